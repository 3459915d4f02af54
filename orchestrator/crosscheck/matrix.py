# SPDX-License-Identifier: BSD-2-Clause
"""The conformance matrix: every scenario in every tool, checked against our master of the same
semantics, written as Markdown and CSV.

A cell (tool x scenario) is red when any check fails:

* **loads**: the tool accepted the archive unchanged and recorded the initial point;
* **parameters**: every parameter of the archive's ``.ssv`` files has its value in the tool (read
  back from the tool after the run), and the plant's initial state ``x1_0``, ``x2_0`` shows up as
  ``plant.x1``, ``plant.x2`` at t0;
* **stop time**: the tool reported no failure and recorded the stop time of the DefaultExperiment;
* **plant.y** (or the ``signals`` chosen: ``orchestrate crosscheck --signal``; for a scenario
  without ``plant.y``, every output it declares): max |signal - ours| in the first second and
  after it within the tool's stated tolerances, where "ours" is ``orchestrate run`` with the
  master of the tool's semantics
  (``jacobi`` for a delayed master, ``gauss-seidel`` for a delay-free one), compared at the
  communication points both recorded. A non-finite sample counts as an infinite difference. The
  first second is tight: that is where a different coupling (one step of delay or not) shows
  (0.049 on ``example1``). After it, the sampled loop's chattering bursts and, in the finite-time
  scenarios, the fault amplify differences in the last bits (e.g. of the time a tool passes to the
  FMUs): a 1e-13 change of the reference's phase moves ``example1_finite_time``'s y by 7.9e-3 at
  t = 27 s in our own ``jacobi`` master, so the tolerance there is loose.

A scenario whose FMUs declare FMI 3.0 clocks (the ``_clocked`` ones) runs in every tool, also in
one that does not drive clocks (``Tool.clocks`` empty) or does not claim its FMI versions: what
that tool does is measured and shown as "no clocks" with the first check it failed, not red (a
tool is not faulted for a feature it does not claim); one that drives them is held to the checks
above.
"""

from __future__ import annotations

import csv
import hashlib
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .. import RunOptions
from .. import run as run_orchestrator
from ..errors import SimulationError
from .tools import AMPLIFIED, Scenario, Tolerance, Tool, ToolRun

__all__ = ["AFTER", "AMPLIFIED", "COLUMN", "Cell", "Check", "Deviation", "Tolerance", "evaluate", "deviation",
           "parameter_check", "run_matrix", "signals_of", "write_csv", "write_markdown"]

COLUMN = "plant.y"
AFTER = 1.0  # s: the stiff start (|v(0)| up to 15 218) is over; tolerances differ before and after
PARAMETER_RTOL = 1e-6  # read back through CSVs of 6 decimals (Ecos) or 12 digits (OMSimulator)
PARAMETER_ATOL = 1e-6


@dataclass(frozen=True)
class Check:
    """One check of a cell: ``ok`` and a short text of what was found; ``key``: which column of the
    matrix it fills (``loads``, ``parameters``, ``stop``, ``until``, ``after``)."""

    name: str
    ok: bool
    detail: str
    key: str = ""


@dataclass(frozen=True)
class Deviation:
    """max |theirs - ours| of one column at the communication points both recorded: over the run
    (``max``, at time ``at``), before ``AFTER`` (``until``) and from it on (``after``); ``column``:
    which (of several compared, the one of the largest difference)."""

    max: float
    at: float
    until: float
    after: float
    compared: int
    column: str = COLUMN


@dataclass
class Cell:
    """One tool on one scenario: its checks (empty when the tool is not installed, or ``unsupported``:
    it does not run FMUs of the scenario's FMI version)."""

    tool: str
    title: str
    scenario: str
    delayed: bool
    reference: str
    missing: str | None = None
    checks: list[Check] = field(default_factory=list)
    wall: float | None = None
    deviation: Deviation | None = None
    tolerance: Tolerance | None = None
    notes: list[str] = field(default_factory=list)
    unsupported: str | None = None
    fmi: str = ""  # the FMI versions of the scenario's FMUs
    tool_fmi: str = ""  # the FMI versions the tool runs
    tool_clocks: str = ""  # how the tool drives FMI 3.0 clocks ("": it does not)
    clocked: bool = False  # the scenario's FMUs declare FMI 3.0 clocks
    clockless: bool = False  # ... and the tool does not drive them

    @property
    def failed(self) -> bool:
        """True when a check failed."""
        return any(not c.ok for c in self.checks)

    @property
    def red(self) -> bool:
        """True when a check failed (a tool that is not installed is not red, nor one without
        clocks on a clocked scenario: that is "no clocks")."""
        return self.failed and not self.clockless

    @property
    def status(self) -> str:
        if self.missing:
            return "not installed"
        if self.unsupported:
            return "not supported"
        if self.clockless and self.failed:
            return "no clocks"
        return "red" if self.red else "ok"


def reference_master(delayed: bool) -> str:
    """Our master of the same semantics: jacobi for a delayed (Jacobi-like) tool, else gauss-seidel."""
    return "jacobi" if delayed else "gauss-seidel"


def deviation(theirs: np.ndarray, ours: np.ndarray, start: float, step: float, column: str = COLUMN,
              after: float = AFTER) -> Deviation:
    """Compare ``column`` at the communication points (t0 + k step) both results hold."""
    k_theirs = np.rint((theirs["time"] - start) / step).astype(np.int64)
    k_ours = np.rint((ours["time"] - start) / step).astype(np.int64)
    _, i, j = np.intersect1d(k_theirs, k_ours, assume_unique=False, return_indices=True)
    if not len(i):
        return Deviation(math.inf, math.nan, math.inf, math.inf, 0, column)
    d = np.abs(theirs[column][i] - ours[column][j])
    d = np.where(np.isfinite(d), d, np.inf)
    t = ours["time"][j]
    early, late = d[t < after], d[t >= after]
    worst = int(np.argmax(d))
    return Deviation(float(d[worst]), float(t[worst]), float(early.max()) if len(early) else 0.0,
                     float(late.max()) if len(late) else 0.0, len(i), column)


def signals_of(scenario: Scenario, chosen: Sequence[str] = ()) -> tuple[str, ...]:
    """The columns compared: ``chosen`` (ValueError naming one the scenario does not output), else
    ``plant.y`` when the scenario outputs it (this project's scenarios), else every output."""
    if chosen:
        unknown = [c for c in chosen if c not in scenario.outputs]
        if unknown:
            raise ValueError(f"{scenario.path}: no output {', '.join(unknown)} (outputs: "
                             f"{', '.join(scenario.outputs) or 'none'})")
        return tuple(chosen)
    return (COLUMN,) if COLUMN in scenario.outputs else scenario.outputs


def _label(signals: Sequence[str]) -> str:
    return signals[0] if len(signals) == 1 else f"{len(signals)} outputs"


def parameter_check(scenario: Scenario, result: np.ndarray, read_back: dict[str, float] | None) -> Check:
    """Parameters applied: values read back from the tool, and the initial plant state at t0."""
    problems = []
    detail = []
    if read_back is not None:
        wrong = [f"{k} = {read_back.get(k, math.nan):g} (archive: {v:g})"
                 for k, v in scenario.parameters.items() if isinstance(v, (int, float))
                 and not math.isclose(read_back.get(k, math.nan), float(v), rel_tol=PARAMETER_RTOL,
                                      abs_tol=PARAMETER_ATOL)]
        numeric = sum(isinstance(v, (int, float)) for v in scenario.parameters.values())
        detail.append(f"{numeric - len(wrong)}/{numeric} read back")
        problems += wrong
    names = result.dtype.names or ()
    for state in ("x1", "x2"):
        expected = scenario.parameters.get(f"plant.{state}_0")
        if expected is None or f"plant.{state}" not in names:
            continue
        if not len(result):
            problems.append(f"no plant.{state} at t0")
        elif not math.isclose(float(result[f"plant.{state}"][0]), float(expected), rel_tol=PARAMETER_RTOL,
                              abs_tol=PARAMETER_ATOL):
            problems.append(f"plant.{state}(t0) = {float(result[f'plant.{state}'][0]):g} "
                            f"(plant.{state}_0 = {float(expected):g})")
        else:
            detail.append(f"{state}(t0) = {float(expected):g}")
    if problems:
        shown = "; ".join(problems[:3]) + (f"; and {len(problems) - 3} more" if len(problems) > 3 else "")
        return Check("parameters", False, shown, "parameters")
    return Check("parameters", True, ", ".join(detail) or "nothing to check", "parameters")


def evaluate(tool: Tool, scenario: Scenario, run: ToolRun, ours: np.ndarray, unchanged: bool = True,
             signals: Sequence[str] = (COLUMN,)) -> Cell:
    """The checks of one tool's run against our result of the same semantics; ``unchanged``: the
    archive's bytes were the same after the run; ``signals``: the columns compared (each must be
    recorded; the tool's tolerance applies to each)."""
    tolerance = tool.tolerance
    cell = Cell(tool.key, tool.title, scenario.name, tool.delayed, reference_master(tool.delayed),
                wall=run.wall, tolerance=tolerance, notes=list(run.notes))
    result = run.result
    loads = len(result) > 0 and unchanged
    detail = "initial point recorded" if len(result) else (run.error or "no samples")
    cell.checks.append(Check("loads", loads, detail if unchanged else "the tool modified the archive",
                             "loads"))
    if not loads:
        return cell
    cell.checks.append(parameter_check(scenario, result, run.parameters))
    t_end = float(result["time"][-1])
    reached = run.error is None and t_end >= scenario.stop - scenario.step / 2
    failure = f"; {run.error}" if run.error else ""
    cell.checks.append(Check("stop time", reached, f"t = {t_end:g} s{failure}", "stop"))
    label = _label(signals)
    missing = [c for c in signals if c not in (result.dtype.names or ())]
    if missing:
        cell.checks.append(Check(label, False, f"{', '.join(missing)} not recorded", "until"))
        return cell
    deviations = [deviation(result, ours, scenario.start, scenario.step, c) for c in signals]
    until = max(deviations, key=lambda d: d.until)
    after = max(deviations, key=lambda d: d.after)
    cell.deviation = dev = replace(max(deviations, key=lambda d: d.max), until=until.until, after=after.after)
    which = (lambda d: f" ({d.column})") if len(signals) > 1 else (lambda d: "")
    cell.checks.append(Check(f"{label} until {AFTER:g} s", dev.until <= tolerance.until,
                             f"{dev.until:.2g}{which(until)} (tolerance {tolerance.until:g})", "until"))
    cell.checks.append(Check(f"{label} after {AFTER:g} s", dev.after <= tolerance.after,
                             f"{dev.after:.2g}{which(after)}, max at t = {dev.at:g} s (tolerance "
                             f"{tolerance.after:g})", "after"))
    return cell


def _ours(scenario: Scenario, master: str) -> tuple[np.ndarray, float, str | None]:
    """``orchestrate run`` of the scenario with ``master``: (result, wall seconds, failure)."""
    import time

    start = time.perf_counter()
    try:
        result = run_orchestrator(scenario.path, RunOptions(master=master)).rows
        error = None
    except SimulationError as exc:
        result, error = exc.result.rows, str(exc)
    return result, time.perf_counter() - start, error


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class OurMaster(Tool):
    """``orchestrate run --master <name>``: the reference of its semantics."""

    def __init__(self, master: str) -> None:
        self.master = master
        self.key = f"orchestrate-{master}"
        self.title = f"orchestrate run --master {master}"
        self.delayed = master == "jacobi"
        self.tolerance = Tolerance(0.0, 0.0, "the reference itself")
        self.fmi_versions = ("2.0", "3.0")
        self.clocks = "periodic input clocks ticked in event mode (Python and compiled executors)"

    def missing(self) -> str | None:
        return None

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        result, wall, error = _ours(scenario, self.master)
        return ToolRun(result, wall, error, None)


def run_matrix(scenarios: Sequence[Scenario], tools: Sequence[Tool],
               progress: Callable[[str], None] | None = None, signals: Sequence[str] = ()) -> list[Cell]:
    """Run every tool on every scenario once (our two masters first: they are the references),
    comparing ``signals`` (:func:`signals_of`)."""
    masters = {m: OurMaster(m) for m in ("gauss-seidel", "jacobi")}
    cells = []
    total = len(scenarios) * (len(tools) + len(masters))
    done = 0
    for scenario in scenarios:
        compared = signals_of(scenario, signals)
        ours: dict[str, np.ndarray] = {}
        for tool in [*masters.values(), *tools]:
            done += 1
            reason = tool.missing()
            # a tool without clocks runs a clocked scenario whatever FMI versions it claims: what it
            # does with the archive is measured, not assumed
            other = [] if scenario.clocked and not tool.clocks else [
                v for v in scenario.fmi_versions if v not in tool.fmi_versions]
            if reason or other:
                runs = ", ".join(tool.fmi_versions)
                unsupported = f"runs FMI {runs} FMUs only, not FMI {', '.join(other)}" if other else None
                cell = Cell(tool.key, tool.title, scenario.name, tool.delayed,
                            reference_master(tool.delayed), missing=reason, unsupported=unsupported)
            else:
                workdir = Path(tempfile.mkdtemp(prefix=f"crosscheck-{tool.key}-"))
                before = _digest(scenario.path)
                try:
                    with _temporary_files_in(workdir / "tmp"):
                        run = tool.run(scenario, workdir)
                finally:
                    shutil.rmtree(workdir, ignore_errors=True)
                if isinstance(tool, OurMaster):
                    ours[tool.master] = run.result
                cell = evaluate(tool, scenario, run, ours[reference_master(tool.delayed)],
                                unchanged=_digest(scenario.path) == before, signals=compared)
            cell.fmi, cell.tool_fmi = ", ".join(scenario.fmi_versions), ", ".join(tool.fmi_versions)
            cell.tool_clocks, cell.clocked = tool.clocks, bool(scenario.clocked)
            cell.clockless = cell.clocked and not tool.clocks
            cells.append(cell)
            if progress is not None:
                wall = f" {cell.wall:.1f} s" if cell.wall is not None else ""
                failed = "; ".join(f"{c.name}: {c.detail}" for c in cell.checks if not c.ok)
                progress(f"[{done}/{total}] {scenario.name} in {tool.key}: {cell.status}{wall}"
                         + (f" ({failed})" if failed else ""))
    return cells


def _fmt(x: float | None) -> str:
    if x is None:
        return ""
    return "0" if x == 0 else f"{x:.2g}"


def write_markdown(cells: Iterable[Cell], path: Path, tools: Sequence[Tool]) -> Path:
    """The matrix (tool x scenario) and the detail of every cell as Markdown."""
    cells = list(cells)
    scenarios = list(dict.fromkeys(c.scenario for c in cells))
    keys = list(dict.fromkeys(c.tool for c in cells))
    by = {(c.tool, c.scenario): c for c in cells}
    fmi = {c.scenario: c.fmi for c in cells}
    clocked = {c.scenario for c in cells if c.clocked}
    lines = ["# SSP tools: conformance matrix", "",
             "Every built scenario (`build/ssp/<name>.ssp`, unchanged: its own step, stop time and "
             "parameter sets) in every tool, written by `orchestrate crosscheck`. A cell is red when the "
             "archive does not load, a parameter of its `.ssv` files is not applied, the run stops before "
             f"the stop time, or max |signal - ours| exceeds the tool's tolerance, in the first "
             f"{AFTER:g} s or after; \"ours\" is `orchestrate run` with the master of the tool's semantics, "
             f"and the signal `{COLUMN}` (`--signal` chooses others; a scenario without it: every output). "
             f"Cells: status, wall time, max |delta signal| until {AFTER:g} s / after. Beside each "
             "scenario the FMI version of its FMUs; beside each tool the FMI versions it runs (a tool is "
             "not run on FMUs of another version: \"not supported\", not red) and whether it drives FMI 3.0 "
             "clocks (a scenario with clocks is run in a tool that does not, and what it does is shown as "
             "\"no clocks\", not red).", "",
             "| tool | master | FMI | clocks | "
             + " | ".join(f"`{s}` (FMI {fmi[s]}{'; clocks' if s in clocked else ''})" for s in scenarios)
             + " |",
             "|---|---|---|---|" + "---|" * len(scenarios)]
    for key in keys:
        first = next(c for c in cells if c.tool == key)
        row = [first.title, "delayed (= `jacobi`)" if first.delayed else "delay-free (= `gauss-seidel`)",
               first.tool_fmi, first.tool_clocks or "no"]
        for s in scenarios:
            c = by.get((key, s))
            if c is None:
                row.append("")
            elif c.missing:
                row.append("not installed")
            elif c.unsupported:
                row.append(f"not supported (FMI {c.fmi})")
            elif c.clockless and c.failed:
                failed = next(k for k in c.checks if not k.ok)
                row.append(f"no clocks: {failed.name}: {failed.detail}")
            else:
                mark = "🟥" if c.red else "🟩"
                dev = (f", {_fmt(c.deviation.until)} / {_fmt(c.deviation.after)}"
                       if c.deviation is not None and not key.startswith("orchestrate-") else "")
                row.append(f"{mark} {c.wall:.1f} s{dev}")
        lines.append("| " + " | ".join(row) + " |")
    lines += ["", "## Details", "",
              f"| tool | scenario | status | loads | parameters | stop time | signal until {AFTER:g} s | "
              f"signal after {AFTER:g} s | notes |", "|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        if c.missing or c.unsupported:
            why = c.missing or c.unsupported
            lines.append(f"| {c.title} | `{c.scenario}` | {c.status} | | | | | | {why} |")
            continue
        checks = {k.key: k for k in c.checks}

        def show(name: str, checks: dict[str, Check] = checks) -> str:
            k = checks.get(name)
            return "" if k is None else (k.detail if k.ok else f"**{k.detail}**")

        shown = "no clocks" if c.status == "no clocks" else "🟥 red" if c.red else "🟩 ok"
        lines.append(f"| {c.title} | `{c.scenario}` | {shown} | {show('loads')} | "
                     f"{show('parameters')} | {show('stop')} | {show('until')} | "
                     f"{show('after')} | {'; '.join(c.notes)} |")
    lines += ["", "## Tolerances", "", f"| tool | compared with | until {AFTER:g} s | after | why |",
              "|---|---|---|---|---|"]
    for tool in tools:
        t = tool.tolerance
        lines.append(f"| {tool.title} | `orchestrate run --master {reference_master(tool.delayed)}` | "
                     f"{t.until:g} | {t.after:g} | {t.reason} |")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


CSV_FIELDS = ("tool", "scenario", "master", "reference", "status", "loads", "parameters", "stop_time",
              "wall_s", "dy_max", "dy_max_at_s", "dy_until_1s", "dy_after_1s", "tol_until_1s", "tol_after_1s",
              "failures", "notes", "fmi", "tool_fmi", "dy_max_signal", "clockless")


def write_csv(cells: Iterable[Cell], path: Path) -> Path:
    """One row per cell (tool, scenario) with every check's outcome."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(CSV_FIELDS)
        for c in cells:
            ok = {k.key: k.ok for k in c.checks}
            d, t = c.deviation, c.tolerance
            writer.writerow([
                c.tool, c.scenario, "delayed" if c.delayed else "delay-free", c.reference, c.status,
                ok.get("loads", ""), ok.get("parameters", ""), ok.get("stop", ""),
                "" if c.wall is None else f"{c.wall:.3f}",
                *(("", "", "", "") if d is None else (repr(d.max), repr(d.at), repr(d.until), repr(d.after))),
                "" if t is None else repr(t.until), "" if t is None else repr(t.after),
                "; ".join(f"{k.name}: {k.detail}" for k in c.checks if not k.ok)
                or (c.missing or c.unsupported or ""),
                "; ".join(c.notes), c.fmi, c.tool_fmi, "" if d is None else d.column, c.clockless])
    return path


@contextmanager
def _temporary_files_in(folder: Path) -> Iterator[None]:
    """Every temporary file of a tool's run made in ``folder`` (removed with the run's workdir):
    Ecos and libcosim leave their unpacked archives in TMPDIR, FMPy its unpacked FMU when a
    simulation raises. TMPDIR for the programs started, ``tempfile.tempdir`` for this process."""
    folder.mkdir()
    saved, saved_env = tempfile.tempdir, os.environ.get("TMPDIR")
    tempfile.tempdir, os.environ["TMPDIR"] = str(folder), str(folder)
    try:
        yield
    finally:
        tempfile.tempdir = saved
        if saved_env is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = saved_env
