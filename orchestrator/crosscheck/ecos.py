# SPDX-License-Identifier: BSD-2-Clause
"""Ecos (github.com/Ecos-platform/ecos, wheel ``ecospy`` 0.7.2): its Python API in this process and
its command-line program ``ecos`` from the same wheel.

Ecos's fixed-step algorithm steps every instance with the inputs it got after the previous step
and transfers the connections afterwards: one step of delay per connection, as libcosim (measured
against our ``jacobi`` master: 7e-15 in the first second; Ecos passes the time accumulated as
``t += h``, and these last-bit differences grow in the chattering bursts after the fault). Ecos does
not check the status of ``fmi2DoStep`` (its source drops fmilibcpp's ``step`` result): a failing FMU does
not stop it, its outputs go on as they are.

Two things of the wheel need help on Linux, both handled here, nothing for the user to set:

* ``libecosc.so`` and ``ecos`` need ``libtbb.so.12``, which the pinned ``tbb`` wheel installs in
  ``<sys.prefix>/lib`` (not on the loader's path). The Python API gets it preloaded (``RTLD_GLOBAL``)
  before ``ecospy`` is imported; the program gets ``--library-path <sys.prefix>/lib`` from its
  dynamic loader.
* The wheel installs ``ecos`` without its execute bit, so it is started through the dynamic loader
  its ELF header names (``/lib64/ld-linux-x86-64.so.2 ecos ...``).

Ecos takes the step as an argument (we pass the archive's) and applies ONE named parameter set
(``--parameterSet NAME``, ``init(parameter_set=NAME)``): the union of the ``.ssv`` files named NAME
over all components. The adapters pass the name when every ``.ssv`` of the archive has the same one;
otherwise no parameter set is applied, and the matrix shows it.
"""

from __future__ import annotations

import ctypes
import importlib.util
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..fmi import interpreter_guard
from ..results import structured
from . import tools as base
from .tools import (
    AMPLIFIED,
    QUIET,
    Scenario,
    Tolerance,
    Tool,
    ToolRun,
    elf_interpreter,
    empty_result,
    table_result,
)

__all__ = ["EcosCliTool", "EcospyTool", "parameter_set_name"]

TBB = "libtbb.so.12"


def _package_dir() -> Path | None:
    spec = importlib.util.find_spec("ecospy")
    locations = spec.submodule_search_locations if spec else None
    return Path(next(iter(locations))) if locations else None


def _tbb() -> Path:
    return Path(sys.prefix) / "lib" / TBB


def _missing_common() -> str | None:
    if _package_dir() is None:
        return "ecospy is not installed (pip install ecospy)"
    if not _tbb().is_file():
        return f"{TBB} not found in {_tbb().parent} (pip install tbb)"
    return None


def parameter_set_name(scenario: Scenario) -> tuple[str | None, str | None]:
    """The parameter set name to give Ecos, and a note when the archive's sets cannot all apply."""
    names = sorted({n for sets in scenario.set_names.values() for n in sets})
    if len(names) <= 1:
        return (names[0] if names else None), None
    return None, (f"Ecos applies one named parameter set; the archive's .ssv files have {len(names)} "
                  f"different names ({', '.join(names)}): none applied")


def _identifier(column: str) -> str:
    component, variable = column.split(".", 1)
    return f"{component}::{variable}"


class EcospyTool(Tool):
    """Ecos through its Python API ``ecospy`` (in this process)."""

    key = "ecospy"
    title = "Ecos 0.7.2 (ecospy)"
    delayed = True
    tolerance = Tolerance(QUIET, AMPLIFIED, "the same algorithm as `jacobi`, but Ecos passes the time as "
                          "t += h (9.999999999999897 at 10 s): last-bit differences, amplified after the "
                          "first second")

    def missing(self) -> str | None:
        return _missing_common()

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        name, note = parameter_set_name(scenario)
        with interpreter_guard():
            ctypes.CDLL(str(_tbb()), mode=ctypes.RTLD_GLOBAL)
            from ecospy import EcosLib, EcosSimulation

            EcosLib.set_log_level("err")
            try:
                sim = EcosSimulation(ssp_path=str(scenario.path), step_size=scenario.step)
            except Exception as exc:  # noqa: BLE001 -- ecospy raises bare Exception
                return ToolRun(empty_result(columns), 0.0, f"ecospy could not load the archive: {exc}")
            try:
                return self._simulate(sim, scenario, columns, name, note)
            finally:
                sim.free()

    @staticmethod
    def _simulate(sim, scenario: Scenario, columns: list[str], name: str | None, note: str | None) -> ToolRun:
        ids = [_identifier(c) for c in scenario.outputs]
        rows = np.empty((scenario.steps + 1, len(columns)))
        n, error = 0, None
        start = time.perf_counter()
        if not sim.init(start_time=scenario.start, parameter_set=name):
            error = "ecospy: init failed"
        else:
            get = sim.get_real
            rows[0] = [sim.get_time(), *(get(i) for i in ids)]
            n = 1
            for _ in range(scenario.steps):
                t = sim.step()
                rows[n] = [t, *(get(i) for i in ids)]
                n += 1
        wall = time.perf_counter() - start
        values = {}
        for column, type_ in scenario.types.items():
            getter = {"Real": sim.get_real, "Integer": sim.get_integer, "Boolean": sim.get_bool}.get(type_)
            if getter is not None:
                values[column] = float(getter(_identifier(column)))
        sim.terminate()
        return ToolRun(structured(rows[:n].copy(), columns), wall, error, values, [note] if note else [])


class EcosCliTool(Tool):
    """Ecos's command-line program ``ecos simulate`` (a subprocess with a clean environment)."""

    key = "ecos"
    title = "Ecos 0.7.2 (ecos CLI)"
    delayed = True
    tolerance = Tolerance(2 * QUIET, AMPLIFIED, "as ecospy, plus its CSV's 6 decimals (rounding 5e-7)")

    def missing(self) -> str | None:
        reason = _missing_common()
        if reason is None and not self._binary().is_file():
            reason = f"{self._binary()} not found (ecospy wheel without the ecos program)"
        return reason

    @staticmethod
    def _binary() -> Path:
        return (_package_dir() or Path(".")) / "binaries" / "ecos"

    def command(self, scenario: Scenario) -> list[str]:
        """The command line: the archive, its stop time and step, and the parameter set name. The
        stop time is given half a step late: ``ecos`` steps while ``t + h <= stop`` with t accumulated
        as ``t += h``, which stops one step early at the exact stop time (29.999 of 30 s).
        ``--noParallel``: Ecos's TBB threads only contend with the FMUs' one interpreter (10 s of
        example1: 10.3 s wall serial, 15.4 s parallel on 2 cores; the 30 s pendulum 56 s against 75 s)."""
        binary = self._binary()
        name, _ = parameter_set_name(scenario)
        return [elf_interpreter(binary), "--library-path", str(_tbb().parent), str(binary), "simulate",
                "--path", str(scenario.path.resolve()), "--startTime", repr(scenario.start),
                "--stopTime", repr(scenario.stop + scenario.step / 2), "--stepSize", repr(scenario.step),
                "--logLevel", "warn", "--noParallel",
                *(["--parameterSet", name] if name else [])]

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        _, note = parameter_set_name(scenario)
        start = time.perf_counter()
        done = subprocess.run(self.command(scenario), cwd=workdir, env=base.clean_environment(),
                              capture_output=True, text=True)
        wall = time.perf_counter() - start
        csv = workdir / f"{scenario.path.stem}.csv"
        error = None
        if done.returncode != 0:
            lines = [ln for ln in (done.stderr + done.stdout).splitlines() if ln.strip()]
            error = f"ecos exited with status {done.returncode}: {lines[-1] if lines else 'no output'}"
        if not csv.is_file():
            return ToolRun(empty_result(columns), wall, error or f"ecos wrote no {csv.name}")
        header, table = _read_ecos_csv(csv)
        if "time" not in table:
            return ToolRun(empty_result(columns), wall, error or f"ecos: {csv.name} has no time column")
        result = table_result(table["time"], table, columns)
        parameters = {c: float(table[c][-1]) for c in scenario.parameters if c in table and len(table[c])}
        notes = [note] if note else []
        notes.append("ecos writes its CSV with 6 decimals")
        return ToolRun(result, wall, error, parameters, notes)


def _read_ecos_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    """Ecos's CSV (``iterations, time, comp::var[TYPE], ...``) as ``{"time" | "comp.var": column}``."""
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(path)
    out = {}
    for raw in table.column_names:
        name = raw.strip()
        if "::" in name:
            component, variable = name.split("::", 1)
            name = f"{component}.{variable.split('[', 1)[0]}"
        out[name] = table[raw].to_numpy().astype(np.float64)
    return table.column_names, out
