# SPDX-License-Identifier: BSD-2-Clause
"""Subcommands ``orchestrate sweep`` and ``orchestrate campaign-report``.

An application that knows which metrics a campaign should compute registers them through
:func:`register` (the paper's tracking metrics: ``orchestrator.experiments.campaigns``).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..cli import (
    add_archive_limits,
    add_command,
    add_output,
    archive_limits,
    parse_overrides,
    resolve_scenario,
    warn,
)
from ..errors import UsageError
from .design import Design, read_design
from .report import write_report
from .sweep import DASHBOARD, SCHEDULER_ENV, CampaignInterrupted, CampaignSummary, sweep
from .worker import Metrics

__all__ = ["register"]

SWEEP_HELP = f"""\
Run every variant of a design (TOML or JSON: grid, ranges with counts, random/LHS samples with a
seed, or an explicit CSV/Parquet table; see orchestrator/campaign/design.py) on each SCENARIO, on
Dask: an embedded cluster with one worker process per core, or --scheduler tcp://HOST:PORT (or
${SCHEDULER_ENV}) for an existing one. Writes OUT/runs.csv (one row per finished run, appended as
runs finish), OUT/runs.parquet and OUT/campaign.json; a failed run is a row with its reason.

exit status: 0 every run ok, 1 some run failed or timed out (or a scenario error), 2 usage error,
130 interrupted (finished rows kept; rerun with --resume to continue).
"""


def register(sub: argparse._SubParsersAction, metrics: Metrics | None = None) -> None:
    """Add ``sweep`` and ``campaign-report``; ``metrics`` become the table's metric columns."""
    p = add_command(
        sub,
        "sweep",
        lambda args: _sweep(args, metrics),
        help="run a campaign of scenario variants",
        description=SWEEP_HELP,
        quiet=True,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "scenarios",
        nargs="+",
        metavar="SCENARIO",
        help=".ssp file, scenario folder or built scenario name (several: crossed with the design)",
    )
    p.add_argument("--design", type=Path, required=True, metavar="FILE", help="design file (.toml or .json)")
    add_output(p, "DIR", "output folder (default: results/campaigns/<design>)", aliases=["--out"])
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="COMPONENT.VARIABLE=VALUE",
        help="an extra fixed override for every run (repeatable)",
    )
    p.add_argument(
        "--stop-time", type=float, metavar="T", help="stop time of every run (default: the design's)"
    )
    p.add_argument("--step", type=float, metavar="H", help="communication step (default: the design's)")
    p.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help=f"an existing Dask scheduler (default: ${SCHEDULER_ENV}, else an embedded cluster)",
    )
    p.add_argument(
        "--workers", type=int, metavar="N", help="embedded cluster: worker processes (default: cores)"
    )
    p.add_argument(
        "--timeout", type=float, metavar="S", help="wall-time limit per run (default: the design's)"
    )
    p.add_argument("--resume", action="store_true", help="skip runs already in OUT/runs.csv (ok or failed)")
    p.add_argument("--force", action="store_true", help="start again, discarding OUT/runs.csv")
    p.add_argument(
        "--keep-trajectories", action="store_true", help="write OUT/trajectories/run-NNNNN-ID.parquet per run"
    )
    p.add_argument(
        "--trajectory-every",
        type=int,
        default=1,
        metavar="N",
        help="with --keep-trajectories: keep every N-th row (and the last)",
    )
    p.add_argument(
        "--plot", type=Path, metavar="DIR", help="also write the campaign report (figures + summary)"
    )
    p.add_argument(
        "--dashboard",
        metavar="HOST:PORT",
        default=DASHBOARD,
        help="embedded cluster: where its Dask dashboard listens (default: this host only, a free port)",
    )
    add_archive_limits(p)

    p = add_command(
        sub, "campaign-report", _report, help="figures and a Markdown summary of a campaign table", quiet=True
    )
    p.add_argument(
        "table", type=Path, metavar="TABLE", help="runs.parquet (or runs.csv beside campaign.json)"
    )
    add_output(p, "DIR", "output folder (default: report/ beside TABLE)", aliases=["--out"])


def _describe(s: CampaignSummary) -> str:
    return (
        f"{s.total} runs ({s.skipped} kept from before): {s.ok} ok, {s.failed} failed, {s.timed_out} "
        f"timed out{f', {s.not_run} not run' if s.not_run else ''}; {s.wall_time:.1f} s"
        + (f" on {s.workers} workers" if s.workers else "")
        + f" -> {s.table}, {s.parquet}"
    )


def _sweep(args: argparse.Namespace, metrics: Metrics | None) -> int:
    design = _design(args)
    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    if args.workers is not None and args.scheduler:
        raise UsageError("--workers sizes the embedded cluster; an external one (--scheduler) has its own")
    if args.trajectory_every < 1:
        raise UsageError("--trajectory-every must be at least 1")
    scenarios = [resolve_scenario(s) for s in args.scenarios]
    out = args.output or Path("results") / "campaigns" / args.design.stem
    try:
        summary = sweep(
            scenarios,
            design,
            out,
            metrics=metrics,
            scheduler=args.scheduler,
            workers=args.workers,
            resume=args.resume,
            force=args.force,
            timeout=args.timeout,
            keep_every=args.trajectory_every if args.keep_trajectories else None,
            progress=not args.quiet and sys.stderr.isatty(),  # as 'run': no bar in a log file
            limits=archive_limits(args),
            dashboard=args.dashboard,
        )
    except CampaignInterrupted as exc:
        s = exc.summary
        print(
            f"orchestrate: interrupted; {s.ok + s.failed + s.timed_out} of {s.total} runs kept in {s.table} "
            "(rerun with --resume to continue)",
            file=sys.stderr,
        )
        return 130
    return _finish(args, summary)


def _design(args: argparse.Namespace) -> Design:
    """The design file's design with the command line's --set, --stop-time and --step on top (and
    --timeout checked: the sweep takes it apart)."""
    design = read_design(args.design)
    extra = parse_overrides(args.set)
    changes: dict[str, Any] = {}
    if extra:
        changes["fixed"] = {**design.fixed, **extra}
    for name in ("stop_time", "step", "timeout"):
        value = getattr(args, name)
        if value is not None:
            if not math.isfinite(value) or (value <= 0 and name != "stop_time"):
                raise UsageError(
                    f"--{name.replace('_', '-')} must be {'positive and ' if name != 'stop_time' else ''}"
                    f"finite (got {value!r})"
                )
            if name != "timeout":
                changes[name] = value
    return replace(design, **changes) if changes else design


def _finish(args: argparse.Namespace, summary: CampaignSummary) -> int:
    """Say how the sweep went (lost workers, runs not run), draw the report if asked; the exit
    status: 0 when every run is ok."""
    if not args.quiet:
        print(_describe(summary))
    for worker, runs in summary.lost_workers.items():
        held = f"runs {', '.join(map(str, runs))} were on it, run again elsewhere" if runs else "no run on it"
        warn(f"worker {worker} was lost ({held})")
    if summary.not_run:
        print(f"orchestrate: error: {summary.not_run} of {summary.total} runs not run: the cluster did not "
              f"finish them ({summary.not_run_reason}); rerun with --resume to run them", file=sys.stderr)
        return 1
    if args.plot is not None:
        report = write_report(summary.parquet, args.plot)
        if not args.quiet:
            print(report)
    return 0 if summary.failed == summary.timed_out == 0 else 1


def _report(args: argparse.Namespace) -> int:
    if not args.table.is_file():
        raise UsageError(f"{args.table}: no such table")
    summary = write_report(args.table, args.output or args.table.parent / "report")
    if not args.quiet:
        print(summary)
    return 0
