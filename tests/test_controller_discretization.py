# SPDX-License-Identifier: BSD-2-Clause
"""The semi-implicit discretization of the law (issue 11) against closed forms.

Oracles: the paper's explicit law (``controller.law`` with ``discretization`` explicit, eq. 37/68),
the implicit relation that defines the semi-implicit control (z_next = z + b h u with u in
-phi(|z|) Sgn(z_next), solved by hand), and the closed form of its largest deviation from the law.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.law import evaluate, semi_implicit_feedback
from controller.params import EXPLICIT, FINITE_TIME, SEMI_IMPLICIT, ControllerParameters, ParameterError
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2

STATE = ([0.0, 0.0, 0.0], [0.5, 0.5], [0.0, 0.5, 0.0])  # Example 1 at t = 0: z1 = 0.5


def one_step(q: float, beta: float, b_max: float, h: float) -> ControllerParameters:
    """n = 1, finite-time (k = 0), eta_hat = 0: the law is v = -q sig(z)^(2 beta - 1) exactly."""
    return ControllerParameters(k=(0.0,), q=(q,), a=(1.0,), kappa=(1.0,), rho=(1.0,), rho_bar=(1.0,),
                                beta=beta, mode=FINITE_TIME, discretization=SEMI_IMPLICIT, sample_time=h,
                                b_max=b_max)


@pytest.mark.parametrize("example", [EXAMPLE1, EXAMPLE2], ids=["example1", "pendulum"])
def test_equals_the_continuous_law_once_the_boundary_layer_is_inside_the_state(example) -> None:
    """At a fixed state, v is the explicit law's exactly (to round-off) for every h below the
    closed-form threshold h* = |z| / (b_max phi(|z|)) of both steps, and differs above it."""
    explicit = example.controller
    terms = evaluate(*STATE, explicit)
    p_alpha, p_beta = 2 * explicit.alpha - 1, 2 * explicit.beta - 1
    thresholds = []
    for i, z in enumerate(terms.z):
        a = abs(z)
        weight = terms.ptp[i] / (2 * explicit.a[i] ** 2)
        phi = explicit.k[i] * a**p_alpha + explicit.q[i] * a**p_beta + STATE[0][1 + i] * weight * a
        thresholds.append(a / (explicit.b_max * phi))
    h_star = min(thresholds)
    for h in (h_star / 2, h_star / 10, h_star / 1000):
        semi = evaluate(*STATE, explicit.with_changes(discretization=SEMI_IMPLICIT, sample_time=h)).v
        assert semi == pytest.approx(terms.v, rel=1e-13)
    above = evaluate(*STATE, explicit.with_changes(discretization=SEMI_IMPLICIT, sample_time=2 * h_star)).v
    assert abs(above) < abs(terms.v) * 0.99


@pytest.mark.parametrize("beta", [0.6, 0.75, 0.9])
def test_worst_case_deviation_converges_at_the_closed_form_order(beta: float) -> None:
    """sup_z |v_semi - v| over all states is (1/p - 1) z*/(b h) at z* = (q p b h)^(1/(1-p)), p = 2 beta - 1:
    order p / (1 - p) in h (1 for the paper's beta = 0.75). Measured on a fine z grid at h / 2^j."""
    q, b = 8.0, 3.0
    p = 2 * beta - 1
    errors = []
    hs = [1e-3 / 2**j for j in range(5)]
    for h in hs:
        params = one_step(q, beta, b, h)
        z_star = (q * p * b * h) ** (1 / (1 - p))
        closed = (1 / p - 1) * z_star / (b * h)
        grid = [z_star * (0.5 + j / 2000) for j in range(2001)]  # around the maximiser
        worst = max(abs(evaluate([0.0, 0.0], [z], [0.0, 0.0], params).v - (-q * z**p)) for z in grid)
        assert worst == pytest.approx(closed, rel=1e-5)
        errors.append(worst)
    orders = [math.log2(errors[j] / errors[j + 1]) for j in range(len(errors) - 1)]
    assert orders == pytest.approx([p / (1 - p)] * len(orders), rel=1e-6)


@settings(max_examples=300, deadline=None)
@given(z=st.floats(-10.0, 10.0).filter(lambda z: abs(z) > 1e-12), gain=st.floats(1e-3, 1.0),
       beta=st.floats(0.55, 0.95), q=st.floats(0.1, 30.0), k=st.floats(0.0, 30.0),
       h=st.floats(1e-4, 1e-2), b_max=st.floats(0.2, 5.0))
def test_is_the_control_of_the_implicit_relation(z, gain, beta, q, k, h, b_max) -> None:
    """u = semi_implicit_feedback solves z_next = z + b_max h u, u in -phi(|z|) Sgn(z_next) (Acary and
    Brogliato's implicit sign with the magnitude at the sample): either |u| = phi and z_next keeps the
    sign of z, or |u| < phi and z_next = 0. So a plant whose input gain is any g <= b_max (``gain`` =
    g / b_max) never has z driven through zero in one sample: no discretization chattering."""
    a = abs(z)
    phi = k * a**1.5 + q * a ** (2 * beta - 1)
    u = semi_implicit_feedback(z, phi, b_max * h)
    z_next = z + b_max * h * u
    if math.isclose(abs(u), phi, rel_tol=1e-12):
        assert z_next * z >= -1e-12 * a
    else:
        assert abs(u) < phi
        assert abs(z_next) <= 1e-12 * a
    plant_next = z + gain * b_max * h * u  # a plant with input gain g = gain * b_max
    assert plant_next * z >= -1e-12 * a and abs(plant_next) <= a


def test_parameter_checks() -> None:
    """discretization is 0 or 1 (or its label); sample_time and b_max are checked when used, and the
    explicit discretization is the default (the paper's law)."""
    assert EXAMPLE1.controller.discretization == EXPLICIT
    semi = EXAMPLE1.controller.with_changes(discretization="semi-implicit")
    assert semi.discretization == SEMI_IMPLICIT and str(semi.discretization) == "semi-implicit"
    with pytest.raises(ParameterError, match=r"discretization must be 0 \(explicit\) or 1 \(semi-implicit\)"):
        EXAMPLE1.controller.with_changes(discretization=2)
    with pytest.raises(ParameterError, match=r"sample_time must satisfy sample_time > 0 \(got 0.0\)"):
        semi.with_changes(sample_time=0.0)
    with pytest.raises(ParameterError, match=r"b_max must satisfy b_max > 0 \(got nan\)"):
        semi.with_changes(b_max=float("nan"))
    EXAMPLE1.controller.with_changes(sample_time=0.0, b_max=-1.0)  # unused by the explicit law
    with pytest.raises(ParameterError, match="beta must satisfy"):  # every other check still applies
        semi.with_changes(beta=1.0)
