# SPDX-License-Identifier: BSD-2-Clause
"""Subcommands of the paper's experiments: build, metrics, report."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import cast

import numpy as np

from fmu_src.toolchain.build import PLATFORM_NAMES, BuildError

from ..cli import add_command, quiet, warn
from ..errors import OrchestratorError, ScenarioError, UsageError
from ..provenance import read_provenance, summary
from ..results import read_result
from . import report
from .metrics import TrackingMetrics, format_table, tracking_metrics
from .scenarios import SCENARIO_DIR, build_scenarios

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the experiments' subcommands to ``orchestrate``."""
    p = add_command(sub, "build", _build, help="build the FMUs and pack the scenarios into .ssp archives",
                    quiet=True)
    p.add_argument("scenarios", nargs="*", metavar="NAME", help="scenarios to pack (default: all)")
    p.add_argument("--sources", type=Path, default=SCENARIO_DIR,
                   help="scenario sources (default: the project's ssp/, or its installed copy)")
    p.add_argument("-o", "--output", "--dest", dest="dest", type=Path, default=Path("build"),
                   help="output folder (default: ./build/)")
    p.add_argument("--force", action="store_true", help="rebuild everything, even what is up to date")
    p.add_argument("--platform", action="append", dest="platforms", choices=PLATFORM_NAMES,
                   help="build at least this platform (repeatable; default: every platform this machine "
                        "can build: linux64, and win64 where mingw-w64 and osslsigncode are installed)")
    p.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1, metavar="N",
                   help="FMUs built at once, each in its own process (default: the machine's cores)")
    p.add_argument("--no-fmi3", dest="fmi3", action="store_false",
                   help="no FMI 3.0 variants of the FMUs and no <name>_fmi3.ssp twins")

    p = add_command(sub, "metrics", _metrics, help="tracking metrics of result files (SPEC section 4)",
                    quiet=True)
    p.add_argument("results", nargs="+", type=Path, metavar="RESULT.csv")
    p.add_argument("--band", type=float, default=0.05, help="settling band on |y - yd| (default 0.05)")
    p.add_argument("--signal", default="plant.y", metavar="COLUMN", help="the output y (default plant.y)")
    p.add_argument("--reference", default="reference.yd", metavar="COLUMN",
                   help="the reference yd it tracks (default reference.yd)")

    p = add_command(sub, "report", _report, help="the paper's examples by co-simulation, as a report",
                    description=report.__doc__.split("\n\n")[0], quiet=True)
    p.add_argument("-o", "--output", "--out", dest="out", type=Path, default=report.DEFAULT_OUT,
                   help=f"output folder ({report.DEFAULT_OUT}/)")
    p.add_argument("--stop-time", type=float, metavar="T", help="horizon of the four runs (the SSD's)")
    p.add_argument("--study-horizon", type=float, default=report.STUDY_HORIZON, metavar="T",
                   help=f"horizon of the settling study (default {report.STUDY_HORIZON:g} s)")
    p.add_argument("--study-values", type=float, nargs="+", default=list(report.STUDY_VALUES), metavar="V",
                   help="initial x1(0) and x2(0) values of the study (default: -2 -1 0 1 2)")
    p.add_argument("--processes", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--campaigns", type=Path, metavar="DIR",
                   help="also report the shipped campaigns whose tables are DIR/<name>/runs.parquet")


def _build(args: argparse.Namespace) -> int:
    if not args.scenarios and not list(args.sources.glob("*/SystemStructure.ssd")):
        raise UsageError(f"no scenarios found in {args.sources}/")
    if args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: at least 1")
    log = args.dest / "build.log"
    args.dest.mkdir(parents=True, exist_ok=True)
    with log.open("a", encoding="utf-8") as logged:
        logged.write(f"--- orchestrate build {' '.join(args.scenarios) or '(all)'}, "
                     f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n")

        def progress(line: str) -> None:  # a line per product, as it is done: on stderr and in the log
            logged.write(line + "\n")
            logged.flush()
            if not quiet():
                print(f"build: {line}", file=sys.stderr, flush=True)

        try:
            targets = build_scenarios(args.scenarios, args.dest, args.sources, fmi3=args.fmi3,
                                      platforms=args.platforms, force=args.force, progress=progress,
                                      jobs=args.jobs)
        except BuildError as error:  # a compiler or source missing: what, not a traceback
            logged.write(f"error: {error}\n")
            raise OrchestratorError(f"build: {error} (log: {log})") from None
    for target in targets.values():
        if not quiet():
            print(target)
    return 0


def _metrics(args: argparse.Namespace) -> int:
    rows, notes = [], []
    for path in args.results:
        data = read_result(path)
        _check_columns(path, data, args)
        record = read_provenance(path)
        _check_grid(path, record)
        label = _label(path, args.results)
        rows.append((label, _result_metrics(path, data, args)))
        notes.append(f"{label}: {summary(record)}")
        _warn_partial(path, data, record)
    print(format_table(rows))
    if not quiet():
        print()
        print("\n".join(notes))
    return 0


def _check_columns(path: Path, data: np.ndarray, args: argparse.Namespace) -> None:
    """ScenarioError naming the result's columns when --signal or --reference is not one."""
    names = data.dtype.names or ()  # a result is a structured array: never None
    missing = [c for c in (args.signal, args.reference) if c not in names]
    if missing:
        columns = ", ".join(n for n in names if n != "time")
        raise ScenarioError(f"{path}: no column {', '.join(missing)} (choose with --signal and "
                            f"--reference; columns: {columns})")


def _result_metrics(path: Path, data: np.ndarray, args: argparse.Namespace) -> TrackingMetrics:
    """The tracking metrics of one result's --signal against --reference (with the controller's v
    and the actuator's output where the result has them)."""
    names = data.dtype.names or ()
    try:
        return tracking_metrics(data["time"], data[args.signal], data[args.reference],
                                data["controller.v"] if "controller.v" in names else None,
                                data["actuator.uf"] if "actuator.uf" in names else None, band=args.band)
    except ValueError as exc:
        raise ScenarioError(f"{path}: {exc}") from exc


def _warn_partial(path: Path, data: np.ndarray, record: Mapping[str, object] | None) -> None:
    """Warn when the result's run did not complete or its rows end before its stop time."""
    if record is not None and record.get("status") != "complete":
        span = f"{record.get('start_time')} .. {record.get('stop_time')} s"
        warn(f"{path}: partial result ({record.get('status')} at t = {record.get('last_time')} s of "
             f"{span}): the metrics cover only the rows written")
    elif record is not None and float(data["time"][-1]) < float(cast("float | str", record["stop_time"])):
        warn(f"{path}: ends at t = {data['time'][-1]:g} s, before the run's stop time "
             f"{record['stop_time']} s: the metrics cover only the rows written")


def _label(path: Path, paths: list[Path]) -> str:
    """A result's row name: its stem, unless another result shares it (p.csv, p.parquet, p.mat were
    three rows called p): then its file name, or its whole path when that is shared too."""
    if sum(p.stem == path.stem for p in paths) == 1:
        return path.stem
    return path.name if sum(p.name == path.name for p in paths) == 1 else str(path)


def _check_grid(path: Path, record: dict | None) -> None:
    """Refuse a result written on a coarser grid than its run's step: the metrics are sums over
    every sample of the run (SPEC section 4), and a decimated grid changes them (RAE 0.0331 ->
    0.0575 on example1 at --output-interval 0.05)."""
    output = record.get("output") if record else None
    interval = output.get("interval") if isinstance(output, dict) else None
    step = record.get("step") if record else None
    if isinstance(interval, (int, float)) and isinstance(step, (int, float)) and interval > step * (1 + 1e-9):
        raise UsageError(f"{path}: written every {interval:g} s (--output-interval) of a run at {step:g} s: "
                         "the metrics need every step; run again without --output-interval")


def _report(args: argparse.Namespace) -> int:
    if args.processes < 1:
        raise UsageError("--processes must be at least 1")
    written = report.write_report(args.out, args.stop_time, args.study_values, args.study_horizon,
                                  args.processes, args.campaigns)
    if not quiet():
        print(written)
    return 0
