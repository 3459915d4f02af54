# SPDX-License-Identifier: BSD-2-Clause
"""The RK4 stepping interface against closed forms and solve_ivp, with the inputs held.

Measured on the reference machine (max over the states of |RK4 - solve_ivp| / |solve_ivp|, solve_ivp
at rtol 1e-12, atol 1e-14):

* one 1 ms step from the stiff start: 6.3e-13 (Example 1), 6.0e-13 (Example 2);
* 1000 held 1 ms steps: 1.2e-13 (Example 1), 1.8e-13 (Example 2) with DOP853; 1.2e-13 and
  1.2e-13 with Radau.

RK4's own error at h = 1 ms is far smaller: the coarse-step convergence test below gives a global
error of about C h^4 with C ~ 1.2 (Example 1) and 5 (Example 2) per second of held inputs, i.e. a
local error C h^5 ~ 5e-15 and a global error ~ 5e-12 absolute on states of size 10-100 (relative
~ 1e-13) after 1 s. So the measured differences are the reference's own tolerance (rtol 1e-12), and
the bound asserted, 5e-12 relative, is the sum of both with a margin of several times.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from controller.law import evaluate
from controller.params import ControllerParameters
from controller.stepping import AdaptiveController
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2

H = 1e-3
# (parameters, x held, yd held) at the stiff start: Example 1 (yd = 0.5 sin t) and the pendulum
# (yd = sin(0.5 t)), both at t = 0.
STIFF_STARTS = {
    "example1": (EXAMPLE1.controller, [0.5, 0.5], [0.0, 0.5, 0.0]),
    "pendulum": (EXAMPLE2.controller, [0.6, 0.1], [0.0, 0.5, 0.0]),
}


def held_reference(params: ControllerParameters, x, yd, t_end: float, method: str, rtol=1e-12, atol=1e-14):
    """solve_ivp on r' and eta_hat' with x and yd held, from the parameters' initial values."""
    sol = solve_ivp(
        lambda t, s: evaluate(s, x, yd, params).derivative,
        (0.0, t_end),
        [params.r0, *params.eta0],
        method=method,
        rtol=rtol,
        atol=atol,
    )
    assert sol.success, sol.message
    return sol.y[:, -1]


@pytest.mark.parametrize("name", sorted(STIFF_STARTS))
@pytest.mark.parametrize("method", ["DOP853", "Radau"])
@pytest.mark.parametrize("steps", [1, 1000])
def test_stepping_matches_solve_ivp(name: str, method: str, steps: int) -> None:
    params, x, yd = STIFF_STARTS[name]
    controller = AdaptiveController(params)
    for _ in range(steps):
        controller.advance(x, yd, H)
    reference = held_reference(params, x, yd, steps * H, method)
    relative = np.abs(np.array(controller.state) - reference) / np.abs(reference)
    assert np.max(relative) < 5e-12, f"relative error {relative} ({name}, {method}, {steps} steps)"


@pytest.mark.parametrize("name", sorted(STIFF_STARTS))
def test_substeps_converge_with_fourth_order(name: str) -> None:
    """Halving the sub-step divides the error by 2^4 = 16 (two 0.5 s steps, sub-steps 50, 25, 12.5 ms)."""
    params, x, yd = STIFF_STARTS[name]
    reference = held_reference(params, x, yd, 1.0, "DOP853", rtol=1e-13, atol=1e-15)
    errors = []
    for substeps in (10, 20, 40):
        controller = AdaptiveController(params, substeps=substeps)
        controller.advance(x, yd, 0.5)
        controller.advance(x, yd, 0.5)
        errors.append(np.max(np.abs(np.array(controller.state) - reference)))
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    # Measured: 17.0, 16.5 (Example 1); 16.6, 16.3 (pendulum).
    assert all(14.0 < ratio < 19.0 for ratio in ratios), ratios


def test_substeps_equal_repeated_short_steps() -> None:
    params, x, yd = STIFF_STARTS["example1"]
    split = AdaptiveController(params, substeps=4)
    split.advance(x, yd, 0.02)
    short = AdaptiveController(params)
    for _ in range(4):
        short.advance(x, yd, 0.005)
    assert split.state == pytest.approx(short.state, rel=1e-14)


def rk4_factor(z: float) -> float:
    """RK4's stability function R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, z = lambda h."""
    return 1.0 + z + z * z / 2.0 + z**3 / 6.0 + z**4 / 24.0


class TestAdaptiveLawExactSolution:
    """n = 1 with x1 and yd held and r at its equilibrium: z and P^T P are constant, so
    eta' = kappa z^2 P^T P / (2 a^2) - (rho + rho_bar) eta is linear with constant coefficients and
    eta(t) = eta_inf + (eta0 - eta_inf) exp(-(rho + rho_bar) t)."""

    X1, YD, YD1 = 0.5, 0.2, -0.3
    # r* = (gamma_gain |x1|^4 + d_r) / a_bar = 2.5 * 0.0625 + 0.625 = 0.78125, exact in binary.
    R_STAR = 0.78125
    ETA0 = 4.0

    def setup_method(self) -> None:
        self.params = ControllerParameters(
            k=(3.0,), q=(2.0,), a=(1.5,), kappa=(2.0,), rho=(2.0,), rho_bar=(1.0,),
            r0=self.R_STAR, eta0=(self.ETA0,),
        )
        self.lam = 3.0  # rho + rho_bar
        z = self.X1 - self.YD
        X1 = (self.X1, self.YD, self.YD1, self.R_STAR)
        ptp = sum(
            math.exp(-sum((component - mu) ** 2 for component in X1) / 4.0) ** 2
            for mu in (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5)
        )
        self.eta_inf = 2.0 * z * z * ptp / (2.0 * 1.5**2 * self.lam)

    def run(self, h: float, steps: int) -> tuple[AdaptiveController, list[float]]:
        controller = AdaptiveController(self.params)
        trajectory = []
        for _ in range(steps):
            controller.advance([self.X1], [self.YD, self.YD1], h)
            trajectory.append(controller.eta_hat[0])
        return controller, trajectory

    def test_matches_continuous_solution(self) -> None:
        steps = 3000
        controller, trajectory = self.run(H, steps)
        assert controller.r == self.R_STAR  # r' = 0 exactly at the equilibrium
        gap = self.ETA0 - self.eta_inf
        exact = [self.eta_inf + gap * math.exp(-self.lam * H * j) for j in range(1, steps + 1)]
        # |R(-lam h) - exp(-lam h)| <= (lam h)^5 / 120 per step, so after N steps the RK4 error is at
        # most N (lam h)^5 / 120 |eta0 - eta_inf| (2.4e-11 here), plus rounding (~N eps |eta|).
        # Measured: 1.0e-12.
        bound = steps * (self.lam * H) ** 5 / 120.0 * abs(gap) + steps * 1e-16 * self.ETA0
        assert np.max(np.abs(np.array(trajectory) - exact)) <= bound

    def test_coarse_steps_follow_rk4_stability_function(self) -> None:
        # With a coarse step the RK4 error is visible (~5e-4) and equals the discrete solution exactly.
        h, steps = 0.2, 20
        _, trajectory = self.run(h, steps)
        factor = rk4_factor(-self.lam * h)
        discrete = [self.eta_inf + (self.ETA0 - self.eta_inf) * factor**j for j in range(1, steps + 1)]
        continuous = [self.eta_inf + (self.ETA0 - self.eta_inf) * math.exp(-self.lam * h * j)
                      for j in range(1, steps + 1)]
        assert trajectory == pytest.approx(discrete, rel=1e-13)
        assert np.max(np.abs(np.array(trajectory) - continuous)) > 1e-4


def test_reset_restores_initial_state() -> None:
    params = EXAMPLE1.controller.with_changes(r0=0.25, eta0=(0.5, 1.5))
    controller = AdaptiveController(params)
    assert controller.state == [0.25, 0.5, 1.5]
    controller.output([0.5, 0.5], [0.0, 0.5, 0.0])
    for _ in range(10):
        controller.advance([0.5, 0.5], [0.0, 0.5, 0.0], H)
    assert controller.r != 0.25 and controller.last is not None
    controller.reset()
    assert controller.state == [0.25, 0.5, 1.5]
    assert (controller.r, controller.eta_hat) == (0.25, (0.5, 1.5))
    assert controller.last is None


def test_output_does_not_change_state_and_records_last() -> None:
    params, x, yd = STIFF_STARTS["pendulum"]
    controller = AdaptiveController(params)
    terms = controller.output(x, yd)
    assert controller.state == [0.0, 0.0, 0.0]
    assert controller.last is terms
    assert terms.v == evaluate([0.0, 0.0, 0.0], x, yd, params).v


def test_advance_after_output_equals_advance_alone() -> None:
    params, x, yd = STIFF_STARTS["example1"]
    with_output, alone = AdaptiveController(params), AdaptiveController(params)
    for _ in range(5):
        with_output.output(x, yd)
        with_output.advance(x, yd, H)
        alone.advance(x, yd, H)
    assert with_output.state == alone.state


def test_advance_does_not_reuse_output_for_other_inputs_or_state() -> None:
    params, x, yd = STIFF_STARTS["example1"]
    other_x = [0.4, 0.5]
    stale = AdaptiveController(params)
    stale.output(x, yd)
    stale.advance(other_x, yd, H)  # inputs changed after output()
    stale.output(other_x, yd)
    stale.state = [0.1, 0.2, 0.3]  # state replaced after output()
    stale.advance(other_x, yd, H)
    fresh = AdaptiveController(params)
    fresh.state = [0.1, 0.2, 0.3]
    fresh.advance(other_x, yd, H)
    assert stale.state == fresh.state


def test_substeps_must_be_positive() -> None:
    with pytest.raises(ValueError, match="substeps"):
        AdaptiveController(EXAMPLE1.controller, substeps=0)
