# SPDX-License-Identifier: BSD-2-Clause
"""Headline findings of the shipped campaigns (orchestrator.experiments.campaigns) on hand-made
tables whose answers are counted by hand: which initial states diverge, never settle or settle, the
largest square of states that all settle, and the worst fault."""

from __future__ import annotations

import math

from orchestrator.experiments.campaigns import claim_headlines, fault_headlines


def claim_row(x1: float, x2: float, mode: int, status: str = "ok", settling: float | None = 0.1) -> dict:
    return {
        "plant.x1_0": x1,
        "plant.x2_0": x2,
        "controller.mode": float(mode),
        "status": status,
        "settling_time": settling if status == "ok" else None,
    }


def test_claim_headlines_count_each_outcome() -> None:
    rows = []
    for x1 in (-2.0, -1.0, 0.0, 1.0, 2.0):
        for x2 in (-2.0, 0.0, 2.0):
            rows.append(claim_row(x1, x2, 0, settling=0.05))
            far = max(abs(x1), abs(x2)) == 2
            # finite-time: diverges from x1(0) = 2, never settles from the other far states
            if x1 == 2:
                rows.append(claim_row(x1, x2, 1, status="failed"))
            else:
                rows.append(claim_row(x1, x2, 1, settling=math.inf if far else 0.4))
    fixed, finite, both = claim_headlines(rows)
    assert fixed == (
        "fixed-time: 15 initial states, 0 diverge (run fails), 0 never enter the band, 15 settle "
        "within 0.050 .. 0.050 s; every state with max(|x1(0)|, |x2(0)|) <= 2 settles."
    )
    # far states: x1 = +-2 (6) and x2 = +-2 with |x1| < 2 (6); 3 of them diverge (x1 = 2)
    assert finite == (
        "finite-time: 15 initial states, 3 diverge (run fails), 9 never enter the band, 3 settle "
        "within 0.400 .. 0.400 s; every state with max(|x1(0)|, |x2(0)|) <= 1 settles."
    )
    assert both == "States where only the fixed-time law settles: 12; only the finite-time law: 0."


def test_fault_headlines_name_the_worst_fault() -> None:
    def row(run: int, mode: int, mae: float, worst: float, k_inf: float, status: str = "ok") -> dict:
        return {
            "run": run,
            "scenario": "example1",
            "controller.mode": float(mode),
            "status": status,
            "mae_after_fault": mae,
            "max_error_after_fault": worst,
            "actuator.K_inf": k_inf,
            "actuator.L_bias": 0.5,
            "actuator.t_fault": 3.0,
            "actuator.b_r": 0.25,
            "actuator.b_l": 0.75,
        }

    rows = [row(0, 0, 1e-3, 2e-3, 0.1), row(1, 0, 3e-3, 1e-3, 0.9), row(2, 1, 0.0, 0.0, 0.5, status="failed")]
    fixed, finite = fault_headlines(rows)[::-1]
    assert fixed == (
        "example1, fixed-time: 2 of 2 runs ok; MAE after the fault <= 0.003, |y - yd| after the "
        "fault <= 0.002 (run 0: K_inf = 0.10, L_bias = 0.50, t_fault = 3.00, b_r = 0.25, b_l = 0.75)."
    )
    assert finite == "example1, finite-time: 0 of 1 runs ok."


def test_claim_headlines_with_the_mode_fixed_by_the_design() -> None:
    rows = [
        {k: v for k, v in claim_row(x1, 0.0, 1, settling=0.2).items() if k != "controller.mode"}
        for x1 in (-1.0, 0.0, 1.0)
    ]
    assert claim_headlines(rows, {"controller.mode": 1}) == [
        "finite-time: 3 initial states, 0 diverge (run fails), 0 never enter the band, 3 settle within "
        "0.200 .. 0.200 s; every state with max(|x1(0)|, |x2(0)|) <= 1 settles."
    ]
