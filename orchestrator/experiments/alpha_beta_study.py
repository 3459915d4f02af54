# SPDX-License-Identifier: BSD-2-Clause
"""Choose alpha and beta by experiment (SPEC section 6): run both examples over a grid.

``python -m orchestrator.experiments.alpha_beta_study`` prints, for every (alpha, beta), the RMSE, MAE,
settling time and peak |v| of both examples, run as the product runs them: the monolithic
reference with the controller and actuator sampled every 1 ms (zero-order hold; the continuous
law with small 2 beta - 1 chatters and stalls an adaptive solver). Finite-time mode does not use
alpha, so it is run once per beta.
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Sequence

from controller.params import FINITE_TIME, FIXED_TIME

from .closed_loop import EXAMPLES, simulate
from .metrics import tracking_metrics

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Print one Markdown row per (example, mode, alpha, beta)."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.alpha_beta_study",
                                     description=__doc__)
    parser.add_argument("--alpha", type=float, nargs="+", default=[1.25, 1.5, 2.0])
    parser.add_argument("--beta", type=float, nargs="+", default=[0.6, 0.75, 0.9])
    parser.add_argument("--stop-time", type=float, default=30.0)
    parser.add_argument("--example", type=int, nargs="+", choices=sorted(EXAMPLES), default=sorted(EXAMPLES))
    parser.add_argument("--finite-time", action=argparse.BooleanOptionalAction, default=True,
                        help="also run finite-time mode once per beta")
    args = parser.parse_args(argv)
    print("| example | mode | alpha | beta | RMSE | MAE | settling time (s) | peak abs(v) |")
    print("|---|---|---|---|---|---|---|---|")
    for number in args.example:
        ex = EXAMPLES[number]
        cases = [(FIXED_TIME, a, b) for a, b in itertools.product(args.alpha, args.beta)]
        if args.finite_time:
            cases += [(FINITE_TIME, ex.controller.alpha, b) for b in args.beta]
        for mode, alpha, beta in cases:
            params = ex.controller.with_changes(mode=mode, alpha=alpha, beta=beta)
            d = simulate(ex, params, stop_time=args.stop_time, sample_time=1e-3).data
            m = tracking_metrics(d["time"], d["y"], d["yd"], d["v"], d["uf"])
            alpha_text = f"{alpha:g}" if mode == FIXED_TIME else "-"
            print(
                f"| {number} | {mode} | {alpha_text} | {beta:g} | {m.rmse:.4f} | {m.mae:.4f} "
                f"| {m.settling_time:.3f} | {m.peak_v:.0f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
