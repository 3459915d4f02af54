# SPDX-License-Identifier: BSD-2-Clause
"""The backstepping law of SPEC section 1: virtual controls, actual control, adaptive laws.

Pure functions of (state, inputs, parameters). The state is ``[r, eta_hat_1, ..., eta_hat_n]``;
the inputs are the plant states ``x = [x_1..x_n]`` and the reference with its derivatives
``yd = [yd, yd', ..., yd^(n)]``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from .fmath import power
from .params import SEMI_IMPLICIT, ControllerParameters
from .rbf import rbf_energy

__all__ = [
    "ControlTerms", "InputError", "check_inputs", "derivative", "evaluate", "semi_implicit_feedback", "sig",
]


def sig(z: float, p: float) -> float:
    """sig(z)^p = sign(z) |z|^p."""
    return math.copysign(power(abs(z), p), z) if z != 0.0 else 0.0


def semi_implicit_feedback(z: float, phi: float, bh: float) -> float:
    """The semi-implicit value of one step's feedback -sign(z) phi: -sign(z) min(phi, |z| / bh).

    ``phi`` is the law's feedback magnitude at |z| (k|z|^(2 alpha-1) + q|z|^(2 beta-1) + eta_hat w|z|),
    ``bh = b_max * sample_time``. It is the control u of z_next = z + bh u with u in -phi Sgn(z_next)
    (magnitude at the sample, sign set-valued at the next one: Acary and Brogliato's implicit sign).
    """
    return -math.copysign(min(phi, abs(z) / bh), z) if z != 0.0 else 0.0


class InputError(ValueError):
    """Plant states or reference derivatives that do not fit the controller's plant order n."""


def check_inputs(x: Sequence[float], yd: Sequence[float], n: int) -> None:
    """Raise :class:`InputError` (one line) unless ``x`` has n entries and ``yd`` has n + 1."""
    if len(x) != n:
        raise InputError(f"x must have n = {n} entries x1..x{n} (got {len(x)}): the controller is for a "
                         f"plant of order {n}")
    if len(yd) != n + 1:
        raise InputError(f"yd must have n + 1 = {n + 1} entries, yd and its derivatives up to order {n} "
                         f"(got {len(yd)})")


@dataclass(frozen=True)
class ControlTerms:
    """Every intermediate term of one evaluation of the law, for the FMU and for tests."""

    v: float
    z: tuple[float, ...]
    zeta: tuple[float, ...]
    ptp: tuple[float, ...]
    derivative: tuple[float, ...]


def evaluate(
    state: Sequence[float],
    x: Sequence[float],
    yd: Sequence[float],
    p: ControllerParameters,
) -> ControlTerms:
    """Evaluate the law and the state derivative at one instant.

    ``derivative`` is ``[r', eta_hat_1', ..., eta_hat_n']`` (eq. 20, 38, 55, 69). With
    ``p.discretization`` semi-implicit each zeta_i is :func:`semi_implicit_feedback` of its terms.
    ``x`` must have n entries and ``yd`` n + 1 (:class:`InputError` otherwise).
    """
    check_inputs(x, yd, p.n)
    z, zeta, ptp, rates = _law(state, x, yd, p, True)
    return ControlTerms(v=zeta[-1], z=tuple(z), zeta=tuple(zeta), ptp=tuple(ptp), derivative=tuple(rates))


def derivative(
    state: Sequence[float],
    x: Sequence[float],
    yd: Sequence[float],
    p: ControllerParameters,
) -> tuple[float, ...]:
    """``[r', eta_hat_1', ..., eta_hat_n']`` alone: :func:`evaluate` without the actual control
    v = zeta_n, which no state derivative needs (the stages of a step skip it: the same values,
    and no error from evaluating v)."""
    check_inputs(x, yd, p.n)
    return tuple(_law(state, x, yd, p, False)[3])


def _law(
    state: Sequence[float], x: Sequence[float], yd: Sequence[float], p: ControllerParameters, with_v: bool
) -> tuple[list[float], list[float], list[float], list[float]]:
    """(z, zeta, P^T P, state derivative), each per step; ``with_v`` False leaves zeta_n out. The
    order of every operation is a contract: ``controller/_law.c`` repeats it for the same bits."""
    n = p.n
    r = state[0]
    eta = state[1:]
    p_alpha = 2.0 * p.alpha - 1.0
    p_beta = 2.0 * p.beta - 1.0
    k = p.k_effective
    semi = p.discretization == SEMI_IMPLICIT
    nn = p.nn_term
    bh = p.b_max * p.sample_time
    # X_1 = [x1, yd, yd', r]; X_{i+1} adds x_{i+1}, eta_hat_i and yd^(i+1).
    s1 = x[0] + yd[0] + yd[1] + r
    s2 = x[0] * x[0] + yd[0] * yd[0] + yd[1] * yd[1] + r * r
    dim = 4
    z_list: list[float] = []
    zeta_list: list[float] = []
    ptp_list: list[float] = []
    rates = [-p.a_bar * r + p.gamma_gain * power(abs(x[0]), p.gamma_power) + p.d_r]  # eq. 20
    previous = yd[0]
    for i in range(n):
        if i > 0:
            s1 += x[i] + eta[i - 1] + yd[i + 1]
            s2 += x[i] * x[i] + eta[i - 1] * eta[i - 1] + yd[i + 1] * yd[i + 1]
            dim += 3
        z = x[i] - previous  # eq. 26
        ptp = rbf_energy(s1, s2, dim, p.centers, p.width)
        weight = ptp / (2.0 * p.a[i] * p.a[i])
        if i == n - 1 and not with_v:
            zeta = 0.0
        elif semi:
            a = abs(z)
            phi = k[i] * power(a, p_alpha) + p.q[i] * power(a, p_beta) + eta[i] * a * weight if nn else (
                k[i] * power(a, p_alpha) + p.q[i] * power(a, p_beta))
            zeta = semi_implicit_feedback(z, phi, bh)
        elif z != 0.0:  # eq. 37/54/68; zeta = 0 at z = 0 (sig(0) = 0), as a positive zero
            zeta = -k[i] * sig(z, p_alpha) - p.q[i] * sig(z, p_beta) - eta[i] * z * weight if nn else (
                -k[i] * sig(z, p_alpha) - p.q[i] * sig(z, p_beta))
        else:
            zeta = 0.0
        rates.append(p.kappa[i] * z * z * weight - (p.rho[i] + p.rho_bar[i]) * eta[i])  # eq. 38
        z_list.append(z)
        zeta_list.append(zeta)
        ptp_list.append(ptp)
        previous = zeta
    if not with_v:
        zeta_list.pop()
    return z_list, zeta_list, ptp_list, rates
