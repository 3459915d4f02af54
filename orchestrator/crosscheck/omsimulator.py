# SPDX-License-Identifier: BSD-2-Clause
"""OMSimulator 3 (OpenModelica), prebuilt outside the repository: its command-line program and its
Python package.

Where it is: ``$OMSIMULATOR_HOME`` if set, else ``../shared/tools/omsimulator`` beside the
repository (``bin/OMSimulator``, the Python package under ``lib/x86_64-linux-gnu``). Nothing of it is
copied into the project; when the folder is absent both adapters say "not installed".

OMSimulator's fixed-step master ("ma") of a weakly coupled system solves the connections at every
communication point in dependency order: delay-free, like our ``gauss-seidel`` master. Its result
file holds two rows per communication point (before and after the exchange); the adapters keep the
second. Differences between the two entry points, both handled here:

* the program reads the step from ``oms:FixedStepMaster stepSize`` but not the stop time of the
  DefaultExperiment (its default is 1 s): we pass ``--stopTime``; it prints its CSV with 12
  significant digits; ``--addParametersToCSV=true`` adds the parameters as columns;
* the Python package (``SSP(path).instantiate()``) takes the start and stop time from the archive
  but not the step (its default is 1 ms): we pass ``setFixedStepSize`` with the archive's step.

FMI 3.0 components: OMSimulator 3 reads them through fmi4c, which cannot tell an output with no
dependency (``dependencies=""``) from one that does not say (every input): the plant's outputs then
close an algebraic loop plant -> controller -> actuator -> plant, which its default solver (KINSOL)
cannot solve without directional derivatives, so initialization fails. For scenarios with FMI 3.0
components both adapters select the fixed-point loop solver (``--algLoopSolver=fixedpoint``): the
plant's outputs do not change with its input, so the iteration ends at once with the values of a
run without the loop. The archive is unchanged.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..fmi import interpreter_guard
from . import colleague
from . import tools as base
from .tools import (
    AMPLIFIED,
    QUIET,
    Scenario,
    Tolerance,
    Tool,
    ToolRun,
    empty_result,
    last_per_step,
    table_result,
)

__all__ = ["OMSimulatorCliTool", "OMSimulatorNoPythonTool", "OMSimulatorPythonTool", "home"]

ENV = "OMSIMULATOR_HOME"
FIXED_POINT = "--algLoopSolver=fixedpoint"  # for FMI 3.0 components (module docstring)
DEFAULT_SOLVER = "--algLoopSolver=kinsol"
DEFAULT_HOME = Path(__file__).resolve().parents[2].parent / "shared" / "tools" / "omsimulator"


def home() -> Path:
    """The OMSimulator installation folder (``$OMSIMULATOR_HOME`` or ``../shared/tools/omsimulator``)."""
    return Path(os.environ[ENV]) if os.environ.get(ENV) else DEFAULT_HOME


def _read_result(path: Path, scenario: Scenario,
                 columns: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """OMSimulator's result CSV, columns named ``[<system>.]<system>.<component>.<variable>``, as our
    layout (last row of each communication point) and every column by ``component.variable``."""
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(path)
    named = {}
    for raw in table.column_names:
        parts = raw.split(".")
        key = "time" if raw == "time" else ".".join(parts[-2:])
        named[key] = table[raw].to_numpy().astype(np.float64)
    keep = last_per_step(named["time"], scenario.start, scenario.step)
    named = {k: v[keep] for k, v in named.items()}
    return table_result(named["time"], named, columns), named


# Both entry points run the same library: one tolerance.
TOLERANCE = Tolerance(QUIET, AMPLIFIED, "delay-free like `gauss-seidel`, not bit-identical: 5e-13 (its CSV's "
                      "12 digits) to 1.5e-8 (pendulum) in the first second, amplified after it")


class OMSimulatorCliTool(Tool):
    """``bin/OMSimulator`` (a subprocess with a clean environment)."""

    key = "omsimulator"
    fmi_versions = ("2.0", "3.0")
    title = "OMSimulator 3 (CLI)"
    delayed = False
    tolerance = TOLERANCE

    def missing(self) -> str | None:
        binary = home() / "bin" / "OMSimulator"
        return None if binary.is_file() else f"not installed ({binary} not found; set {ENV})"

    def command(self, scenario: Scenario, workdir: Path) -> list[str]:
        """The command line: the archive, its stop time, a result file with the parameters."""
        return [str(home() / "bin" / "OMSimulator"), str(scenario.path.resolve()),
                f"--startTime={scenario.start!r}", f"--stopTime={scenario.stop!r}",
                f"--resultFile={workdir / 'result.csv'}", "--addParametersToCSV=true",
                f"--tempDir={workdir}", *([FIXED_POINT] if "3.0" in scenario.fmi_versions else [])]

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        start = time.perf_counter()
        done = subprocess.run(self.command(scenario, workdir), cwd=workdir, env=base.clean_environment(),
                              capture_output=True, text=True)
        wall = time.perf_counter() - start
        errors = [ln.strip() for ln in (done.stdout + done.stderr).splitlines() if ln.startswith("error:")]
        error = None
        if done.returncode != 0 or errors:
            error = f"OMSimulator exited with status {done.returncode}" + (f": {errors[0]}" if errors else "")
        csv = workdir / "result.csv"
        if not csv.is_file() or csv.stat().st_size == 0:
            return ToolRun(empty_result(columns), wall, error or "OMSimulator wrote no result file")
        result, named = _read_result(csv, scenario, columns)
        parameters = {c: float(named[c][-1]) for c in scenario.parameters if c in named and len(named[c])}
        return ToolRun(result, wall, error, parameters, ["OMSimulator's CSV has 12 significant digits"])


class OMSimulatorNoPythonTool(OMSimulatorCliTool):
    """``bin/OMSimulator`` on a colleague's machine: every Python of this one hidden in a private
    mount namespace (``colleague.py``), so the FMUs can only run on the runtime they carry."""

    key = "omsimulator-nopython"
    title = "OMSimulator 3 (CLI), no Python on the machine"

    def missing(self) -> str | None:
        return super().missing() or colleague.refusal()

    def command(self, scenario: Scenario, workdir: Path) -> list[str]:
        return colleague.hidden(super().command(scenario, workdir))


@contextlib.contextmanager
def _stdout_silenced() -> Iterator[None]:
    """Discard what the library prints on file descriptor 1 (closing a log file prints "info:
    Logging information has been saved to ...")."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


@contextlib.contextmanager
def _quiet_temp(folder: Path) -> Iterator[None]:
    """Make ``tempfile`` create its folders in ``folder`` (the package makes some it never
    removes) while OMSimulator runs."""
    before = tempfile.tempdir
    tempfile.tempdir = str(folder)
    try:
        yield
    finally:
        tempfile.tempdir = before


class OMSimulatorPythonTool(Tool):
    """OMSimulator's Python package (``libOMSimulator.so`` in this process)."""

    key = "omsimulator-py"
    fmi_versions = ("2.0", "3.0")
    title = "OMSimulator 3 (Python)"
    delayed = False
    tolerance = TOLERANCE

    def missing(self) -> str | None:
        package = home() / "lib" / "x86_64-linux-gnu" / "OMSimulator"
        return None if package.is_dir() else f"not installed ({package} not found; set {ENV})"

    @staticmethod
    def _import():
        """Import the package from the installation folder (sys.path restored afterwards)."""
        folder = str(home() / "lib" / "x86_64-linux-gnu")
        path = list(sys.path)
        sys.path.insert(0, folder)
        try:
            return importlib.import_module("OMSimulator")
        finally:
            sys.path[:] = path

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        oms = self._import()
        csv = workdir / "result.csv"
        values: dict[str, float] = {}
        error = None
        start = time.perf_counter()
        log = workdir / "omsimulator.log"
        with interpreter_guard(), _quiet_temp(workdir):
            with _stdout_silenced():  # closing the previous log file prints a line
                oms.Capi.setLogFile(str(log))
            model = None
            fmi3 = "3.0" in scenario.fmi_versions
            try:
                if fmi3:
                    oms.Capi.setCommandLineOption(FIXED_POINT)
                model = oms.SSP(str(scenario.path), temp_dir=str(workdir)).instantiate()
                model.setResultFile(str(csv))
                model.setFixedStepSize(scenario.step)
                start = time.perf_counter()
                model.initialize()
                model.simulate()
                for column in scenario.parameters:
                    component, variable = column.split(".", 1)
                    values[column] = float(model.getValue(oms.CRef(scenario.system, component, variable)))
            except Exception as exc:  # noqa: BLE001 -- the package raises RuntimeError, KeyError, ...
                error = f"OMSimulator: {exc}"
                logged = [ln.strip() for ln in log.read_text(errors="replace").splitlines()
                          if ln.startswith("error:")] if log.is_file() else []
                if logged:
                    error += f" ({logged[0]})"
            finally:
                wall = time.perf_counter() - start
                if model is not None:
                    with contextlib.suppress(Exception):
                        model.terminate()
                    with contextlib.suppress(Exception):
                        model.delete()
                if fmi3:
                    oms.Capi.setCommandLineOption(DEFAULT_SOLVER)
                with _stdout_silenced():
                    oms.Capi.setLogFile(os.devnull)
        if not csv.is_file() or csv.stat().st_size == 0:
            return ToolRun(empty_result(columns), wall, error or "OMSimulator wrote no result file")
        result, _ = _read_result(csv, scenario, columns)
        return ToolRun(result, wall, error, values or None, ["OMSimulator's CSV has 12 significant digits"])
