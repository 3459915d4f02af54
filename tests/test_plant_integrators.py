# SPDX-License-Identifier: BSD-2-Clause
"""The plants' Dormand-Prince 5(4) integrator (fmu_src.models.plants.dopri_hold_step) on its own:
an analytic solution, its order of convergence, step rejection, tolerance proportionality, the
step size carried across communication steps, and failure. Oracles: closed forms and solve_ivp."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmu_src.models.plants import dopri_hold_step, example1_rhs

UNLIMITED = 1e30  # a tolerance no error reaches: every step of the size asked for is accepted


def oscillator(t: float, s: Sequence[float], uf: float) -> tuple[float, float, float]:
    """x1'' = uf - x1 (undamped, forced), z' = -z + uf: a closed-form solution for held uf."""
    x1, x2, z = s
    return x2, uf - x1, -z + uf


def oscillator_exact(t: float, s0: Sequence[float], uf: float) -> tuple[float, float, float]:
    x1, x2, z = s0
    c, s = math.cos(t), math.sin(t)
    return (
        uf + (x1 - uf) * c + x2 * s,
        -(x1 - uf) * s + x2 * c,
        uf + (z - uf) * math.exp(-t),
    )


def reference(rhs, t0: float, y0: Sequence[float], uf: float, h: float) -> np.ndarray:
    return solve_ivp(lambda t, y: rhs(t, y, uf), (t0, t0 + h), y0, method="DOP853",
                     rtol=1e-13, atol=1e-15).y[:, -1]


def test_analytic_solution_over_many_communication_steps() -> None:
    """Inputs jumping at every 1 ms point for 2 s; within 1e-9 of the closed form at every point."""
    h, state, guess = 1e-3, (0.3, -0.2, 0.1), 0.0
    worst = 0.0
    for k in range(2000):
        uf = math.sin(0.01 * k) + (0.5 if k % 7 == 0 else 0.0)
        exact = oscillator_exact(h, state, uf)
        state, guess, accepted, _ = dopri_hold_step(oscillator, k * h, state, uf, h, 1e-10, 1e-12, guess)
        worst = max(worst, max(abs(a - b) for a, b in zip(state, exact, strict=True)))
        state = exact  # every step from the exact state: the local error of one communication step
    assert worst < 1e-11
    assert accepted >= 1


@pytest.mark.parametrize(("rhs", "span"), [(oscillator, 4.0), (example1_rhs, 0.2)],
                         ids=["oscillator", "example1"])
def test_fifth_order_convergence(rhs, span: float) -> None:
    """N equal accepted steps: the global error falls by 2^5 = 32 per halving of the step."""
    y0, uf = (0.5, 0.5, 0.0), 2.0
    exact = oscillator_exact(span, y0, uf) if rhs is oscillator else reference(rhs, 0.0, y0, uf, span)
    errors = []
    for n in (10, 20, 40):
        h, state = span / n, y0
        for k in range(n):
            state, _, accepted, rejected = dopri_hold_step(rhs, k * h, state, uf, h, UNLIMITED, UNLIMITED, h)
            assert (accepted, rejected) == (1, 0)
        errors.append(np.max(np.abs(np.subtract(state, exact))))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert all(24.0 < r < 48.0 for r in ratios), (errors, ratios)  # 16: 4th order, 64: 6th


def test_rejects_a_step_too_long_for_the_stiff_start() -> None:
    """Example 1 with uf = -773 (the controller's first output) from a 1 ms first guess: rejected,
    shrunk, still on t + h and within 1e-10 of solve_ivp; the next guess is the shrunk size."""
    y0, uf, h = (0.5, 0.5, 0.0), -773.0, 1e-3
    state, next_step, accepted, rejected = dopri_hold_step(example1_rhs, 0.0, y0, uf, h, 1e-10, 1e-12, h)
    assert rejected >= 1 and accepted >= 2
    assert next_step < h
    np.testing.assert_allclose(state, reference(example1_rhs, 0.0, y0, uf, h), rtol=0, atol=1e-10)


def test_error_proportional_to_the_tolerance() -> None:
    """rtol is the accuracy parameter: 1e-9 is at least 100 times closer to solve_ivp than 1e-5."""
    y0, uf, h = (0.5, 0.5, 0.0), -773.0, 1e-3
    exact = reference(example1_rhs, 0.0, y0, uf, h)
    errors = []
    for rtol in (1e-5, 1e-9):
        state = dopri_hold_step(example1_rhs, 0.0, y0, uf, h, rtol, rtol * 1e-2, h).state
        errors.append(np.max(np.abs(np.subtract(state, exact))))
    assert errors[1] < errors[0] / 100 and errors[1] < 1e-9


def test_carried_step_size() -> None:
    """In a quiet stretch the carried size exceeds the communication step: one step per point; a
    size cut to land on t + h does not shrink the guess passed on."""
    state, guess, h = (0.1, 0.0, 0.4), 0.0, 1e-3
    counts = []
    for k in range(50):
        state, guess, accepted, rejected = dopri_hold_step(
            example1_rhs, k * h, state, 0.2 - state[0], h, 1e-10, 1e-12, guess
        )
        counts.append(accepted + rejected)
    assert guess > h
    assert counts[-40:] == [1] * 40


def test_no_step_size_meets_the_tolerance() -> None:
    def broken(t: float, s: Sequence[float], uf: float) -> tuple[float, float, float]:
        return (math.nan if t > 0.0 else 0.0, 0.0, 0.0)

    with pytest.raises(ValueError, match="no step size meets rtol"):
        dopri_hold_step(broken, 0.0, (0.0, 0.0, 0.0), 0.0, 1e-3, 1e-10, 1e-12, 1e-3)
