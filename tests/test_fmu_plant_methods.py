# SPDX-License-Identifier: BSD-2-Clause
"""The plant FMUs' integrator parameters: ``method`` (0 Dormand-Prince 5(4) with ``rtol``/``atol``,
the default; 1 RK4 with sub-steps of at most ``max_step``, also chosen when only ``max_step`` is
set), checked against solve_ivp (DOP853, rtol 1e-10) on the stiff first 20 ms of Example 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmu_helpers import example1, open_slave, solve_held

pytestmark = pytest.mark.system

H = 1e-3
STEPS = 20


def error_to_solve_ivp(path, **parameters: float) -> float:
    """Max |x_FMU - x_solve_ivp| over 20 steps of the controller-sized input 770 exp(-t/2 ms)."""
    inputs = [770.0 * math.exp(-k * H / 0.002) - 5.0 * k for k in range(STEPS)]
    states = []
    with open_slave(path) as slave:
        slave.initialize(**parameters)
        for k, uf in enumerate(inputs):
            slave.set(uf=uf)
            slave.step(k * H, H)
            states.append(slave.get("x1", "x2", "z"))
    oracle = solve_held(example1, 0.0, (0.5, 0.5, 0.0), inputs, H)
    return float(np.max(np.abs(np.array(states) - oracle)))


def test_default_is_error_controlled_and_rtol_is_its_accuracy(fmus: dict) -> None:
    default = error_to_solve_ivp(fmus["Example1Plant"])
    loose = error_to_solve_ivp(fmus["Example1Plant"], rtol=1e-5, atol=1e-7)
    assert default < 1e-9
    assert loose > 100 * default


def test_method_1_is_rk4_with_max_step(fmus: dict) -> None:
    """One RK4 step per 1 ms is visibly off; the explicit method 0 ignores max_step."""
    rk4 = error_to_solve_ivp(fmus["Example1Plant"], method=1, max_step=1e-3)
    dopri = error_to_solve_ivp(fmus["Example1Plant"], method=0, max_step=1e-3)
    assert rk4 > 1e-4
    assert dopri < 1e-9


def test_max_step_alone_selects_rk4(fmus: dict) -> None:
    """Importers that set max_step (before method existed) keep the fixed-step integrator."""
    assert error_to_solve_ivp(fmus["Example1Plant"], max_step=1e-3) == error_to_solve_ivp(
        fmus["Example1Plant"], method=1, max_step=1e-3
    )
