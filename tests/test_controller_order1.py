# SPDX-License-Identifier: BSD-2-Clause
"""FixedTimeController1 (plant order n = 1) around the integrator x' = u, against the analytic behaviour
of the closed loop. With yd = 0 and the NN term out of play (kappa_1 = 1e-12, eta_hat_1(0) = 0, so
eta_hat_1 stays below 1e-12) the law is v = -k sig(x)^(2 alpha - 1) - q sig(x)^(2 beta - 1), here with
alpha = 1.5 and beta = 0.75: x' = -k x|x| - q sig(x)^(1/2). Then

* each sampled control is that formula at the state it was given (to round-off);
* the finite-time law (k = 0): sqrt(x(t)) = sqrt(x0) - q t / 2, so x reaches 0 at T = 2 sqrt(x0) / q,
  growing without bound with x0;
* the fixed-time law: x reaches 0 at T(x0) = integral_0^x0 dx / (k x^2 + q sqrt(x)), below the
  x0-independent bound T(inf) = integral_0^inf (the paper's claim, exactly, for this plant).

The loop is sampled at h = 0.1 ms with a zero-order hold; the plant is integrated exactly (x_(k+1) =
x_k + h v_k for a held v), so the zero's time differs from the continuous one by O(h) only: the explicit
Euler drift of the sampled law and the last step's overshoot (measured: 5 h early), asserted within
10 h = 1 ms."""

from __future__ import annotations

import math

import pytest
from fmu_helpers import open_slave
from scipy.integrate import quad

pytestmark = pytest.mark.system

H = 1e-4
K, Q = 3.0, 2.0


def zero_time(fmus: dict, x0: float, mode: int) -> float:
    """The first sample time at which the sampled loop from x0 reaches x <= 0; every control checked."""
    with open_slave(fmus["FixedTimeController1"]) as slave:
        slave.initialize(k1=K, q1=Q, kappa1=1e-12, mode=mode, alpha=1.5, beta=0.75)
        x = x0
        for step in range(200_000):
            slave.set(x1=x, yd=0.0, yd_dot=0.0)
            v = slave.get("v")[0]
            law = -(0.0 if mode else K) * x * abs(x) - Q * math.sqrt(x)
            assert v == pytest.approx(law, rel=1e-9), (step, x)
            slave.step(step * H, H)
            x += H * v
            if x <= 0.0:
                return (step + 1) * H
    raise AssertionError(f"x did not reach 0 from {x0}")


def test_finite_time_law_reaches_zero_at_two_root_x0_over_q(fmus: dict) -> None:
    for x0 in (1.0, 4.0):
        assert zero_time(fmus, x0, mode=1) == pytest.approx(2.0 * math.sqrt(x0) / Q, abs=10 * H)


def test_fixed_time_law_reaches_zero_at_the_integrals_time_below_a_bound_for_every_x0(fmus: dict) -> None:
    def rate(x: float) -> float:
        return 1.0 / (K * x * x + Q * math.sqrt(x))

    bound = quad(rate, 0.0, 1.0)[0] + quad(rate, 1.0, math.inf)[0]
    times = []
    for x0 in (1.0, 10.0):
        expected = quad(rate, 0.0, x0)[0]
        times.append(zero_time(fmus, x0, mode=0))
        assert times[-1] == pytest.approx(expected, abs=10 * H)
    assert times[0] < times[1] < bound < 2.0 * math.sqrt(10.0) / Q  # the finite-time law's T from 10
