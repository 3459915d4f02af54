# SPDX-License-Identifier: BSD-2-Clause
"""The scenario exported as one FMU (``orchestrate export``) in hosts that read FMUs but no SSP:
fmusim (Reference FMUs) and the FMU Compliance Checker (FMI Library) on a colleague's machine with
no Python (``colleague.py``), and FMPy's ``simulate_fmu`` in this process.

The FMU runs our ``gauss-seidel`` master inside, so it is compared with it: bit for bit, but for
fmusim's CSV, which prints 16 significant digits. Each archive is exported once per process and
the three hosts share it. Where the tools live: ``../shared/tools/{fmusim,fmucheck}/bin``.
"""

from __future__ import annotations

import hashlib
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from ..export import export
from ..fmi import interpreter_guard
from . import colleague
from .tools import Scenario, Tolerance, Tool, ToolRun, empty_result, table_result

__all__ = ["ExportedFmpyTool", "ExportedFmuCheckTool", "ExportedFmusimTool", "exported_fmu"]

TOOLS_HOME = Path(__file__).resolve().parents[2].parent / "shared" / "tools"
FMUSIM = TOOLS_HOME / "fmusim" / "bin" / "fmusim"
FMUCHECK = TOOLS_HOME / "fmucheck" / "bin" / "fmuCheck"
# The same master and FMUs inside: bit for bit; fmusim's %.16g CSV rounds a value of size ~1 by
# up to 5.6e-17 (measured on example1), so 1e-12 leaves room without hiding a different coupling.
TOLERANCE = Tolerance(1e-12, 1e-12, "our `gauss-seidel` master inside one FMU: bit for bit (fmusim's CSV "
                      "prints 16 digits: up to 5.6e-17)")
_EXPORTED: dict[str, Path] = {}
_EXPORT_FOLDER: list[tempfile.TemporaryDirectory[str]] = []  # made at the first export, removed at exit
_TEMPORARY = tempfile.gettempdir()  # not a tool run's own (matrix.py), removed after that run


def exported_fmu(scenario: Scenario) -> Path:
    """The scenario's archive exported as one FMU (default options), once per process and archive
    content, in a folder removed when the process exits."""
    key = hashlib.sha256(scenario.path.read_bytes()).hexdigest()
    if key not in _EXPORTED or not _EXPORTED[key].is_file():
        if not _EXPORT_FOLDER:
            _EXPORT_FOLDER.append(tempfile.TemporaryDirectory(prefix="crosscheck-export-", dir=_TEMPORARY))
        folder = Path(_EXPORT_FOLDER[0].name) / key[:16]
        folder.mkdir(exist_ok=True)
        _EXPORTED[key], _ = export(scenario.path, folder / f"{scenario.name}.fmu")
    return _EXPORTED[key]


def _read_csv(path: Path, scenario: Scenario) -> np.ndarray:
    """A host's CSV (header of quoted names, ``time`` first) in our layout."""
    from fmpy.util import read_csv

    data = read_csv(str(path))
    table = {name: np.asarray(data[name], dtype=float) for name in data.dtype.names or ()}
    return table_result(table["time"], table, ["time", *scenario.outputs])


class _ExportedTool(Tool):
    """Export, then run the FMU in one host; ``host(fmu, scenario, workdir)`` returns the CSV."""

    delayed = False
    tolerance = TOLERANCE
    program: Path | None = None
    fmi_versions = ("2.0", "3.0")  # the container embeds both
    clocks = "inside the FMU: the container ticks them, plain Co-Simulation outside"

    def missing(self) -> str | None:
        if self.program is not None and not self.program.is_file():
            return f"not installed ({self.program} not found)"
        return colleague.refusal() if self.program is not None else None

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        try:
            fmu = exported_fmu(scenario)
        except Exception as exc:  # noqa: BLE001 -- the cell reports any failure of the export
            return ToolRun(empty_result(columns), 0.0, f"orchestrate export failed: {exc}")
        start = time.perf_counter()
        result, error = self.host(fmu, scenario, workdir)
        return ToolRun(result if result is not None else empty_result(columns), time.perf_counter() - start,
                       error, None, [f"exported FMU, {fmu.stat().st_size / 1e6:.1f} MB"])

    def host(self, fmu: Path, scenario: Scenario, workdir: Path) -> tuple[np.ndarray | None, str | None]:
        raise NotImplementedError

    def _program(self, command: list[str], out: Path,
                 scenario: Scenario) -> tuple[np.ndarray | None, str | None]:
        done = subprocess.run(colleague.hidden(command), capture_output=True, text=True)
        error = None
        if done.returncode != 0:
            lines = (done.stdout + done.stderr).strip().splitlines()
            error = f"{self.program.name if self.program else '?'} exited with status {done.returncode}" + (
                f": {lines[-1]}" if lines else "")
        if not out.is_file() or out.stat().st_size == 0:
            return None, error or "no result file"
        return _read_csv(out, scenario), error


class ExportedFmusimTool(_ExportedTool):
    """fmusim on a colleague's machine (no Python), the FMU's own DefaultExperiment."""

    key = "export-fmusim"
    title = "exported FMU in fmusim 0.0.39, no Python"
    program = FMUSIM

    def host(self, fmu: Path, scenario: Scenario, workdir: Path) -> tuple[np.ndarray | None, str | None]:
        out = workdir / "fmusim.csv"
        command = [str(FMUSIM), "--interface-type", "cs", "--start-time", repr(scenario.start), "--stop-time",
                   repr(scenario.stop), "--output-file", str(out), str(fmu)]
        return self._program(command, out, scenario)


class ExportedFmuCheckTool(_ExportedTool):
    """The FMU Compliance Checker on a colleague's machine (no Python), every step recorded."""

    key = "export-fmucheck"
    title = "exported FMU in fmuCheck 2.0.4, no Python"
    program = FMUCHECK

    def host(self, fmu: Path, scenario: Scenario, workdir: Path) -> tuple[np.ndarray | None, str | None]:
        out, log = workdir / "fmucheck.csv", workdir / "fmucheck.log"
        command = [str(FMUCHECK), "-k", "cs", "-h", repr(scenario.step), "-n", "0", "-s", repr(scenario.stop),
                   "-o", str(out), "-e", str(log), "-t", str(workdir), str(fmu)]
        result, error = self._program(command, out, scenario)
        report = log.read_text(errors="replace") if log.is_file() else ""
        if error is None and not ("\t0 Error(s)" in report and "\t0 Warning(s)" in report):
            error = "fmuCheck reports errors or warnings (see its log)"
        return result, error


class ExportedFmpyTool(_ExportedTool):
    """FMPy's ``simulate_fmu`` in this process (the embedded FMUs run on this interpreter)."""

    key = "export-fmpy"
    title = "exported FMU in fmpy 0.3.32 (simulate_fmu)"

    def host(self, fmu: Path, scenario: Scenario, workdir: Path) -> tuple[np.ndarray | None, str | None]:
        import fmpy

        try:
            with interpreter_guard():
                data = fmpy.simulate_fmu(str(fmu), start_time=scenario.start, stop_time=scenario.stop,
                                         output_interval=scenario.step)
        except Exception as exc:  # noqa: BLE001 -- fmpy raises plain Exception for a failed call
            return None, f"fmpy: {exc}"
        table = {name: np.asarray(data[name], dtype=float) for name in data.dtype.names or ()}
        return table_result(table["time"], table, ["time", *scenario.outputs]), None
