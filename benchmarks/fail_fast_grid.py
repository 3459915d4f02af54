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
import statistics
import sys
import time
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from orchestrator import RunOptions, run
from orchestrator.errors import SimulationError

REPO = Path(__file__).resolve().parent.parent
SCENARIO = Path("build", "ssp", "example1_no_fault.ssp")
LAWS = {0: "fixed-time", 1: "finite-time"}


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
    costs: dict[str, dict[tuple[str, str], list[float]]] = {name: defaultdict(list) for name in builds}
    differ = []
    wall = time.perf_counter()
    for mode, law in LAWS.items():
        for x1 in values:
            for x2 in values:
                found = {}
                for name, archive in builds.items():
                    found[name], cpu = outcome(archive, x1, x2, mode)
                    costs[name][law, found[name]].append(cpu)
                if len(set(found.values())) > 1:
                    differ.append((law, x1, x2, found))
        print(f"{law}: done ({time.perf_counter() - wall:.0f} s)", file=sys.stderr)
    groups = sorted({group for per in costs.values() for group in per})
    print(f"| law | outcome | runs | {' | '.join(f'{n}: median / max / total CPU' for n in builds)} |")
    print(f"|---|---|---|{'---|' * len(builds)}")
    for law, found in groups:
        cells = []
        for name in builds:
            cpu = costs[name].get((law, found), [])
            cells.append(f"{1e3 * statistics.median(cpu):.0f} ms / {1e3 * max(cpu):.0f} ms / {sum(cpu):.1f} s"
                         if cpu else "-")
        runs = max(len(costs[name].get((law, found), [])) for name in builds)
        print(f"| {law} | {found} | {runs} | {' | '.join(cells)} |")
    totals = " | ".join(f"{sum(sum(c) for c in costs[name].values()):.1f} s" for name in builds)
    print(f"| all | | {2 * args.num ** 2} | {totals} |")
    print(f"runs whose outcome differs between the builds: {len(differ)}")
    for law, x1, x2, found in differ:
        print(f"  {law} x1(0) = {x1:g}, x2(0) = {x2:g}: {found}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
