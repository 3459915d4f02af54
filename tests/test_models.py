# SPDX-License-Identifier: BSD-2-Clause
"""Shared plant/actuator/reference math against independent transcriptions of SPEC sections 2-3."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmu_src.models.actuator import ActuatorParameters, actuator_output, dead_zone
from fmu_src.models.plants import PendulumParameters, example1_rhs, hold_step, pendulum_rhs
from fmu_src.models.reference import ReferenceParameters, reference_signal

RNG = np.random.default_rng(7)
STATES = RNG.uniform(-2.0, 2.0, size=(20, 3))
INPUTS = RNG.uniform(-800.0, 800.0, size=20)


def spec_example1(x1, x2, z, uf):
    """SPEC section 3, Example 1, written out with numpy."""
    dz = -z - x1**2 + 0.5
    dx1 = (2 + np.sin(x1)) * x2 + 0.1 * np.sin(x1 * x2) + z * np.sin(x1**2)
    dx2 = (2 + np.cos(x1 * x2)) * uf + 0.5 * np.sin(x1**2 * x2**2) + x1**2 * z
    return dx1, dx2, dz


def spec_pendulum(t, x1, x2, z, uf, M=0.25, L=4.0, B=0.25, g=10.0):
    """SPEC section 3, Example 2, written out with numpy."""
    dz = -2 * z + 0.25 * x1**2
    dx1 = x2 + z * x1 + 0.2 * np.sin(t)
    dx2 = uf / (M * L) - (g / L + B / M) * np.sin(x1 * x2) + z * x2 * np.sin(x1) + 0.3 * np.cos(t)
    return dx1, dx2, dz


@pytest.mark.parametrize("i", range(len(STATES)))
def test_plant_right_hand_sides_match_spec(i):
    x1, x2, z = STATES[i]
    uf, t = INPUTS[i], 0.37 * i
    assert example1_rhs(t, (x1, x2, z), uf) == pytest.approx(
        spec_example1(x1, x2, z, uf), rel=1e-13, abs=1e-12
    )
    assert pendulum_rhs(t, (x1, x2, z), uf, PendulumParameters()) == pytest.approx(
        spec_pendulum(t, x1, x2, z, uf), rel=1e-13, abs=1e-12
    )


def test_pendulum_parameters_enter_where_spec_puts_them():
    p = PendulumParameters(M=0.5, L=2.0, B=0.1, g=9.81)
    got = pendulum_rhs(1.3, (0.4, -0.2, 0.1), 3.0, p)
    assert got == pytest.approx(
        spec_pendulum(1.3, 0.4, -0.2, 0.1, 3.0, M=0.5, L=2.0, B=0.1, g=9.81), rel=1e-13
    )


@pytest.mark.parametrize(
    ("v", "expected"),
    [
        (0.5, 0.0),  # breakpoint b_r: m_r (v - b_r) = 0
        (0.5 + 1e-9, 1e-9),
        (0.4999, 0.0),
        (2.0, 1.5),
        (-0.6, 0.0),  # breakpoint -b_l: m_l (v + b_l) = 0
        (-0.6 - 1e-9, -1.2e-9),
        (-0.5999, 0.0),
        (-2.6, -2.4),
        (0.0, 0.0),
    ],
)
def test_dead_zone_branches_and_breakpoints(v, expected):
    assert dead_zone(v, ActuatorParameters()) == pytest.approx(expected, abs=1e-15)


def test_actuator_is_transparent_before_the_fault_and_faulty_from_t_fault_on():
    p = ActuatorParameters(t_fault=10.0)
    assert actuator_output(9.999, 0.3, 1.0, 2.0, p) == (0.3, 0.0)
    for t in (10.0, 17.5):
        uf, u = actuator_output(t, 2.0, 1.0, 2.0, p)
        K = 0.4 + 0.6 * math.exp(-0.2 * t)
        assert u == pytest.approx(1.5, rel=1e-15)
        assert uf == pytest.approx(K * 1.5 + 2.0 * math.cos(1.0) ** 2, rel=1e-14)
    uf, u = actuator_output(12.0, 0.1, 0.3, -1.0, p)  # inside the dead band: only L(t) remains
    assert (uf, u) == (pytest.approx(-(math.cos(0.3) ** 2), rel=1e-14), 0.0)


def test_reference_derivatives_agree_with_central_differences():
    p = ReferenceParameters(amplitude=0.8, omega=1.7, phase=0.3, offset=0.1)
    h = 1e-5
    for t in np.linspace(0.0, 10.0, 11):
        yd, yd1, yd2 = reference_signal(t, p)
        assert yd == pytest.approx(0.8 * math.sin(1.7 * t + 0.3) + 0.1, rel=1e-14)
        minus, plus = reference_signal(t - h, p), reference_signal(t + h, p)
        assert yd1 == pytest.approx((plus[0] - minus[0]) / (2 * h), abs=1e-8)
        assert yd2 == pytest.approx((plus[1] - minus[1]) / (2 * h), abs=1e-8)


def test_hold_step_is_fourth_order_and_agrees_with_solve_ivp():
    """One 1 ms step with the huge initial input of Example 1; error ratio ~16 when halving.

    With uf = -773 held, x2 moves by about 2.3 in 1 ms, so one RK4 step of 1 ms is off by ~3e-4:
    the plants need sub-steps of tens of microseconds during the initial transient.
    """
    state, uf, h = (0.5, 0.5, 0.0), -773.0, 1e-3
    exact = solve_ivp(
        lambda t, y: example1_rhs(t, y, uf), (0.0, h), state, method="DOP853", rtol=1e-13, atol=1e-15
    ).y[:, -1]
    errors = [
        np.max(np.abs(np.subtract(hold_step(example1_rhs, 0.0, state, uf, h, h / m), exact)))
        for m in (4, 8, 16)
    ]
    assert errors[2] < 1e-8
    assert 12.0 < errors[0] / errors[1] < 20.0
    assert 12.0 < errors[1] / errors[2] < 20.0
