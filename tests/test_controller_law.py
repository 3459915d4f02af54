# SPDX-License-Identifier: BSD-2-Clause
"""The law of SPEC section 1 against closed forms and a direct transcription written here.

The oracles below are transcribed from the SPEC, not from controller/law.py: n = 1 uses explicit
sums with math.exp, n = 2 builds the NN input vectors X_1 and X_2 as arrays and uses the RBF
basis (whose values are checked by hand in test_controller_rbf.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.law import evaluate, sig
from controller.params import FINITE_TIME, ControllerParameters
from controller.rbf import rbf_basis
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2

MU = (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5)


def power(z: float, p: float) -> float:
    """sig(z)^p written independently: sign(z) * |z|^p."""
    return float(np.sign(z)) * abs(z) ** p


def test_sig_zero_and_odd_symmetry() -> None:
    assert sig(0.0, 0.5) == 0.0
    assert sig(0.0, 2.0) == 0.0
    assert sig(-0.0, 0.5) == 0.0
    for z in (1e-12, 0.3, 1.0, 2.7, 1e6):
        for p in (0.2, 0.5, 1.0, 2.0, 3.5):
            assert sig(-z, p) == -sig(z, p)
            assert sig(z, p) == pytest.approx(z**p, rel=1e-15)
    assert sig(-8.0, 1.0 / 3.0) == pytest.approx(-2.0, rel=1e-15)


def first_order_closed_form(r: float, eta: float, x1: float, yd: float, yd1: float, p: ControllerParameters):
    """(v, r', eta') for n = 1 written out from SPEC section 1 with tau = 2 and the paper's centers."""
    z = x1 - yd
    ptp = 0.0
    for mu in MU:
        distance2 = (x1 - mu) ** 2 + (yd - mu) ** 2 + (yd1 - mu) ** 2 + (r - mu) ** 2
        ptp += math.exp(-distance2 / 4.0) ** 2
    k = p.k_effective[0]
    v = (
        -k * power(z, 2 * p.alpha - 1)
        - p.q[0] * power(z, 2 * p.beta - 1)
        - eta * z * ptp / (2 * p.a[0] ** 2)
    )
    r_dot = -p.a_bar * r + p.gamma_gain * x1**4 + p.d_r
    eta_dot = p.kappa[0] * z**2 * ptp / (2 * p.a[0] ** 2) - (p.rho[0] + p.rho_bar[0]) * eta
    return v, r_dot, eta_dot


FIRST_ORDER = ControllerParameters(
    k=(3.0,), q=(2.0,), a=(1.5,), kappa=(2.0,), rho=(1.0,), rho_bar=(0.5,), alpha=1.7, beta=0.6
)


@pytest.mark.parametrize("mode", ["fixed-time", "finite-time"])
@pytest.mark.parametrize(
    ("r", "eta", "x1", "yd", "yd1"),
    [
        (0.0, 0.0, 0.5, 0.0, 0.5),
        (0.8, 1.3, -0.7, 0.2, -0.4),
        (2.0, 0.1, 1.1, 1.1, 0.0),  # z = 0
        (0.3, 5.0, -2.0, 0.9, 1.0),
    ],
)
def test_first_order_against_closed_form(
    mode: str, r: float, eta: float, x1: float, yd: float, yd1: float
) -> None:
    params = FIRST_ORDER.with_changes(mode=mode)
    v, r_dot, eta_dot = first_order_closed_form(r, eta, x1, yd, yd1, params)
    terms = evaluate([r, eta], [x1], [yd, yd1], params)
    assert terms.z == pytest.approx((x1 - yd,), rel=1e-15)
    assert terms.v == pytest.approx(v, rel=1e-13, abs=1e-15)
    assert terms.zeta == (terms.v,)
    assert terms.derivative == pytest.approx((r_dot, eta_dot), rel=1e-13, abs=1e-15)


def second_order_transcription(state, x, yd, p: ControllerParameters):
    """(v, z, zeta, ptp, derivative) for n = 2, building X_1 and X_2 explicitly (SPEC section 1)."""
    r, eta1, eta2 = state
    x1, x2 = x
    yd0, yd1, yd2 = yd
    k = (0.0, 0.0) if p.mode == FINITE_TIME else p.k
    a1, a2 = p.alpha * 2 - 1, p.beta * 2 - 1

    X1 = np.array([x1, yd0, yd1, r])
    P1 = np.array(rbf_basis(X1, p.centers, p.width))
    ptp1 = float(P1 @ P1)
    z1 = x1 - yd0
    nn = 1.0 if p.nn_term else 0.0  # issue 37's switch: the NN term of each zeta_i in or out
    zeta1 = -k[0] * power(z1, a1) - p.q[0] * power(z1, a2) - nn * eta1 * z1 * ptp1 / (2 * p.a[0] ** 2)

    X2 = np.array([x1, x2, eta1, yd0, yd1, yd2, r])
    P2 = np.array(rbf_basis(X2, p.centers, p.width))
    ptp2 = float(P2 @ P2)
    z2 = x2 - zeta1
    zeta2 = -k[1] * power(z2, a1) - p.q[1] * power(z2, a2) - nn * eta2 * z2 * ptp2 / (2 * p.a[1] ** 2)

    r_dot = -p.a_bar * r + p.gamma_gain * x1**4 + p.d_r
    eta1_dot = p.kappa[0] * z1**2 * ptp1 / (2 * p.a[0] ** 2) - (p.rho[0] + p.rho_bar[0]) * eta1
    eta2_dot = p.kappa[1] * z2**2 * ptp2 / (2 * p.a[1] ** 2) - (p.rho[1] + p.rho_bar[1]) * eta2
    return zeta2, (z1, z2), (zeta1, zeta2), (ptp1, ptp2), (r_dot, eta1_dot, eta2_dot)


def random_points(seed: int, count: int = 25):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        state = [rng.uniform(0.0, 2.0), rng.uniform(0.0, 3.0), rng.uniform(0.0, 3.0)]
        yield state, list(rng.uniform(-1.5, 1.5, 2)), list(rng.uniform(-1.0, 1.0, 3))


@pytest.mark.parametrize("example", [EXAMPLE1, EXAMPLE2], ids=["example1", "example2"])
@pytest.mark.parametrize("mode", ["fixed-time", "finite-time"])
@pytest.mark.parametrize("nn_term", [True, False], ids=["nn-on", "nn-off"])
def test_second_order_against_transcription(example, mode: str, nn_term: bool) -> None:
    """Issue 37: with the NN term off, zeta_i loses eta_hat_i z_i P_i^T P_i / (2 a_i^2) and nothing
    else (the estimates still adapt, eq. 38, on the z_2 of the law without it)."""
    params = example.controller.with_changes(mode=mode, alpha=1.3, beta=0.8, nn_term=nn_term)
    points = [([0.0, 0.0, 0.0], [0.5, 0.5], [0.0, 0.5, 0.0])] + list(random_points(7))
    for state, x, yd in points:
        v, z, zeta, ptp, derivative = second_order_transcription(state, x, yd, params)
        terms = evaluate(state, x, yd, params)
        assert terms.v == pytest.approx(v, rel=1e-12)
        assert terms.z == pytest.approx(z, rel=1e-12)
        assert terms.zeta == pytest.approx(zeta, rel=1e-12)
        assert terms.ptp == pytest.approx(ptp, rel=1e-12)
        assert terms.derivative == pytest.approx(derivative, rel=1e-12)


def test_example1_initial_control_is_large() -> None:
    # SPEC section 6: |v(0)| near 770 for Example 1, 15 000 for Example 2 (independent implementation).
    v1 = evaluate([0.0, 0.0, 0.0], [0.5, 0.5], [0.0, 0.5, 0.0], EXAMPLE1.controller).v
    v2 = evaluate([0.0, 0.0, 0.0], [0.6, 0.1], [0.0, 0.5, 0.0], EXAMPLE2.controller).v
    assert abs(v1) == pytest.approx(770, rel=0.01)
    assert abs(v2) == pytest.approx(15000, rel=0.03)


def test_finite_time_is_the_limit_of_vanishing_k() -> None:
    """Finite-time mode (k unused) is the fixed-time law as k -> 0: the gap shrinks linearly in k."""
    finite = EXAMPLE1.controller.with_changes(mode=FINITE_TIME)
    for state, x, yd in random_points(11, 10):
        reference = np.array(evaluate(state, x, yd, finite).derivative + (evaluate(state, x, yd, finite).v,))
        gaps = []
        for scale in (1e-4, 1e-6):
            fixed = EXAMPLE1.controller.with_changes(k=(10 * scale, 10 * scale))
            terms = evaluate(state, x, yd, fixed)
            gaps.append(np.max(np.abs(np.array(terms.derivative + (terms.v,)) - reference)))
        assert gaps[1] <= 1.1e-2 * gaps[0] + 1e-12


def test_finite_time_first_step_differs_by_exactly_the_k_term() -> None:
    # For step 1, z_1 = x_1 - yd does not depend on k, so zeta_1 differs by -k_1 sig(z_1)^(2 alpha - 1) only.
    fixed = EXAMPLE2.controller
    finite = EXAMPLE2.controller.with_changes(mode=FINITE_TIME)
    for state, x, yd in random_points(3, 10):
        z1 = x[0] - yd[0]
        difference = evaluate(state, x, yd, fixed).zeta[0] - evaluate(state, x, yd, finite).zeta[0]
        assert difference == pytest.approx(-25.0 * power(z1, 2 * fixed.alpha - 1), rel=1e-12, abs=1e-14)


def test_nn_term_switch_accepts_zero_and_one_only() -> None:
    assert EXAMPLE1.controller.nn_term is True
    assert EXAMPLE1.controller.with_changes(nn_term=0).nn_term is False
    with pytest.raises(ValueError, match=r"nn_term must be 1 \(on\) or 0 \(off\) \(got 2\)"):
        EXAMPLE1.controller.with_changes(nn_term=2)
