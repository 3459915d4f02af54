# SPDX-License-Identifier: BSD-2-Clause
"""The paper's settling-time bound, eq. (83), computed from the gains (SPEC section 10).

Theorem 1 ends with ``V' <= -c V^alpha - c_hat V^beta + x_0`` (eq. 81) and Lemma 2 (eq. 14, with
p = alpha, s = beta, r_1 = c, r_2 = c_hat) gives ``T <= T_m = 1/(c Phi (alpha - 1)) +
1/(c_hat Phi (1 - beta))`` for any 0 < Phi < 1. The constants, as eq. (70)-(77) define them for
a plant of order n (where the paper leaves one open, the choice is in :class:`Constant`'s ``source``):

* ``c_j`` (eq. 71, the z_j^(2 alpha) coefficients): ``c_j = k_j b_m + m_bar k_n b_m`` as eq. (71)
  writes it for j <= n - 1, and ``c_n = b_m m_bar k_n`` from eq. (70) (eq. 71 defines no c_n);
* ``c_tilde_j`` (the z_j^(2 beta) coefficients, eq. 71's c_bar_j): ``q_j b_m + b_m m_bar q_n`` and
  ``b_m m_bar q_n``;
* ``o_j = rho_j`` and ``rho_tilde_j = rho_bar_j``: the eta_tilde_j^2 / (2 kappa_j) coefficients of
  eq. (74), which the sigma-modification terms ``-(rho_j + rho_bar_j) eta_hat_j`` of the adaptive
  law (eq. 69) produce through eq. (72)-(73) (theta_j = rho_j, theta_bar_j = rho_bar_j);
* ``c = min(2^alpha c_j, o_j, a_bar)``, ``c_hat = min(2^beta c_tilde_j, rho_tilde_j, a_bar)``
  (eq. 77; a_bar is the dynamic signal's decay rate, eq. 20);
* ``b_m``: the lower bound of the plant's input gains (Assumption 3), ``m_bar``: the lower bound of
  K(t) m(t), the actuator's effectiveness times the dead-zone's slope (Assumption 1, eq. 7).

T_m bounds the time V needs to reach the residual set (82), not the time |y - yd| needs to enter a
band: the two are compared as the paper's claim (Remark 4) invites, not as equal quantities.
The bound decreases as Phi grows to 1 (the residual set grows without bound then): ``infimum``
is its limit Phi -> 1, the smallest value the paper's argument can give.
"""

from __future__ import annotations

from dataclasses import dataclass

from controller.params import FINITE_TIME, ControllerParameters

__all__ = ["Constant", "FixedTimeBound", "fixed_time_bound"]


@dataclass(frozen=True)
class Constant:
    """One constant of the bound: its value and where it comes from."""

    name: str
    value: float
    source: str


@dataclass(frozen=True)
class FixedTimeBound:
    """T_m of eq. (83) at ``phi``, its infimum over Phi in (0, 1), and the constants behind it."""

    phi: float
    t_m: float
    infimum: float
    constants: tuple[Constant, ...]

    def constant(self, name: str) -> float:
        """The value of the constant called ``name``."""
        return next(c.value for c in self.constants if c.name == name)


def fixed_time_bound(
    params: ControllerParameters, b_m: float, m_bar: float, phi: float = 0.5
) -> FixedTimeBound:
    """T_m of eq. (83) for a loop of order n = ``params.n`` with these gains, input-gain bound ``b_m``
    and actuator bound ``m_bar`` (module docstring). Raises ValueError outside the theorem's
    assumptions (the finite-time law, b_m or m_bar not positive, Phi outside (0, 1))."""
    if params.mode == FINITE_TIME:
        raise ValueError("the finite-time law (k = 0) has no fixed-time bound: c = 0 in eq. (83)")
    if not (b_m > 0.0 and m_bar > 0.0):
        raise ValueError(f"b_m and m_bar must be positive (got {b_m!r}, {m_bar!r})")
    if not 0.0 < phi < 1.0:
        raise ValueError(f"Phi must satisfy 0 < Phi < 1 (got {phi!r})")
    k, q, n = params.k, params.q, params.n
    alpha, beta = params.alpha, params.beta
    cs = [k[j] * b_m + m_bar * k[n - 1] * b_m for j in range(n - 1)] + [b_m * m_bar * k[n - 1]]
    cts = [q[j] * b_m + b_m * m_bar * q[n - 1] for j in range(n - 1)] + [b_m * m_bar * q[n - 1]]
    c = min(*(2.0**alpha * cj for cj in cs), *params.rho, params.a_bar)
    c_hat = min(*(2.0**beta * ct for ct in cts), *params.rho_bar, params.a_bar)
    steps = [
        *(Constant(f"c_{j}", cs[j - 1], f"eq. (71): k_{j} b_m + m_bar k_{n} b_m") for j in range(1, n)),
        Constant(f"c_{n}", cs[-1], f"eq. (70): b_m m_bar k_{n} (eq. 71 defines no c_n)"),
        *(Constant(f"c_tilde_{j}", cts[j - 1], f"eq. (71): q_{j} b_m + b_m m_bar q_{n}")
          for j in range(1, n)),
        Constant(f"c_tilde_{n}", cts[-1], f"eq. (70): b_m m_bar q_{n}"),
    ]
    constants = (
        Constant("b_m", b_m, "lower bound of the plant's input gains (Assumption 3)"),
        Constant("m_bar", m_bar, "lower bound of K(t) m(t), effectiveness x dead-zone slope (eq. 7)"),
        *steps,
        Constant("o_j", min(params.rho), "eq. (72), (74): theta_j = rho_j of (69), the smaller"),
        Constant("rho_tilde_j", min(params.rho_bar), "eq. (73), (74): theta_bar_j = rho_bar_j, the smaller"),
        Constant("a_bar", params.a_bar, "decay rate of the dynamic signal r (eq. 20)"),
        Constant("c", c, "eq. (77): min(2^alpha c_j, o_j, a_bar)"),
        Constant("c_hat", c_hat, "eq. (77): min(2^beta c_tilde_j, rho_tilde_j, a_bar)"),
    )
    infimum = 1.0 / (c * (alpha - 1.0)) + 1.0 / (c_hat * (1.0 - beta))
    return FixedTimeBound(phi=phi, t_m=infimum / phi, infimum=infimum, constants=constants)
