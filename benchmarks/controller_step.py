# SPDX-License-Identifier: BSD-2-Clause
"""Cost of one communication step of the controller: ``output(x, yd)`` + ``advance(x, yd, h=1e-3)``.

``python benchmarks/controller_step.py`` prints, for n = 2 and Example 1 gains, the median over
batches of the time per call in microseconds, for the whole step and for its parts, on the
general-n library path (:class:`controller.stepping.AdaptiveController`) and on the flat interface
the controller FMUs call (:func:`controller.native.law_for`: the compiled law where it is built,
else the Python reference; which one ran is printed), in the same run. ``benchmarks/fmu_step.py``
measures the FMUs themselves.
Figures only: timings are never asserted.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable, Sequence

from controller.law import evaluate
from controller.native import law_for
from controller.rbf import rbf_energy
from controller.stepping import AdaptiveController
from fmu_src.models.examples import EXAMPLE1

__all__ = ["main", "median_microseconds"]

H = 1e-3


def median_microseconds(call: Callable[[], object], batches: int, per_batch: int) -> float:
    """Median over ``batches`` of the mean time of one ``call()`` in a batch of ``per_batch``, in us."""
    call()  # warm up
    samples = []
    for _ in range(batches):
        start = time.perf_counter_ns()
        for _ in range(per_batch):
            call()
        samples.append((time.perf_counter_ns() - start) / per_batch / 1000.0)
    return statistics.median(samples)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the median cost of a step and its breakdown."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=int, default=20)
    parser.add_argument("--per-batch", type=int, default=2000)
    args = parser.parse_args(argv)
    params = EXAMPLE1.controller
    x, yd = [0.5, 0.5], [0.0, 0.5, 0.0]
    state = [0.0, 0.0, 0.0]

    def step(controller: AdaptiveController) -> None:
        controller.output(x, yd)
        controller.advance(x, yd, H)

    stepping = AdaptiveController(params)
    advancing = AdaptiveController(params)
    outputting = AdaptiveController(params)
    fast = law_for(params)
    inputs, start = (*x, *yd), tuple(state)
    stage = fast.evaluate(start, inputs)

    def fast_step() -> None:  # as the FMU: the output's law is the first RK4 stage
        fast.advance(H, fast.evaluate(start, inputs), start, inputs)

    figures = {
        "output + advance (one communication step)": lambda: step(stepping),
        "advance alone (RK4: 4 law evaluations)": lambda: advancing.advance(x, yd, H),
        "output alone (1 law evaluation)": lambda: outputting.output(x, yd),
        "evaluate (the law, n = 2)": lambda: evaluate(state, x, yd, params),
        "rbf_energy (7 neurons)": lambda: rbf_energy(1.0, 2.0, 7, params.centers, params.width),
        "FMU's form: evaluate + advance (one step)": fast_step,
        "FMU's form: evaluate (1 law evaluation)": lambda: fast.evaluate(start, inputs),
        "FMU's form: advance from a stage (3 rates)": lambda: fast.advance(H, stage, start, inputs),
    }
    print(f"median of {args.batches} batches of {args.per_batch} calls, n = 2, Example 1 gains, h = {H} s; "
          f"the FMU's form is {type(fast).__name__}")
    results = {}
    for name, call in figures.items():
        results[name] = median_microseconds(call, args.batches, args.per_batch)
        print(f"  {name:<44s} {results[name]:8.2f} us")
    total = results["output + advance (one communication step)"]
    law = results["evaluate (the law, n = 2)"]
    rbf = results["rbf_energy (7 neurons)"]
    # A step evaluates the law 4 times: once in output(), 3 times in advance() (its first RK4 stage
    # reuses output's evaluation); each evaluation calls rbf_energy n = 2 times.
    print(f"breakdown: 4 law evaluations = {4 * law:.2f} us ({4 * law / total:.0%} of the step), "
          f"of which rbf_energy 8 x {rbf:.2f} = {8 * rbf:.2f} us ({8 * rbf / total:.0%})")
    fast_total = results["FMU's form: evaluate + advance (one step)"]
    print(f"one step: general path {total:.2f} us, the FMU's form {fast_total:.2f} us "
          f"({total / fast_total:.1f}x faster)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
