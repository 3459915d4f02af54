# SPDX-License-Identifier: BSD-2-Clause
"""Subcommands of the regression application: ``regress`` (a suite of scenarios against their
baselines, with JUnit XML and an HTML report), ``baseline`` (write and review baselines) and
``compare`` (one result file against one baseline)."""

from __future__ import annotations

import argparse
import fnmatch
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..cli import add_command
from ..errors import OutputError, UsageError
from ..files import not_regular, temporary_folder
from ..provenance import read_provenance, summary
from ..results import Columns, open_columns
from . import review
from .figures import plot_failures
from .junit import write_junit
from .merged import compare_columns
from .report import REPORT_NAME, write_report
from .suite import (
    ERROR,
    FAIL,
    LABELS,
    PASS,
    Case,
    Outcome,
    Settings,
    SuiteInterrupted,
    check_setup,
    default_jobs,
    find_cases,
    run_cases,
    scenario_line,
    summary_line,
)
from .tubes import (
    BASELINE_GRID,
    TOLERANCES_NAME,
    Tolerance,
    Tolerances,
    format_comparison,
    load_tolerances,
    parse_tolerance,
    tolerances_beside,
    write_baseline,
)

__all__ = ["register"]

LAYOUT = """\
layout: each scenario (NAME.ssp, or a folder NAME/ holding SystemStructure.ssd) has its baseline in
the folder baselines/ beside it, baselines/NAME.csv, and the tubes of the folder's scenarios in
baselines/tolerances.json (without it: 1 % of each signal's range); --baselines DIR puts every
baseline and the tolerances in DIR instead. A folder given is searched for scenarios at any
depth. Each scenario runs its own DefaultExperiment, in worker processes (--jobs): an FMU that
crashes fails its scenario only. docs/regression.md describes it all."""

REGRESS_HELP = f"""\
Run every scenario found in PATH... and compare it with its baseline: every signal of the baseline
must stay inside its tube (and be produced). One line per scenario as it finishes, then a summary.

{LAYOUT}

exit status: 0 every scenario inside its tubes, 1 a regression (a signal outside its tube or
missing, a scenario that does not run to its end), 2 usage error or unreadable input (a scenario
without a baseline, a bad tolerance file, a stale build), 130/143 interrupted (SIGINT/SIGTERM:
the reports are written with the scenarios not run marked so).
"""

BASELINE_HELP = f"""\
Run every scenario found in PATH... and write its baseline (its outputs on a grid of about
--grid s, the run's own rows). A scenario without a baseline gets one; an existing baseline is
replaced only when accepted: --accept NAME (the whole scenario), --accept NAME:SIGNAL (one
column), --accept-all. Before that, each new run is compared with the baseline it would replace:
one line per scenario and per signal that moved (by how much, inside or beyond its tube), and
with --review DIR the same HTML report as 'regress' writes. FMUs are never rebuilt: build them
first (this project: 'orchestrate build' or 'make build'; a stale build is refused).

{LAYOUT}

exit status: 0 done (what was accepted written), 1 a scenario failed to run (nothing of it
written) or a baseline could not be written, 2 usage error, 130/143 interrupted (nothing written).
"""

COMPARE_HELP = """\
Compare every signal the result and the baseline both have (or those chosen with --signal) inside
the baseline's tubes. A baseline signal the result does not have is listed as missing and, unless
chosen with --signal, not part of the verdict.

exit status: 0 every compared signal inside its tube, 1 regression (a signal outside its tube, a
chosen signal missing, a result that does not cover the baseline's time span, nothing in common),
2 usage or unreadable input.
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``regress``, ``baseline`` and ``compare`` to ``orchestrate``."""
    p = add_command(sub, "regress", _regress,
                    help="run scenarios against their baselines (JUnit XML, HTML report)",
                    description=REGRESS_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    _suite_arguments(p)
    p.add_argument("--junit-xml", type=Path, metavar="FILE", help="write the JUnit XML of the suite to FILE")
    p.add_argument("--html", type=Path, metavar="DIR", help=f"write the HTML report to DIR/{REPORT_NAME}")
    p.add_argument("--quiet", action="store_true", help="no line for a scenario that passes")

    p = add_command(sub, "baseline", _baseline, help="write baselines, review and accept their updates",
                    description=BASELINE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    _suite_arguments(p)
    p.add_argument("--grid", type=float, default=BASELINE_GRID, metavar="S",
                   help=f"spacing of a baseline's rows, rounded to a multiple of the step "
                        f"(default {BASELINE_GRID})")
    p.add_argument("--review", type=Path, metavar="DIR",
                   help=f"write the HTML report of the changes to DIR/{REPORT_NAME}")
    p.add_argument("--accept", action="append", default=[], metavar="NAME[:SIGNAL]",
                   help="replace the baseline of scenario NAME (or only its column SIGNAL) (repeatable)")
    p.add_argument("--accept-all", action="store_true", help="replace every baseline that changed")

    p = add_command(sub, "compare", _compare, help="compare a result file with a baseline (regression tubes)",
                    description=COMPARE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("result", type=Path, metavar="RESULT.csv")
    p.add_argument("baseline", type=Path, metavar="BASELINE.csv")
    p.add_argument("--tolerances", type=Path, metavar="FILE.json",
                   help=f"tubes (default: {TOLERANCES_NAME} beside the baseline, else 1 %% of range)")
    p.add_argument("--tol", action="append", default=[], metavar="SIGNAL=ATOL|KEY:VALUE,...",
                   help="one signal's tube, e.g. plant.y=1e-3 or plant.y=atol:1e-3,quiet_atol:1e-6")
    p.add_argument("--signal", action="append", default=[], metavar="PATTERN",
                   help="compare only the baseline's signals matching this shell pattern, each required of "
                        "the result (repeatable; default: every signal both have)")
    p.add_argument("--plot-dir", type=Path, metavar="DIR", help="write DIR/<signal>.png per failing signal")


def _suite_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help=".ssp archive, scenario folder, built scenario name, or a folder to search")
    p.add_argument("--baselines", type=Path, metavar="DIR",
                   help="the folder of every baseline and tolerances.json (default: baselines/ beside "
                        "each scenario)")
    p.add_argument("--jobs", "-j", type=int, metavar="N",
                   help="scenarios run at once, each in its own process (default: one per core)")
    p.add_argument("--timeout", type=float, metavar="SECONDS", help="wall-clock limit of each scenario's run")
    p.add_argument("--allow-stale", action="store_true",
                   help="run scenarios an application's check finds stale (e.g. a build older than its "
                        "sources)")


def _setup(args: argparse.Namespace, need_baseline: bool) -> tuple[list[Case], int, Settings]:
    if args.jobs is not None and args.jobs < 1:
        raise UsageError("--jobs must be at least 1")
    if args.timeout is not None and not args.timeout > 0:
        raise UsageError("--timeout must be a positive number of seconds")
    cases = find_cases(args.paths, args.baselines)
    check_setup(cases, need_baseline=need_baseline, allow_stale=args.allow_stale)
    jobs = args.jobs or default_jobs(len(cases))
    return cases, min(jobs, len(cases)), Settings(timeout=args.timeout)


def _check_outputs(files: Sequence[Path | None], folders: Sequence[Path | None]) -> None:
    """Refuse output places that cannot be written before anything runs."""
    for path in files:
        if path is not None and not_regular(path):
            raise UsageError(f"{path}: {not_regular(path)}")
    for folder in folders:
        if folder is not None and folder.exists() and not folder.is_dir():
            raise UsageError(f"{folder}: not a folder")


def _run(cases: list[Case], jobs: int, settings: Settings,
         show: Callable[[Outcome], bool]) -> tuple[list[Outcome], float, int]:
    """Run the suite, printing the line of each scenario ``show`` selects as it finishes; returns
    the outcomes, the wall time and 0 (or the exit status of an interruption)."""
    width = max(len(c.name) for c in cases)
    where = f"{len(cases)} scenario{'s' if len(cases) != 1 else ''}, {jobs} job{'s' if jobs != 1 else ''}"
    print(f"running {where}", flush=True)

    def done(outcome: Outcome) -> None:
        if show(outcome):
            print(scenario_line(outcome, width), flush=True)

    started = time.monotonic()
    try:
        return run_cases(cases, jobs, settings, done), time.monotonic() - started, 0
    except SuiteInterrupted as exc:
        print(f"orchestrate: interrupted by {'SIGTERM' if exc.exit_status == 143 else 'SIGINT'}: "
              f"{sum(o.status != 'not run' for o in exc.outcomes)} of {len(cases)} scenarios finished",
              file=sys.stderr)
        return exc.outcomes, time.monotonic() - started, exc.exit_status


def _write(what: str, write: Callable[[], Path]) -> str:
    """Call ``write()``; a file that cannot be written is one line on stderr ('' returned)."""
    try:
        return str(write())
    except OSError as exc:
        print(f"orchestrate: error: cannot write the {what}: {exc}", file=sys.stderr)
        return ""


def _regress(args: argparse.Namespace) -> int:
    _check_outputs([args.junit_xml], [args.html])
    cases, jobs, settings = _setup(args, need_baseline=True)
    outcomes, seconds, interrupted = _run(cases, jobs, settings, lambda o: not args.quiet or o.status != PASS)
    line = summary_line(outcomes, seconds, jobs)
    print(line)
    written = True
    if args.junit_xml is not None:
        path = _write("JUnit XML", lambda: write_junit(outcomes, seconds, args.junit_xml))
        if path:
            print(f"JUnit XML:   {path}")
        written &= bool(path)
    if args.html is not None:
        title = "Co-simulation regression"
        path = _write("HTML report", lambda: write_report(outcomes, args.html, title, line))
        if path:
            print(f"HTML report: {path}")
        written &= bool(path)
    if interrupted:
        return interrupted
    if any(o.status in (FAIL, ERROR) for o in outcomes):
        return 1
    return 0 if written else 2


def _baseline(args: argparse.Namespace) -> int:
    if not args.grid > 0:
        raise UsageError("--grid must be a positive number of seconds")
    _check_outputs([], [args.review])
    cases, jobs, settings = _setup(args, need_baseline=False)
    acceptance = review.parse_accept(args.accept, cases, args.accept_all)
    settings = Settings(timeout=settings.timeout, baseline=True, grid=args.grid)
    outcomes, seconds, interrupted = _run(cases, jobs, settings, lambda o: o.status == ERROR)
    if interrupted:
        print("nothing written")
        return interrupted
    failed = [o for o in outcomes if o.status == ERROR]
    width = max(len(c.name) for c in cases)
    # every acceptance checked before the first baseline is written
    plans = {i: review.accepted(o, acceptance) for i, o in enumerate(outcomes) if o.status != ERROR}
    pending = [outcomes[i].case.name for i, plan in plans.items()
               if not _write_one_baseline(outcomes[i], plan, width)]
    if args.review is not None:
        _write_review(outcomes, args.review, len(pending), seconds)
    return _left_out(failed, pending)


def _left_out(failed: Sequence[Outcome], pending: Sequence[str]) -> int:
    """Name the scenarios whose baseline was not written (run failed, change not accepted); the
    exit status: 1 when a run failed."""
    if failed:
        print(f"no baseline written for {', '.join(o.case.name for o in failed)}: the run failed (above)")
    if pending:
        print(f"not accepted: {', '.join(pending)} (accept with --accept NAME, --accept NAME:SIGNAL or "
              "--accept-all)")
    return 1 if failed else 0


def _write_one_baseline(o: Outcome, plan: tuple[np.ndarray | None, str], width: int) -> bool:
    """Write the run's baseline as ``plan`` (the table to write, what was done) says and print one
    line for it (and its signals, where it moved or changed); False when a change waits for
    acceptance."""
    label = _baseline_label(o)
    table, done = plan
    if table is not None:
        try:
            write_baseline(table, o.case.baseline)
        except OSError as exc:
            raise OutputError(f"{o.case.baseline}: {exc}") from None
    print(f"{label:<10}  {o.case.name:<{width}}  {done if label == 'new' else review.review_message(o)}")
    for text in review.signal_lines(o) if label in ("moved", "CHANGED") else []:
        print(text)
    if done and label != "new":
        print(f"{'':<10}  {'':<{width}}  {done}")
    return bool(done) or label not in ("moved", "CHANGED")


def _baseline_label(o: Outcome) -> str:
    """How the new run stands to the old baseline: new, unchanged, moved (within the tubes) or CHANGED."""
    if o.comparison is None:
        return "new"
    if not review.moved(o):
        return "unchanged"
    return "moved" if o.status == PASS else "CHANGED"


def _write_review(outcomes: Sequence[Outcome], target: Path, pending: int, seconds: float) -> None:
    """The baseline review as an HTML report at ``target``: what each new run changes."""
    heading = (f"baseline review: {len(outcomes)} scenarios, {pending} with changes not accepted "
               f"({seconds:.1f} s)")
    shown = [_as_review(o) for o in outcomes]
    title, labels = "Baseline review", {**LABELS, PASS: "OK", FAIL: "CHANGED"}
    path = _write("review", lambda: write_report(shown, target, title, heading, "new run", labels))
    if path:
        print(f"review: {path}")


def _as_review(o: Outcome) -> Outcome:
    """The outcome as the review report shows it: its line says what the new run changes."""
    return Outcome(o.case, o.status, review.review_message(o), o.comparison, o.warnings, o.seconds, o.detail)


def _compare(args: argparse.Namespace) -> int:
    """``orchestrate compare``: each file parsed once into a column file per signal in a temporary
    folder, compared a signal at a time (memory: a few columns, not the files)."""
    folder = temporary_folder("compare-")
    try:
        (folder / "result").mkdir()
        (folder / "baseline").mkdir()
        return _compare_files(args, open_columns(args.result, folder / "result"),
                              open_columns(args.baseline, folder / "baseline"))
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _tolerance_overrides(texts: Sequence[str], tolerances: Tolerances, columns: Sequence[str],
                         baseline: Path) -> dict[str, Tolerance]:
    """The --tol options as signal -> tolerance; UsageError naming a signal the baseline lacks."""
    overrides = dict(parse_tolerance(text, tolerances) for text in texts)
    unknown = [n for n in overrides if n not in columns]
    if unknown:
        raise UsageError(f"--tol: no signal {', '.join(unknown)} in {baseline} "
                         f"(signals: {', '.join(columns)})")
    return overrides


def _chosen_signals(patterns: Sequence[str], columns: Sequence[str], baseline: Path) -> list[str]:
    """The signals of ``columns`` that the --signal patterns match; UsageError for a pattern that
    matches none."""
    unmatched = [p for p in patterns if not fnmatch.filter(columns, p)]
    if unmatched:
        raise UsageError(f"--signal: no signal of {baseline} matches {', '.join(unmatched)} "
                         f"(signals: {', '.join(columns)})")
    return [n for n in columns if any(fnmatch.fnmatchcase(n, p) for p in patterns)]


def _compare_files(args: argparse.Namespace, result: Columns | np.ndarray,
                   baseline: Columns | np.ndarray) -> int:
    tolerances = load_tolerances(args.tolerances).for_scenario(args.baseline.stem) if args.tolerances \
        else tolerances_beside(args.baseline)
    columns = [n for n in baseline.dtype.names or () if n != "time"]
    overrides = _tolerance_overrides(args.tol, tolerances, columns, args.baseline)
    signals = _chosen_signals(args.signal, columns, args.baseline) if args.signal else None
    comparison = compare_columns(result, baseline, tolerances.with_overrides(overrides), str(args.result),
                                 str(args.baseline), signals=signals, failed_arrays=args.plot_dir is not None)
    print(f"result:   {args.result}: {summary(read_provenance(args.result))}")
    print(f"baseline: {args.baseline}: {summary(read_provenance(args.baseline))}")
    print(format_comparison(comparison))
    if args.plot_dir is not None:
        for path in plot_failures(comparison, args.plot_dir):
            print(path)
    return 0 if comparison.passed else 1
