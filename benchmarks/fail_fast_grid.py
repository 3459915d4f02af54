# SPDX-License-Identifier: BSD-2-Clause
"""What the runs of a campaign over initial states cost, by outcome: the grid of
``ssp/campaigns/fail_fast_grid.toml`` (Example 1 without fault, x1(0), x2(0) in [-10, 10]^2, both
laws, 2 s), one run after the other in this process.

    python benchmarks/fail_fast_grid.py [--num 11] [--before CHECKOUT]

Each run is ``orchestrator.run`` on ``build/ssp/example1_no_fault.ssp`` (run ``make build``
first) with the grid's initial state and law, no output file; its cost is the CPU time of this
process around the call (``process_time``: FMU instantiation and the sampled loop, the plant's
integrator included; not the interpreter's start-up, which every run pays alike). With
``--before CHECKOUT`` (another checkout of this repository with its own ``make build``), the
same run on that checkout's archive follows each run on this one, by the same engine, so the two
builds of the FMUs are compared under the same load. The runs are grouped by law and outcome
(settled, or diverged: the plant discarded a step on one of its bounds); a run whose outcome
differs between the builds is listed.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import sys
import time
from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from orchestrator import RunOptions, run
from orchestrator.errors import SimulationError

REPO = Path(__file__).resolve().parent.parent
SCENARIO = Path("build", "ssp", "example1_no_fault.ssp")
LAWS = {0: "fixed-time", 1: "finite-time"}


Costs = dict[str, dict[tuple[str, str], list[float]]]  # build -> (law, outcome) -> CPU s of each run


def outcome(archive: Path, x1: float, x2: float, mode: int) -> tuple[str, float]:
    """Run one grid point; its outcome ("settled", "diverged": the plant discarded a step, or
    another failure) and CPU seconds."""
    overrides = {"plant.x1_0": x1, "plant.x2_0": x2, "controller.mode": mode}
    options = RunOptions(stop_time=2.0, overrides=overrides)
    start = time.process_time()
    try:
        run(archive, options)
        found = "settled"
    except SimulationError as error:
        found = "diverged" if error.status == "fmi2Discard" else f"failed: {error}"
    return found, time.process_time() - start


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--num", type=int, default=11, help="grid points per axis (default 11)")
    parser.add_argument("--before", type=Path, metavar="CHECKOUT",
                        help="a checkout with its own 'make build'")
    args = parser.parse_args(argv)
    builds = {"now": REPO / SCENARIO}
    if args.before is not None:
        builds = {"before": args.before / SCENARIO, **builds}
    for archive in builds.values():
        if not archive.is_file():
            parser.error(f"{archive}: not built (run 'make build' in its checkout)")
    values = [float(v) for v in np.linspace(-10.0, 10.0, args.num)]
    costs, differ = _run_grid(builds, values)
    _print_costs(costs, builds, args.num)
    print(f"runs whose outcome differs between the builds: {len(differ)}")
    for law, x1, x2, found in differ:
        print(f"  {law} x1(0) = {x1:g}, x2(0) = {x2:g}: {found}")
    return 0


def _run_grid(builds: Mapping[str, Path], values: Sequence[float]) -> tuple[Costs, list[tuple]]:
    """Every grid point with each law in each build: the CPU seconds by build, law and outcome, and
    the points whose outcome differs between the builds."""
    costs: Costs = {name: defaultdict(list) for name in builds}
    differ = []
    wall = time.perf_counter()
    for mode, law in LAWS.items():
        for x1, x2 in itertools.product(values, values):
            found = {}
            for name, archive in builds.items():
                found[name], cpu = outcome(archive, x1, x2, mode)
                costs[name][law, found[name]].append(cpu)
            if len(set(found.values())) > 1:
                differ.append((law, x1, x2, found))
        print(f"{law}: done ({time.perf_counter() - wall:.0f} s)", file=sys.stderr)
    return costs, differ


def _print_costs(costs: Costs, builds: Mapping[str, Path], num: int) -> None:
    """The Markdown table: per law and outcome, the runs and each build's median, largest and total CPU."""
    groups = sorted({group for per in costs.values() for group in per})
    print(f"| law | outcome | runs | {' | '.join(f'{n}: median / max / total CPU' for n in builds)} |")
    print(f"|---|---|---|{'---|' * len(builds)}")
    for law, found in groups:
        cells = [_cpu_cell(costs[name].get((law, found), [])) for name in builds]
        runs = max(len(costs[name].get((law, found), [])) for name in builds)
        print(f"| {law} | {found} | {runs} | {' | '.join(cells)} |")
    totals = " | ".join(f"{sum(sum(c) for c in costs[name].values()):.1f} s" for name in builds)
    print(f"| all | | {2 * num ** 2} | {totals} |")


def _cpu_cell(cpu: Sequence[float]) -> str:
    """median / max / total of the runs' CPU times ("-" for none)."""
    if not cpu:
        return "-"
    return f"{1e3 * statistics.median(cpu):.0f} ms / {1e3 * max(cpu):.0f} ms / {sum(cpu):.1f} s"


if __name__ == "__main__":
    sys.exit(main())
