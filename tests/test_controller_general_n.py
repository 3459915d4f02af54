# SPDX-License-Identifier: BSD-2-Clause
"""Issue 45, item 4: the controller guide writes the law for general n, and the implementation is it.

Oracle: the lines of ``docs/controller-fmu.md``'s "The law for general n", transcribed here with numpy
(the NN input vectors X_i built as arrays, the RBF energy summed neuron by neuron, plain ``**`` powers),
compared with ``controller.law.evaluate`` for n = 1 to 4, both laws, both discretizations, the NN term
on and off; the page must hold every transcribed line word for word."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from controller.law import evaluate
from controller.params import FINITE_TIME, FIXED_TIME, ControllerParameters

GUIDE = Path(__file__).resolve().parent.parent / "docs" / "controller-fmu.md"
LINES = (
    "r'          = -a_bar r + gamma_gain |x_1|^gamma_power + d_r",
    "z_1         = x_1 - yd",
    "z_i         = x_i - zeta_(i-1)                                    for i = 2..n",
    "X_1         = [x_1, yd, yd^(1), r]",
    "X_i         = [x_1..x_i, eta_hat_1..eta_hat_(i-1), yd, yd^(1)..yd^(i), r]    (3 i + 1 entries)",
    "S_i         = sum over j = 1..l of exp(-2 ||X_i - mu_j (1, ..., 1)||^2 / tau^2)    (= P_i^T P_i)",
    "phi_i       = k_i |z_i|^(2 alpha - 1) + q_i |z_i|^(2 beta - 1) + eta_hat_i |z_i| S_i / (2 a_i^2)",
    "zeta_i      = -sign(z_i) phi_i                                    discretization = 0 (explicit)",
    "zeta_i      = -sign(z_i) min(phi_i, |z_i| / (b_max h))            discretization = 1 (semi-implicit)",
    "v           = zeta_n",
    "eta_hat_i'  = kappa_i z_i^2 S_i / (2 a_i^2) - (rho_i + rho_bar_i) eta_hat_i",
)


def test_the_guide_writes_the_transcribed_lines() -> None:
    page = GUIDE.read_text(encoding="utf-8")
    missing = [line for line in LINES if line not in page]
    assert not missing


def transcription(state: list[float], x: list[float], yd: list[float], p: ControllerParameters
                  ) -> tuple[list[float], list[float], list[float]]:
    """(z, zeta, [r', eta_hat_1'..eta_hat_n']) by the guide's lines."""
    n = p.n
    r, eta = state[0], state[1:]
    k = [0.0] * n if p.mode == FINITE_TIME else list(p.k)
    rates = [-p.a_bar * r + p.gamma_gain * abs(x[0]) ** p.gamma_power + p.d_r]
    z, zeta = [], []
    for i in range(n):
        z.append(x[i] - (yd[0] if i == 0 else zeta[i - 1]))
        big_x = np.array([*x[: i + 1], *eta[:i], *yd[: i + 2], r])
        assert big_x.size == 3 * (i + 1) + 1
        s = sum(np.exp(-2.0 * np.sum((big_x - mu) ** 2) / p.width**2) for mu in p.centers)
        a = abs(z[i])
        phi = k[i] * a ** (2 * p.alpha - 1) + p.q[i] * a ** (2 * p.beta - 1)
        if p.nn_term:
            phi += eta[i] * a * s / (2 * p.a[i] ** 2)
        if p.discretization == 1:
            phi = min(phi, a / (p.b_max * p.sample_time))
        zeta.append(-np.sign(z[i]) * phi)
        rates.append(p.kappa[i] * z[i] ** 2 * s / (2 * p.a[i] ** 2) - (p.rho[i] + p.rho_bar[i]) * eta[i])
    return z, zeta, rates


@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("mode", [FIXED_TIME, FINITE_TIME])
@pytest.mark.parametrize("discretization", [0, 1])
@pytest.mark.parametrize("nn_term", [True, False])
def test_the_implementation_is_the_guides_law(n: int, mode: int, discretization: int, nn_term: bool) -> None:
    rng = np.random.default_rng(1000 * n + 100 * mode + 10 * discretization + nn_term)
    gains = {name: tuple(rng.uniform(0.5, 20.0, n)) for name in ("k", "q", "a", "kappa", "rho", "rho_bar")}
    for _ in range(25):
        p = ControllerParameters(**gains, alpha=float(rng.uniform(1.1, 2.0)),
                                 beta=float(rng.uniform(0.55, 0.95)), mode=mode,
                                 discretization=discretization, sample_time=1e-3,
                                 b_max=float(rng.uniform(1.0, 100.0)), nn_term=nn_term)
        state = [float(rng.uniform(0.0, 2.0)), *rng.uniform(0.0, 2.0, n)]
        x = list(rng.normal(0.0, 1.0, n))
        yd = list(rng.normal(0.0, 0.5, n + 1))
        terms = evaluate(state, x, yd, p)
        z, zeta, rates = transcription(state, x, yd, p)
        np.testing.assert_allclose(terms.z, z, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(terms.zeta, zeta, rtol=1e-11, atol=1e-12)
        assert terms.v == terms.zeta[-1]
        np.testing.assert_allclose(terms.derivative, rates, rtol=1e-11, atol=1e-12)
