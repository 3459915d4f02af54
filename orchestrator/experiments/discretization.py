# SPDX-License-Identifier: BSD-2-Clause
"""Chattering of the sampled controller: explicit sampling (the paper's law, held) against the
semi-implicit discretization (``controller.params.Discretization``) and the continuous law.

    python -m orchestrator.experiments.discretization [--jobs 2] [--output results/discretization.md]

One run measures both examples, both modes, at h = 0.5, 1, 2 and 5 ms, on the monolithic reference
(``closed_loop.simulate``: the sampled law with a zero-order hold, plant and controller states by
``solve_ivp``; no FMU), and prints the tables and the issue-11 targets at 1 ms.

Chattering measures, on the samples after ``START`` = 1 s (the transient excluded):

* total variation of v per second: sum |v_{k+1} - v_k| / (t_last - t_first);
* peak |v|;
* a **chattering sample** is a reversal of v (v_k - v_{k-1} and v_{k+1} - v_k of opposite signs)
  with both changes larger than ``RATE`` * h, ``RATE`` = 50 per second: v moving back and forth at
  over 50 units per second (the continuous law never does after 1 s on either example: its largest
  |v'| there is 230 /s on Example 1 and 330 /s on the pendulum, but never reversing at that rate);
* a **burst** is a maximal group of chattering samples with gaps under ``GAP`` = 0.1 s; its length
  is from its first to its last chattering sample plus one step. Reported: the number of bursts,
  their total and their longest length.
"""

from __future__ import annotations

import argparse
import multiprocessing
import queue as queues
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from controller.params import EXPLICIT, FINITE_TIME, FIXED_TIME, SEMI_IMPLICIT, Mode
from fmu_src.models.examples import EXAMPLES

from .closed_loop import SolverError, simulate
from .metrics import TrackingMetrics, tracking_metrics

__all__ = ["Case", "Chattering", "Outcome", "chattering", "main", "run_case"]

START = 1.0
RATE = 50.0
GAP = 0.1
SAMPLE_TIMES = (5e-4, 1e-3, 2e-3, 5e-3)
METHODS = ("explicit", "semi-implicit", "continuous")


@dataclass(frozen=True)
class Chattering:
    """Chattering measures of one control signal after ``START`` (module docstring)."""

    tv_per_second: float
    peak: float
    bursts: int
    burst_time: float
    longest_burst: float


def chattering(t: ArrayLike, v: ArrayLike, start: float = START, rate: float = RATE,
               gap: float = GAP) -> Chattering:
    """Total variation per second, peak |v| and bursts of ``v`` on the uniform grid ``t`` from ``start``."""
    t = np.asarray(t, dtype=float)
    v = np.asarray(v, dtype=float)
    keep = t >= start - 1e-12
    t, v = t[keep], v[keep]
    if t.size < 3:
        raise ValueError(f"chattering needs at least 3 samples after t = {start} (got {t.size})")
    h = (t[-1] - t[0]) / (t.size - 1)
    dv = np.diff(v)
    tv = float(np.sum(np.abs(dv)) / (t[-1] - t[0]))
    reversal = (dv[1:] * dv[:-1] < 0.0) & (np.minimum(np.abs(dv[1:]), np.abs(dv[:-1])) > rate * h)
    times = t[1:-1][reversal]
    bursts: list[tuple[float, float]] = []
    for s in times:
        if bursts and s - bursts[-1][1] < gap:
            bursts[-1] = (bursts[-1][0], float(s))
        else:
            bursts.append((float(s), float(s)))
    lengths = [b - a + h for a, b in bursts]
    return Chattering(tv, float(np.max(np.abs(v))), len(bursts), float(sum(lengths)),
                      float(max(lengths, default=0.0)))


@dataclass(frozen=True)
class Case:
    """One run: example number, mode, method and sample time (None for the continuous law)."""

    example: int
    mode: Mode
    method: str
    h: float | None


@dataclass(frozen=True)
class Outcome:
    """The measures of one case, or why it failed."""

    case: Case
    metrics: TrackingMetrics | None
    chattering: Chattering | None
    failure: str = ""


def run_case(case: Case) -> Outcome:
    """Simulate one case on the monolithic reference and measure it."""
    ex = EXAMPLES[case.example]
    discretization = SEMI_IMPLICIT if case.method == "semi-implicit" else EXPLICIT
    params = ex.controller.with_changes(mode=case.mode, discretization=discretization,
                                        sample_time=case.h or 1e-3)
    try:
        run = simulate(ex, params, sample_time=case.h, grid=case.h or 1e-3)
    except SolverError as error:
        return Outcome(case, None, None, error.reason.strip()[:60])
    d = run.data
    return Outcome(case, tracking_metrics(d["time"], d["y"], d["yd"], d["v"], d["uf"]),
                   chattering(d["time"], d["v"]))


def cases(examples: Sequence[int] = (1, 2), modes: Sequence[Mode] = (FIXED_TIME, FINITE_TIME),
          sample_times: Sequence[float] = SAMPLE_TIMES) -> list[Case]:
    """Every case of the study: per example and mode, the continuous law once and both sampled
    methods at every sample time."""
    out = []
    for e in examples:
        for m in modes:
            out.append(Case(e, m, "continuous", None))
            out.extend(Case(e, m, method, h) for h in sample_times for method in METHODS[:2])
    return out


def _row(o: Outcome) -> str:
    h = "-" if o.case.h is None else f"{o.case.h * 1e3:g}"
    if o.metrics is None or o.chattering is None:
        return f"| {h} | {o.case.method} | failed: {o.failure} |" + " |" * 10
    c, m = o.chattering, o.metrics
    return (f"| {h} | {o.case.method} | {c.tv_per_second:.3g} | {c.peak:.3g} | {c.bursts} | "
            f"{c.burst_time:.2f} | {c.longest_burst:.2f} | {m.rae:.4f} | {m.mse:.3g} | {m.rmse:.4f} | "
            f"{m.mae:.3g} | {m.settling_time:.3f} |")


def tables(outcomes: Sequence[Outcome]) -> str:
    """Markdown: one table per example and mode, and the issue-11 targets at 1 ms (fixed-time)."""
    lines = []
    for e in sorted({o.case.example for o in outcomes}):
        for mode in (FIXED_TIME, FINITE_TIME):
            group = [o for o in outcomes if o.case.example == e and o.case.mode == mode]
            if not group:
                continue
            group.sort(key=lambda o: (o.case.h or 0.0, METHODS.index(o.case.method)))
            lines += ["", f"{EXAMPLES[e].name}, {mode} (v after 1 s; tracking metrics over 0-30 s)", "",
                      "| h (ms) | method | TV of v per s | peak abs(v) | bursts | burst time (s) | "
                      "longest (s) | RAE | MSE | RMSE | MAE | settling (s) |",
                      "|---|---|---|---|---|---|---|---|---|---|---|---|"]
            lines += [_row(o) for o in group]
    lines += ["", *targets(outcomes)]
    return "\n".join(lines)


def targets(outcomes: Sequence[Outcome]) -> list[str]:
    """The issue's done-when checks at h = 1 ms, fixed-time: semi-implicit against the continuous law
    (TV within 2x, peak within 1.2x) and against explicit sampling (MAE within +10 %, settling +20 %)."""
    found = {(o.case.example, o.case.mode, o.case.method, o.case.h): o for o in outcomes}
    lines = ["| example | TV / continuous (<= 2) | peak / continuous (<= 1.2) | MAE / explicit (<= 1.1) | "
             "settling / explicit (<= 1.2) | met |", "|---|---|---|---|---|---|"]
    for e in sorted({o.case.example for o in outcomes}):
        ratios = _target_ratios(found.get((e, FIXED_TIME, "semi-implicit", 1e-3)),
                                found.get((e, FIXED_TIME, "continuous", None)),
                                found.get((e, FIXED_TIME, "explicit", 1e-3)))
        if ratios is None:
            continue
        met = all(r <= limit for r, limit in zip(ratios, (2.0, 1.2, 1.1, 1.2), strict=True))
        lines.append(f"| {EXAMPLES[e].name} | " + " | ".join(f"{r:.2f}" for r in ratios)
                     + f" | {'yes' if met else 'NO'} |")
    return lines


def _target_ratios(semi: Outcome | None, cont: Outcome | None,
                   expl: Outcome | None) -> tuple[float, float, float, float] | None:
    """:func:`targets`' four ratios of one example (None where a run or its figures are missing):
    TV and peak of the semi-implicit run over the continuous law's, MAE and settling over explicit."""
    if not (semi and cont and expl and semi.metrics and semi.chattering and cont.chattering
            and expl.metrics):
        return None
    return (semi.chattering.tv_per_second / cont.chattering.tv_per_second,
            semi.chattering.peak / cont.chattering.peak, semi.metrics.mae / expl.metrics.mae,
            semi.metrics.settling_time / expl.metrics.settling_time)


def _worker(case: Case, queue: Any) -> None:
    queue.put(run_case(case))


def run_all(todo: Sequence[Case], jobs: int, timeout: float) -> list[Outcome]:
    """Every case in its own process, ``jobs`` at a time; a run past ``timeout`` seconds is stopped
    and reported as failed (the explicit loop at 5 ms can make the reference solver crawl)."""
    context = multiprocessing.get_context("spawn")
    pending = list(todo)
    running: list[tuple[Case, Any, Any, float]] = []  # case, process, its result queue, start
    outcomes: list[Outcome] = []
    while pending or running:
        while pending and len(running) < max(1, jobs):
            case = pending.pop(0)
            queue = context.Queue()
            process = context.Process(target=_worker, args=(case, queue), daemon=True)
            process.start()
            running.append((case, process, queue, time.monotonic()))
        time.sleep(0.5)
        for item in list(running):
            case, process, queue, started = item
            try:
                outcomes.append(queue.get_nowait())
            except queues.Empty:
                if time.monotonic() - started < timeout:
                    continue
                process.terminate()
                outcomes.append(Outcome(case, None, None, f"not done in {timeout:g} s"))
            process.join()
            running.remove(item)
    return outcomes


def main(argv: Sequence[str] | None = None) -> int:
    """Run the study (in ``--jobs`` processes) and print (or write) the tables."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.discretization",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--example", type=int, action="append", choices=sorted(EXAMPLES))
    parser.add_argument("--sample-time", type=float, action="append", help="s (default: 0.5, 1, 2, 5 ms)")
    parser.add_argument("--timeout", type=float, default=900.0,
                        help="seconds per run before it is stopped and reported (default 900)")
    parser.add_argument("--output", type=Path, help="also write the tables to this Markdown file")
    args = parser.parse_args(argv)
    todo = cases(args.example or (1, 2), sample_times=args.sample_time or SAMPLE_TIMES)
    # The slowest first (finest steps), so the pool ends together.
    todo.sort(key=lambda c: c.h if c.h is not None else 1e-3)
    outcomes = run_all(todo, args.jobs, args.timeout)
    text = tables(outcomes)
    print(text)
    if args.output:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
