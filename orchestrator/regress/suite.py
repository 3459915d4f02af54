# SPDX-License-Identifier: BSD-2-Clause
"""A regression suite: scenarios found in folders, each with its baseline and tolerances beside it,
run in parallel processes and compared with their baselines.

The layout (docs/regression.md)::

    regression/                     a folder given to 'orchestrate regress' (any depth below it)
      plant_step.ssp                a scenario: an .ssp archive ...
      closed_loop/                  ... or a folder holding SystemStructure.ssd (FMUs in resources/)
      baselines/
        plant_step.csv              the baseline of each scenario of the folder, named as it
        closed_loop.csv
        tolerances.json             the tubes (optional; default 1 % of each signal's range)

Each scenario runs its own DefaultExperiment. Every column of its baseline is required of the run
(a signal the scenario no longer has is a regression, unlike ``orchestrate compare``'s default).
Each scenario runs in a process of its own (``jobs`` at a time): an FMU that crashes fails its
scenario, not the suite, and pythonfmu FMUs, which share one interpreter per process, never meet.
"""

from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
import multiprocessing.resource_tracker
import os
import signal
import time
import traceback
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import RunOptions, run
from ..cli import fmu_dirs, resolve_scenario, scenario_checks
from ..errors import OrchestratorError, ScenarioError, ScenarioWarning, SimulationError, UsageError
from ..results import read_result
from ..ssp import SSD_NAME
from .tubes import (
    BASELINE_GRID,
    TOLERANCES_NAME,
    Comparison,
    Tolerances,
    compare,
    load_tolerances,
    output_columns,
    thin,
)

__all__ = ["BASELINES", "Case", "Outcome", "SuiteInterrupted", "find_cases", "run_cases", "scenario_line",
           "summary_line"]

BASELINES = "baselines"  # the folder beside the scenarios that holds their baselines and tolerances
MAX_SCENARIOS = 10_000  # a folder walk stops there: a suite is not a whole file system
PASS, FAIL, ERROR, NOT_RUN = "pass", "fail", "error", "not run"
LABELS = {PASS: "PASS", FAIL: "REGRESSION", ERROR: "ERROR", NOT_RUN: "NOT RUN"}


@dataclass(frozen=True)
class Case:
    """One scenario of a suite: where it is, its name, its baseline and its tolerances.

    Attributes
    ----------
    name : str
        The scenario's name: the archive's stem or the folder's name (the baseline's stem).
    scenario : Path
        The ``.ssp`` archive or the folder holding ``SystemStructure.ssd``.
    baseline : Path
        ``<baselines>/<name>.csv`` (it may not exist yet: ``orchestrate baseline`` writes it).
    group : str
        The folder it was found in, as given (the JUnit ``classname``).
    """

    name: str
    scenario: Path
    baseline: Path
    group: str

    @property
    def tolerances(self) -> Path:
        """``tolerances.json`` beside the baseline (it may not exist: built-in tubes then)."""
        return self.baseline.parent / TOLERANCES_NAME


def _is_scenario(path: Path) -> bool:
    return (path.is_file() and path.suffix.lower() == ".ssp") or (path / SSD_NAME).is_file()


def _walk(root: Path) -> list[Path]:
    """Scenarios under ``root``, sorted: ``.ssp`` files and folders holding an SSD (not entered),
    skipping ``baselines/`` and hidden folders; symbolic links to folders are not followed."""
    found: list[Path] = []
    for folder, dirs, names in os.walk(root):
        here = Path(folder)
        keep = []
        for d in sorted(dirs):
            if d.startswith(".") or d == BASELINES:
                continue
            if (here / d / SSD_NAME).is_file():
                found.append(here / d)
            else:
                keep.append(d)
        dirs[:] = keep
        found += [here / n for n in sorted(names) if n.lower().endswith(".ssp") and not n.startswith(".")]
        if len(found) > MAX_SCENARIOS:
            raise UsageError(f"{root}: more than {MAX_SCENARIOS} scenarios below it: give a smaller folder")
    return sorted(found)


def find_cases(paths: Iterable[str | os.PathLike], baselines: str | os.PathLike | None = None) -> list[Case]:
    """The scenarios named by ``paths``: ``.ssp`` archives, scenario folders, names of built
    scenarios (``build/ssp/NAME.ssp``), or folders searched for them.

    Parameters
    ----------
    paths : iterable of path
        What to run (at least one).
    baselines : path, optional
        One folder holding every baseline and ``tolerances.json`` (default: the ``baselines/``
        folder beside each scenario).

    Raises
    ------
    UsageError
        A path that names no scenario, a folder without any, or two scenarios of one name sharing
        a baselines folder (each problem on its own line).
    """
    cases: list[Case] = []
    problems: list[str] = []
    for given in paths:
        cases += _cases_of(given, baselines, problems)
    unique = _distinct(cases, problems)
    if problems:
        raise UsageError("\n".join(problems) if len(problems) == 1 else
                         f"{len(problems)} problems:\n" + "\n".join(f"  - {p}" for p in problems))
    if not unique:
        raise UsageError("no scenarios given")
    return unique


def _cases_of(given: str | os.PathLike, baselines: str | os.PathLike | None,
              problems: list[str]) -> list[Case]:
    """The cases one path of :func:`find_cases` names; what is wrong with it appended to ``problems``."""
    path = Path(given)
    if not path.exists() and (os.sep in str(given) or path.suffix):
        problems.append(f"{given}: no such file or folder")
        return []
    if not path.exists():  # a name: the scenario built into build/ssp/NAME.ssp
        try:
            path = resolve_scenario(str(given))
        except ScenarioError as exc:
            problems.append(str(exc))
            return []
    if _is_scenario(path):
        found, group = [path], str(path.parent)
    elif path.is_dir():
        found, group = _walk(path), str(path)
        if not found:
            problems.append(f"{path}: no scenarios in it (.ssp archives or folders holding {SSD_NAME})")
    else:
        problems.append(f"{path}: not a scenario (an .ssp archive or a folder holding {SSD_NAME})")
        return []
    return [_case(scenario, path, group, baselines) for scenario in found]


def _case(scenario: Path, given: Path, group: str, baselines: str | os.PathLike | None) -> Case:
    """The case of ``scenario``, found under the path ``given`` (its group: where it was found)."""
    name = scenario.stem if scenario.is_file() else scenario.name
    folder = Path(baselines) if baselines is not None else scenario.parent / BASELINES
    where = scenario.parent.relative_to(given) if scenario != given else Path()
    return Case(name, scenario, folder / f"{name}.csv", (Path(group) / where).as_posix())


def _distinct(cases: Sequence[Case], problems: list[str]) -> list[Case]:
    """Each case once (a scenario named twice runs once); two scenarios that would write one
    baseline appended to ``problems``."""
    seen: dict[Path, Case] = {}
    unique = []
    for case in cases:
        other = seen.setdefault(case.baseline.resolve(), case)
        if other is case:
            unique.append(case)
        elif other.scenario.resolve() != case.scenario.resolve():
            problems.append(f"{other.scenario} and {case.scenario} would share the baseline {case.baseline}: "
                            "rename one, or give each its own baselines folder")
    return unique


def check_setup(cases: Sequence[Case], *, need_baseline: bool, allow_stale: bool = False) -> None:
    """What must hold before anything runs, all problems at once: every baseline present and
    readable (``need_baseline``), every tolerance file readable, no stale build (an application's
    check, e.g. this project's 'build older than its sources', unless ``allow_stale``).

    Raises
    ------
    UsageError
        One line per problem.
    """
    problems = [p for case in cases for p in _setup_problems(case, need_baseline, allow_stale)]
    problems = list(dict.fromkeys(problems))  # a tolerance file shared by many scenarios: once
    if problems:
        raise UsageError(problems[0] if len(problems) == 1 else
                         f"{len(problems)} problems:\n" + "\n".join(f"  - {p}" for p in problems))


def _setup_problems(case: Case, need_baseline: bool, allow_stale: bool) -> list[str]:
    """What :func:`check_setup` finds wrong with one case: its baseline, its tolerances, its build."""
    problems = []
    if need_baseline and not case.baseline.is_file():
        problems.append(f"{case.scenario}: no baseline {case.baseline} (write it with 'orchestrate "
                        f"baseline {case.scenario}')")
    elif case.baseline.is_file():
        try:
            read_result(case.baseline)
        except OrchestratorError as exc:
            problems.append(str(exc))
    if case.tolerances.is_file():
        try:
            load_tolerances(case.tolerances)
        except OrchestratorError as exc:
            problems.append(str(exc))
    if not allow_stale:
        problems += [f"{case.scenario}: {p}" for p in scenario_checks(case.scenario)]
    return problems


def tolerances_of(case: Case) -> Tolerances:
    """The tubes of ``case``: its folder's ``tolerances.json`` with the scenario's own section."""
    common = load_tolerances(case.tolerances) if case.tolerances.is_file() else Tolerances()
    return common.for_scenario(case.name)


@dataclass
class Outcome:
    """What one scenario gave.

    ``status`` is ``pass``, ``fail`` (outside a tube, a signal or time span lost), ``error`` (it did
    not run to the end) or ``not run`` (the suite was interrupted first); ``message`` says why in one
    line. ``candidate`` is the new baseline (``orchestrate baseline``: the run on the baseline grid).
    """

    case: Case
    status: str
    message: str
    comparison: Comparison | None = None
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    detail: str = ""  # a traceback for an unexpected exception (the JUnit error text)
    candidate: np.ndarray | None = None


@dataclass(frozen=True)
class Settings:
    """How each scenario runs: a wall-clock ``timeout`` per run (None: none); ``grid``: a baseline's
    spacing in s (``baseline`` mode, which keeps the run's rows as ``Outcome.candidate``)."""

    timeout: float | None = None
    baseline: bool = False
    grid: float = BASELINE_GRID


class _Collect(logging.Handler):
    """Collects the warnings FMUs log during a run (they are reported, not printed)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage().strip()
        if text and text not in self.messages:
            self.messages.append(text)


def check_case(case: Case, settings: Settings | None = None) -> Outcome:
    """Run ``case``'s scenario and compare it with its baseline (every baseline column required)."""
    settings = settings or Settings()
    started = time.monotonic()
    collect = _Collect()
    logging.getLogger().addHandler(collect)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ScenarioWarning)
            outcome = _check(case, settings)
    except SimulationError as exc:
        outcome = Outcome(case, ERROR, f"the run failed: {exc}")
    except OrchestratorError as exc:
        outcome = Outcome(case, ERROR, f"cannot run: {exc}".replace("\n", " "))
    except Exception as exc:  # noqa: BLE001 - a broken FMU or bug fails this scenario, not the suite
        outcome = Outcome(case, ERROR, f"cannot run: {type(exc).__name__}: {exc}",
                          detail=traceback.format_exc())
    finally:
        logging.getLogger().removeHandler(collect)
    outcome.warnings = [str(w.message) for w in caught if issubclass(w.category, ScenarioWarning)]
    outcome.warnings += collect.messages
    outcome.seconds = time.monotonic() - started
    return outcome


def _check(case: Case, settings: Settings) -> Outcome:
    dirs = fmu_dirs(case.scenario)
    rows = run(case.scenario, RunOptions(fmu_dirs=dirs, timeout=settings.timeout)).rows
    tolerances = tolerances_of(case)
    this_run = f"{case.name} (this run)"
    if settings.baseline:
        candidate = thin(rows, settings.grid, output_columns(case.scenario, dirs))
        if not case.baseline.is_file():
            return Outcome(case, PASS, "new: no baseline yet", candidate=candidate)
        comparison = compare(candidate, read_result(case.baseline), tolerances, this_run, str(case.baseline))
        return Outcome(case, PASS if comparison.passed else FAIL, _message(comparison), comparison,
                       candidate=candidate)
    baseline = read_result(case.baseline)
    signals = [n for n in baseline.dtype.names or () if n != "time"]
    comparison = compare(rows, baseline, tolerances, this_run, str(case.baseline), signals=signals)
    comparison.extra = []  # a run has every connector; its baseline holds the outputs chosen for it
    return Outcome(case, PASS if comparison.passed else FAIL, _message(comparison), comparison)


def _message(c: Comparison) -> str:
    """One line: how many signals are inside, which are outside (worst first), what is lost."""
    failed = sorted(c.failed, key=lambda s: -s.severity)
    parts = []
    if failed:
        worst = ", ".join(f"{s.name} ({s.worst_excess:.3g} beyond at t = {s.worst_time:.3f} s)"
                          for s in failed[:3])
        more = f" and {len(failed) - 3} more" if len(failed) > 3 else ""
        parts.append(f"{len(failed)} of {len(c.checks)} signals outside their tubes: {worst}{more}")
    if c.lost:
        parts.append(f"missing from the run: {', '.join(c.lost)}")
    parts += c.problems
    if not parts:
        return f"{len(c.checks)} signals inside their tubes"
    return "; ".join(parts)


class SuiteInterrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM during a suite: ``outcomes`` holds every scenario, those not finished as
    ``not run``; ``exit_status`` is the shell's (130, 143)."""

    def __init__(self, outcomes: list[Outcome], exit_status: int) -> None:
        super().__init__()
        self.outcomes = outcomes
        self.exit_status = exit_status


def _serve(conn: multiprocessing.connection.Connection, settings: Settings) -> None:
    """A worker process: scenarios received one at a time, each outcome sent back, until None.
    Ctrl-C reaches the whole process group; only the parent handles it (it ends the workers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked since its start (below)
    try:
        while (case := conn.recv()) is not None:
            conn.send(check_case(case, settings))
    except (KeyboardInterrupt, EOFError):  # SIGTERM to the group, or the parent gone: it says so
        return


class _Worker:
    """A worker process, the pipe to it, and the scenario it runs (None: idle)."""

    def __init__(self, context: multiprocessing.context.SpawnContext, settings: Settings,
                 number: int) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, settings), daemon=True,
                                       name=f"regress worker {number}")
        self.process.start()
        child.close()
        self.index: int | None = None
        self.started = 0.0

    def give(self, index: int, case: Case) -> None:
        """Start scenario number ``index``."""
        self.index, self.started = index, time.monotonic()
        self.conn.send(case)

    def outcome(self, case: Case) -> Outcome | None:
        """The outcome it sent; an error naming how it died if it died first (the worker is then
        ended); None while it still runs."""
        try:
            if not self.conn.poll():
                if self.process.is_alive():
                    return None
                raise EOFError
            outcome: Outcome = self.conn.recv()
        except (EOFError, OSError):
            self.process.join()
            code = self.process.exitcode
            how = (f"died (signal {-code} ({signal.Signals(-code).name}))" if code is not None and code < 0
                   else f"ended (exit status {code})")
            outcome = Outcome(case, ERROR, f"the process running it {how} before it reported",
                              seconds=time.monotonic() - self.started)
            self.end()
        self.index = None
        return outcome

    def end(self, wait: float = 5.0) -> None:
        """Ask it to stop (when alive and idle), wait ``wait`` s, then kill it; close the pipe."""
        if self.process.is_alive() and self.index is None:
            try:
                self.conn.send(None)
            except OSError:
                pass
        self.process.join(wait)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


def run_cases(cases: Sequence[Case], jobs: int = 1, settings: Settings | None = None,
              done: Callable[[Outcome], None] | None = None, *, isolate: bool = True) -> list[Outcome]:
    """Run every case and compare it with its baseline; returns the outcomes in the order of
    ``cases``.

    Parameters
    ----------
    cases : sequence of Case
        The scenarios (:func:`find_cases`).
    jobs : int
        Scenarios run at once, each worker process running one after the other.
    settings : Settings, optional
        Timeout and baseline mode.
    done : callable, optional
        ``done(outcome)``, called as each scenario finishes.
    isolate : bool
        Run in worker processes (default), so that an FMU that crashes its process fails its
        scenario only (a new worker takes the rest); False: in this process, one after the other.

    Raises
    ------
    SuiteInterrupted
        On SIGINT or SIGTERM (KeyboardInterrupt): the workers are ended, the outcomes kept.
    """
    settings = settings or Settings()
    outcomes: dict[int, Outcome] = {}

    def finish(index: int, outcome: Outcome) -> None:
        outcomes[index] = outcome
        if done is not None:
            done(outcome)

    def every() -> list[Outcome]:
        return [outcomes.get(i) or Outcome(c, NOT_RUN, "not run: the suite was interrupted")
                for i, c in enumerate(cases)]

    workers: list[_Worker] = []
    try:
        if not isolate:
            for index, case in enumerate(cases):
                finish(index, check_case(case, settings))
            return every()
        _run_isolated(cases, max(1, jobs), settings, finish, workers)
        return every()
    except KeyboardInterrupt as exc:  # the workers hold nothing to keep: ended at once, without a word
        for worker in workers:
            if worker.process.is_alive():
                worker.process.kill()
        raise SuiteInterrupted(every(), getattr(exc, "exit_status", 130)) from None
    finally:
        for worker in workers:
            worker.end()


def _run_isolated(cases: Sequence[Case], jobs: int, settings: Settings,
                  finish: Callable[[int, Outcome], None], workers: list[_Worker]) -> None:
    """Every case in ``jobs`` worker processes (kept in ``workers``, which the caller ends); a
    worker that dies is replaced for the scenarios left."""
    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads or FMUs
    # The first spawn starts multiprocessing's resource tracker, and starting it unblocks SIGINT in
    # this process (CPython's bpo-33613 guard): started now, before _start_worker blocks SIGINT, so
    # that the first worker too inherits the block (it printed a KeyboardInterrupt traceback from
    # its imports when Ctrl-C came while it started).
    multiprocessing.resource_tracker.ensure_running()
    pending = list(enumerate(cases))
    started = 0
    while pending or _busy(workers):
        workers[:] = [w for w in workers if w.process.is_alive() or w.index is not None]
        started = _top_up(workers, jobs, pending, context, settings, started)
        busy = _busy(workers)
        multiprocessing.connection.wait([*(w.conn for w in busy), *(w.process.sentinel for w in busy)])
        _collect(busy, cases, finish)


def _top_up(workers: list[_Worker], jobs: int, pending: list[tuple[int, Case]],
            context: multiprocessing.context.SpawnContext, settings: Settings, started: int) -> int:
    """Up to ``jobs`` workers while scenarios are pending, each idle one given the next scenario;
    the number of workers started so far."""
    while pending and len(workers) < jobs:
        started += 1
        _start_worker(workers, context, settings, started)
    for worker in workers:
        if worker.index is None and pending:
            worker.give(*pending.pop(0))
    return started


def _busy(workers: Sequence[_Worker]) -> list[_Worker]:
    """The workers running a scenario."""
    return [w for w in workers if w.index is not None]


def _start_worker(workers: list[_Worker], context: multiprocessing.context.SpawnContext, settings: Settings,
                  number: int) -> None:
    """Worker ``number`` into ``workers``, SIGINT blocked while it starts and until it is there: a
    Ctrl-C during its imports waits for _serve to ignore it (no traceback from the worker), and the
    parent, which gets its own at once after, ends every worker it started."""
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        workers.append(_Worker(context, settings, number))
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _collect(busy: Sequence[_Worker], cases: Sequence[Case], finish: Callable[[int, Outcome], None]) -> None:
    """``finish`` each case whose worker has its outcome (finished, or died on it)."""
    for worker in busy:
        index = worker.index
        outcome = worker.outcome(cases[index]) if index is not None else None
        if index is not None and outcome is not None:
            finish(index, outcome)


def scenario_line(outcome: Outcome, width: int = 0) -> str:
    """``REGRESSION  name  message  (1.2 s)``: one line per scenario, as the terminal shows it."""
    warned = f"; {len(outcome.warnings)} warning(s) in the report" if outcome.warnings else ""
    took = f" ({outcome.seconds:.1f} s)" if outcome.status != NOT_RUN else ""
    return f"{LABELS[outcome.status]:<10}  {outcome.case.name:<{width}}  {outcome.message}{warned}{took}"


def summary_line(outcomes: Sequence[Outcome], seconds: float, jobs: int) -> str:
    """``3 scenarios: 1 passed, 2 regressed, 0 failed to run (5.2 s, 2 jobs)``."""
    count = {s: sum(o.status == s for o in outcomes) for s in LABELS}
    verdict = "PASS" if count[PASS] == len(outcomes) else "REGRESSION"
    skipped = f", {count[NOT_RUN]} not run" if count[NOT_RUN] else ""
    return (f"{verdict}: {len(outcomes)} scenario{'s' if len(outcomes) != 1 else ''}: {count[PASS]} passed, "
            f"{count[FAIL]} regressed, {count[ERROR]} failed to run{skipped} ({seconds:.1f} s, "
            f"{jobs} job{'s' if jobs != 1 else ''})")


def default_jobs(count: int) -> int:
    """Worker processes when none are asked for: one per core the process may use, at most one
    per scenario."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores, count))

