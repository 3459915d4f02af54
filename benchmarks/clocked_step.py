# SPDX-License-Identifier: BSD-2-Clause
"""What ticking FMI 3.0 clocks costs: the ``_clocked`` scenarios (the controller's clocked twin,
activated in Event Mode) stepped by the Python master and by the compiled executor, against the
unclocked scenario of the same step in the compiled executor.

    python benchmarks/clocked_step.py [--scenarios example1 pendulum_smooth] [--stop-time 3]
        [--repeat 3] [--build build]

Per scenario, at its sample time and at a master step that does not divide it (0.4 ms against
1 ms, 0.3 ms against 0.5 ms: the step is cut at every tick, so there are more FMU steps than
rows): CPU per communication step (``time.process_time``, results in memory, best of
``--repeat``), and the ratios Python / compiled and clocked / unclocked (compiled). The archives are
``<build>/ssp/<name>.ssp`` and ``<name>_clocked.ssp`` (``orchestrate build``).
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import orchestrator
from orchestrator import RunOptions

OFF_GRID = {"example1": 0.0004, "pendulum_smooth": 0.0003}  # s: a step that does not divide the sample time


def cpu_per_step(archive: Path, stop: float, step: float | None, executor: str,
                 repeat: int) -> tuple[float, int]:
    """Best CPU seconds per communication step of ``repeat`` runs, and the number of steps."""
    best, steps = float("inf"), 0
    for _ in range(repeat):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = time.process_time()
            rows = orchestrator.run(archive, RunOptions(stop_time=stop, step=step, executor=executor)).rows
            best = min(best, time.process_time() - start)
        steps = len(rows) - 1
    return best / steps, steps


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=list(OFF_GRID))
    parser.add_argument("--stop-time", type=float, default=3.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--build", type=Path, default=Path("build"))
    args = parser.parse_args(argv)
    print("| scenario | step | steps | unclocked, compiled | clocked, Python | clocked, compiled | "
          "Python / compiled | clocked / unclocked |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        for step in (None, OFF_GRID.get(name)):
            if step is None and OFF_GRID.get(name) is None:
                continue
            plain, steps = cpu_per_step(args.build / "ssp" / f"{name}.ssp", args.stop_time, step, "compiled",
                                        args.repeat)
            clocked = args.build / "ssp" / f"{name}_clocked.ssp"
            python, _ = cpu_per_step(clocked, args.stop_time, step, "python", args.repeat)
            compiled, _ = cpu_per_step(clocked, args.stop_time, step, "compiled", args.repeat)
            shown = "sample time" if step is None else f"{step * 1e3:g} ms"
            print(f"| `{name}` | {shown} | {steps} | {plain * 1e6:.1f} us | {python * 1e6:.1f} us | "
                  f"{compiled * 1e6:.1f} us | {python / compiled:.2f} | {compiled / plain:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
