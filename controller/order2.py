# SPDX-License-Identifier: BSD-2-Clause
"""The controller of :mod:`controller.stepping` specialised to a plant of order n = 2, in scalars.

The general-n path (:func:`controller.law.evaluate` building :class:`~controller.law.ControlTerms`,
lists for the RK4 stages, :func:`controller.rbf.rbf_energy` per step) costs about 4 us per law
evaluation, and a communication step evaluates the law four times. Here the same arithmetic is
written out for n = 2 with local floats: every constant of the law is unpacked once, the two RBF
energies are summed without temporaries, and no object is allocated per evaluation but the result
tuple. What depends on the inputs alone (z1 and its powers, the gamma term of r', the inputs'
share of the RBF sums) is computed once per step and shared by the output and the three further
RK4 stages, which also skip v (the derivatives do not need it): each partial result is the value
the whole law computes, so this changes no bit. The operations are those of the general path in
the same order, so the two give the same bits (``tests/test_controller_order2.py``).

The n = 2 controller FMU ran this path until issue 35 compiled the law (:mod:`controller.native`);
it stays the library's pure-Python path for n = 2 (about 3 times faster than the general one) and
the record of the FMU's former arithmetic (``tests/test_controller_n2_identity.py`` replays every
shipped scenario through it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from .fmath import exp, power
from .law import ControlTerms
from .params import SEMI_IMPLICIT, ControllerParameters

__all__ = ["Held", "LawValues", "Order2Controller", "Stage"]

# (v, z1, z2, zeta1, ptp1, ptp2, r', eta_hat_1', eta_hat_2')
LawValues = tuple[float, float, float, float, float, float, float, float, float]
# what the law takes from the held inputs alone (see _kernels_for)
Held = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
# (zeta1, z2, weight2, ptp1, ptp2, r', eta_hat_1', eta_hat_2')
Rates = tuple[float, float, float, float, float, float, float, float]
# the law at the current state and the inputs' share of it (Order2Controller.stage)
Stage = tuple[LawValues, Held]


def _kernels_for(params: ControllerParameters) -> tuple[Callable[..., Held], Callable[..., Rates],
                                                         Callable[..., LawValues]]:
    """``held``, ``rates`` and ``law_at`` for ``params``: every constant bound in the closures (no
    attribute lookups per evaluation), the general path's order of operations throughout.

    ``held(x1, x2, yd, yd', yd'')`` computes once what the law takes from the inputs alone (they are
    held over a step, so the output and the RK4 stages share it: z1, its powers, the gamma term, the
    inputs' sums); ``rates(r, eta1, eta2, held)`` is the part of the law that depends on the states,
    up to the state derivative (v is not needed there); ``law_at(r, eta1, eta2, held)`` is the
    whole law: rates and v."""
    k1, k2 = params.k_effective
    q1, q2 = params.q
    two_a2_1, two_a2_2 = (2.0 * a * a for a in params.a)
    kappa1, kappa2 = params.kappa
    leak1, leak2 = (rho + bar for rho, bar in zip(params.rho, params.rho_bar, strict=True))
    p_alpha = 2.0 * params.alpha - 1.0
    p_beta = 2.0 * params.beta - 1.0
    a_bar, gamma_gain, gamma_power, d_r = params.a_bar, params.gamma_gain, params.gamma_power, params.d_r
    scale = -2.0 / (params.width * params.width)
    # Per neuron (2 mu, dim mu^2) for X_1 (dim 4) and X_2 (dim 7), in rbf_energy's rounding order.
    neurons1 = tuple((2.0 * mu, 4 * mu * mu) for mu in params.centers)
    neurons2 = tuple((2.0 * mu, 7 * mu * mu) for mu in params.centers)
    seven = len(params.centers) == 7  # the FMU's seven neurons: an unrolled sum, no loop
    # For the unrolled sums: 2 mu_j (m), dim mu_j^2 for X_1 (c) and for X_2 (d), as closure cells.
    m1, m2, m3, m4, m5, m6, m7 = (m for m, _ in neurons1) if seven else (0.0,) * 7
    c1, c2, c3, c4, c5, c6, c7 = (c for _, c in neurons1) if seven else (0.0,) * 7
    d1, d2, d3, d4, d5, d6, d7 = (d for _, d in neurons2) if seven else (0.0,) * 7
    copysign = math.copysign
    semi = params.discretization == SEMI_IMPLICIT  # controller.law.semi_implicit_feedback, inlined
    nn = params.nn_term  # False: the NN term left out of zeta1 and v (issue 37's ablation)
    bh = params.b_max * params.sample_time

    def held(x1: float, x2: float, yd: float, yd1: float, yd2: float) -> Held:
        """The inputs' share of the law; each item is the value the law computes at every stage
        (``x1 + yd + yd1`` is the first partial sum of ``x1 + yd + yd1 + r``, and so on)."""
        z1 = x1 - yd
        a = abs(z1)
        if semi:  # phi's first two terms and the boundary layer |z1| / (b h)
            gains1 = k1 * power(a, p_alpha) + q1 * power(a, p_beta)
            layer1 = a / bh
        else:  # zeta1's first two terms; b h is not validated (nor used) by the explicit law
            gains1 = -k1 * copysign(power(a, p_alpha), z1) - q1 * copysign(power(a, p_beta), z1)
            layer1 = 0.0
        return (x1 + yd + yd1, x1 * x1 + yd * yd + yd1 * yd1, x2, x2 * x2, yd2, yd2 * yd2, z1, a, gains1,
                layer1, kappa1 * z1 * z1, gamma_gain * power(abs(x1), gamma_power))

    def rates(r: float, eta1: float, eta2: float, inputs: Held) -> Rates:
        """(zeta1, z2, weight2, ptp1, ptp2, r', eta1', eta2') at states (r, eta1, eta2)."""
        s1, s2, x2, x2x2, yd2, yd2yd2, z1, a, gains1, layer1, kappa_z1z1, gamma_term = inputs
        # X_1 = [x1, yd, yd', r]: P^T P from its sum and sum of squares (controller.rbf.rbf_energy).
        s1 += r
        s2 += r * r
        if seven:
            ptp1 = (  # left to right, as rbf_energy's loop
                exp(scale * (s2 - m1 * s1 + c1))
                + exp(scale * (s2 - m2 * s1 + c2))
                + exp(scale * (s2 - m3 * s1 + c3))
                + exp(scale * (s2 - m4 * s1 + c4))
                + exp(scale * (s2 - m5 * s1 + c5))
                + exp(scale * (s2 - m6 * s1 + c6))
                + exp(scale * (s2 - m7 * s1 + c7))
            )
        else:
            ptp1 = 0.0
            for two_mu, dim_mu2 in neurons1:
                ptp1 += exp(scale * (s2 - two_mu * s1 + dim_mu2))
        # X_2 adds x2, eta_hat_1 and yd''.
        s1 += x2 + eta1 + yd2
        s2 += x2x2 + eta1 * eta1 + yd2yd2
        if seven:
            ptp2 = (
                exp(scale * (s2 - m1 * s1 + d1))
                + exp(scale * (s2 - m2 * s1 + d2))
                + exp(scale * (s2 - m3 * s1 + d3))
                + exp(scale * (s2 - m4 * s1 + d4))
                + exp(scale * (s2 - m5 * s1 + d5))
                + exp(scale * (s2 - m6 * s1 + d6))
                + exp(scale * (s2 - m7 * s1 + d7))
            )
        else:
            ptp2 = 0.0
            for two_mu, dim_mu2 in neurons2:
                ptp2 += exp(scale * (s2 - two_mu * s1 + dim_mu2))

        weight1 = ptp1 / two_a2_1
        if z1 != 0.0:
            if semi:
                phi = gains1 + eta1 * a * weight1 if nn else gains1
                zeta1 = -copysign(layer1 if layer1 < phi else phi, z1)  # min(phi, a / bh)
            else:
                zeta1 = gains1 - eta1 * z1 * weight1 if nn else gains1
        else:
            zeta1 = 0.0
        z2 = x2 - zeta1
        weight2 = ptp2 / two_a2_2
        return (zeta1, z2, weight2, ptp1, ptp2, -a_bar * r + gamma_term + d_r,
                kappa_z1z1 * weight1 - leak1 * eta1, kappa2 * z2 * z2 * weight2 - leak2 * eta2)

    def law_at(r: float, eta1: float, eta2: float, inputs: Held) -> LawValues:
        """(v, z1, z2, zeta1, ptp1, ptp2, r', eta1', eta2') at states (r, eta1, eta2) and the inputs
        of ``inputs = held(...)``."""
        zeta1, z2, weight2, ptp1, ptp2, dr, deta1, deta2 = rates(r, eta1, eta2, inputs)
        if z2 != 0.0:
            a = abs(z2)
            if semi:
                phi = k2 * power(a, p_alpha) + q2 * power(a, p_beta) + eta2 * a * weight2 if nn else (
                    k2 * power(a, p_alpha) + q2 * power(a, p_beta))
                v = -copysign(a / bh if a / bh < phi else phi, z2)  # min(phi, a / bh)
            elif nn:
                v = (-k2 * copysign(power(a, p_alpha), z2) - q2 * copysign(power(a, p_beta), z2)
                     - eta2 * z2 * weight2)
            else:
                v = -k2 * copysign(power(a, p_alpha), z2) - q2 * copysign(power(a, p_beta), z2)
        else:
            v = 0.0
        return (v, inputs[6], z2, zeta1, ptp1, ptp2, dr, deta1, deta2)

    return held, rates, law_at


class Order2Controller:
    """:class:`controller.stepping.AdaptiveController` for n = 2: same states, law and RK4 stepping.

    The states are the floats ``r``, ``eta1``, ``eta2``. :meth:`law` evaluates the control and the
    state derivative for explicit states and inputs; :meth:`stage` at the current state, keeping
    the inputs' share; :meth:`advance` integrates over one step with the inputs held, reusing a
    stage when given one.
    """

    def __init__(self, params: ControllerParameters, substeps: int = 1) -> None:
        if params.n != 2:
            raise ValueError(f"Order2Controller needs a plant of order n = 2 (got n = {params.n})")
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1 (got {substeps})")
        self.params = params
        self.substeps = substeps
        self._held, self._rates, self._law_at = _kernels_for(params)
        self.r = self.eta1 = self.eta2 = 0.0
        self.reset()

    def reset(self) -> None:
        """Back to the initial values r0 and eta0."""
        assert self.params.eta0 is not None  # ControllerParameters fills it
        self.r = self.params.r0
        self.eta1, self.eta2 = self.params.eta0

    @property
    def state(self) -> list[float]:
        """``[r, eta_hat_1, eta_hat_2]`` as in :class:`~controller.stepping.AdaptiveController`."""
        return [self.r, self.eta1, self.eta2]

    @state.setter
    def state(self, value: Sequence[float]) -> None:
        self.r, self.eta1, self.eta2 = value

    def law(self, r: float, eta1: float, eta2: float, x1: float, x2: float, yd: float, yd1: float, yd2: float
            ) -> LawValues:
        """(v, z1, z2, zeta1, ptp1, ptp2, r', eta1', eta2') at states (r, eta1, eta2), plant states
        (x1, x2) and reference (yd, yd', yd'')."""
        return self._law_at(r, eta1, eta2, self._held(x1, x2, yd, yd1, yd2))

    def stage(self, x1: float, x2: float, yd: float, yd1: float, yd2: float) -> Stage:
        """The law at the current state and these inputs, with the inputs' share of it: the caller
        shows the law as outputs and hands the pair to :meth:`advance` as its first stage."""
        inputs = self._held(x1, x2, yd, yd1, yd2)
        return self._law_at(self.r, self.eta1, self.eta2, inputs), inputs

    def output(self, x: Sequence[float], yd: Sequence[float]) -> ControlTerms:
        """The control and its terms at the current state, as :meth:`AdaptiveController.output`."""
        v, z1, z2, zeta1, ptp1, ptp2, dr, d1, d2 = self.law(self.r, self.eta1, self.eta2, *x, *yd)
        return ControlTerms(v=v, z=(z1, z2), zeta=(zeta1, v), ptp=(ptp1, ptp2), derivative=(dr, d1, d2))

    def advance(
        self,
        x1: float,
        x2: float,
        yd: float,
        yd1: float,
        yd2: float,
        h: float,
        first: Stage | None = None,
    ) -> None:
        """Integrate r and eta_hat over a step of length h with the inputs held (RK4, ``substeps``).

        ``first`` may be :meth:`stage` at the current state and these inputs (the output the
        caller has just computed): it is the first RK4 stage and saves one evaluation, and its
        inputs' share saves computing that again.
        """
        rates = self._rates
        law: LawValues | None
        if first is None:
            law, inputs = None, self._held(x1, x2, yd, yd1, yd2)  # shared by every stage: inputs held
        else:
            law, inputs = first
        dt = h / self.substeps
        half = 0.5 * dt
        sixth = dt / 6.0
        r, e1, e2 = self.r, self.eta1, self.eta2
        for _ in range(self.substeps):
            if law is None:
                _, _, _, _, _, a0, a1, a2 = rates(r, e1, e2, inputs)
            else:
                a0, a1, a2 = law[6], law[7], law[8]
                law = None
            _, _, _, _, _, b0, b1, b2 = rates(r + half * a0, e1 + half * a1, e2 + half * a2, inputs)
            _, _, _, _, _, c0, c1, c2 = rates(r + half * b0, e1 + half * b1, e2 + half * b2, inputs)
            _, _, _, _, _, d0, d1, d2 = rates(r + dt * c0, e1 + dt * c1, e2 + dt * c2, inputs)
            r = r + sixth * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
            e1 = e1 + sixth * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
            e2 = e2 + sixth * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        self.r, self.eta1, self.eta2 = r, e1, e2
