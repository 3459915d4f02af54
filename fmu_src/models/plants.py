# SPDX-License-Identifier: BSD-2-Clause
"""The paper's plants (SPEC section 3) and their integrators over a communication step.

Plant states are ordered ``(x1, x2, z)``; right-hand sides take ``(t, state, uf)``. Pure Python
floats: these run inside every FMU step, and with three states NumPy's per-call overhead would
cost more than the arithmetic.

Two integrators advance a plant over one communication step with the input held:
:func:`dopri_hold_step` (Dormand-Prince 5(4) with error control, the default) and
:func:`hold_step` (classical RK4 with fixed sub-steps, kept for comparison and for importers that
set ``max_step``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

from controller.fmath import cos, power, sin

from .checks import bound_problems, finite_problems

__all__ = [
    "DOPRI",
    "MAX_STEPS",
    "METHODS",
    "RATE_HORIZON",
    "RK4",
    "STATE_LIMIT",
    "STATE_NAMES",
    "Y_LIMIT",
    "AdaptiveStep",
    "PendulumParameters",
    "RightHandSide",
    "State",
    "StateLimitError",
    "beyond_limit",
    "budget_spent",
    "dopri_hold_step",
    "carried_beyond",
    "escape_rate",
    "example1_rhs",
    "hold_step",
    "integration_problems",
    "no_step_size",
    "pendulum_problems",
    "pendulum_rhs",
    "pendulum_rhs_for",
]

State = tuple[float, float, float]
STATE_NAMES = ("x1", "x2", "z")  # the examples' states (the messages' names unless a plant gives its own)
RightHandSide = Callable[[float, Sequence[float], float], State]


def example1_rhs(t: float, state: Sequence[float], uf: float) -> State:
    """Example 1 (eq. 85): the plant with unmodeled dynamics z."""
    x1, x2, z = state
    return (
        (2.0 + sin(x1)) * x2 + 0.1 * sin(x1 * x2) + z * sin(x1 * x1),
        (2.0 + cos(x1 * x2)) * uf + 0.5 * sin(x1 * x1 * x2 * x2) + x1 * x1 * z,
        -z - x1 * x1 + 0.5,
    )


@dataclass(frozen=True)
class PendulumParameters:
    """Example 2 (eq. 99): mass M, length L, damping B, gravity g, disturbance amplitudes."""

    M: float = 0.25
    L: float = 4.0
    B: float = 0.25
    g: float = 10.0
    d1: float = 0.2
    d2: float = 0.3


def pendulum_rhs(t: float, state: Sequence[float], uf: float, p: PendulumParameters) -> State:
    """Example 2 (eq. 99): the pendulum with unmodeled dynamics z and disturbances."""
    x1, x2, z = state
    return (
        x2 + z * x1 + p.d1 * sin(t),
        uf / (p.M * p.L)
        - (p.g / p.L + p.B / p.M) * sin(x1 * x2)
        + z * x2 * sin(x1)
        + p.d2 * cos(t),
        -2.0 * z + 0.25 * x1 * x1,
    )


def pendulum_rhs_for(p: PendulumParameters) -> RightHandSide:
    """:func:`pendulum_rhs` with the parameters bound as local constants (the FMU's hot path: no
    attribute lookups per evaluation; the same operations, so the same values)."""
    d1, d2, ml, damping = p.d1, p.d2, p.M * p.L, p.g / p.L + p.B / p.M

    def rhs(t: float, state: Sequence[float], uf: float) -> State:
        x1, x2, z = state
        return (
            x2 + z * x1 + d1 * sin(t),
            uf / ml - damping * sin(x1 * x2) + z * x2 * sin(x1) + d2 * cos(t),
            -2.0 * z + 0.25 * x1 * x1,
        )

    return rhs


def hold_step(
    rhs: RightHandSide,
    t: float,
    state: Sequence[float],
    uf: float,
    h: float,
    max_step: float,
    limit: float = math.inf,
    y_limit: float = math.inf,
    rate_horizon: float = 0.0,
    names: Sequence[str] = STATE_NAMES,
) -> State:
    """Advance a plant over [t, t + h] with uf held, by classical RK4.

    The step is cut into ceil(h / max_step) equal sub-steps; the global error is
    O(max_step^4), so ``max_step`` is the integrator's accuracy parameter. With ``rate_horizon``
    > 0, the rate bound of :func:`dopri_hold_step` applies at the start of every sub-step
    (:class:`StateLimitError`).
    """
    substeps = max(1, math.ceil(h / max_step - 1e-9))
    dt = h / substeps
    reach = rate_horizon * h
    x1_limit = min(limit, y_limit)
    x1, x2, z = state
    for i in range(substeps):
        ti = t + i * dt
        a1, a2, a3 = rhs(ti, (x1, x2, z), uf)
        if carried_beyond((x1, x2, z), (a1, a2, a3), reach, x1_limit, limit):
            raise StateLimitError(escape_rate((x1, x2, z), (a1, a2, a3), ti, reach, limit, y_limit, names))
        b1, b2, b3 = rhs(ti + 0.5 * dt, (x1 + 0.5 * dt * a1, x2 + 0.5 * dt * a2, z + 0.5 * dt * a3), uf)
        c1, c2, c3 = rhs(ti + 0.5 * dt, (x1 + 0.5 * dt * b1, x2 + 0.5 * dt * b2, z + 0.5 * dt * b3), uf)
        d1, d2, d3 = rhs(ti + dt, (x1 + dt * c1, x2 + dt * c2, z + dt * c3), uf)
        x1 += dt / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
        x2 += dt / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        z += dt / 6.0 * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
    return x1, x2, z


# Values of the plant FMUs' Integer parameter ``method``.
DOPRI = 0  # Dormand-Prince 5(4), step size from rtol/atol
RK4 = 1  # classical RK4, fixed sub-steps of at most max_step
METHODS = {DOPRI: "Dormand-Prince 5(4) with error control", RK4: "RK4 with fixed sub-steps"}

# Dormand & Prince (1980), "A family of embedded Runge-Kutta formulae", J. Comput. Appl. Math. 6;
# coefficients as in Hairer, Norsett & Wanner, Solving ODEs I, Table II.5.2. The 7th stage is the
# function value at the new point; E = b - b_hat gives the error estimate of the 4th-order solution.
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = 71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40
_SAFETY, _FAC_MIN, _FAC_MAX = 0.9, 0.2, 10.0

# Fail-fast defaults of the plant FMUs (parameters ``y_limit``, ``state_limit`` and ``max_steps``),
# measured on the sampled loops of the fixed-time study (Example 1 at 1 ms, the pendulum at 0.5 ms,
# initial states in [-10, 10]^2, both laws, explicit and semi-implicit): the runs that settle reach
# states up to 753 (Example 1) and 2563 (the pendulum), in x2, and up to 22 572 integrator steps in
# one communication step (Example 1's first, semi-implicit, from (10, 10)); their output x1 moves
# from x1(0) towards the reference (|yd| <= 1). A finite escape runs away in x1 first: the output
# of Example 1 from (6, 0) under the finite-time law passes -12 at 0.86 s, -20 at 0.9 s, and the
# integrator crawls (resolving sin(x1^2 x2^2)) for 0.05 s more before any state reaches 1e4:
# two thirds of the run's CPU. Y_LIMIT (|x1| = |y|) ends such a step early; STATE_LIMIT (any
# state) ends what passes it otherwise; MAX_STEPS (accepted and rejected steps in one
# communication step, about 4 us each in Python, 0.4 us compiled) ends a step that a held
# control of 1e7 makes the integrator crawl through (explicit sampling from far states: more
# than 100 000 at 1 ms; a campaign at a finer step from such states may need more: 58 455 at
# 0.1 ms from (10, 10)).
# Before, a diverging run ran into the old budget of 100 000 steps: 0.6-3 s of CPU per run.
#
# RATE_HORIZON (in communication steps) ends a step whose right-hand side would carry a state
# beyond its bound within that many steps (|dx_i/dt| * RATE_HORIZON * h above the bound), checked
# where the integrator has the derivative anyway: at the step's start (the new input applied)
# and at every accepted point inside it. A held control of 1e7 on Example 1 (x2' >= 1e7) at 1 ms
# is told by the first evaluation instead of 50 000 integrator steps (0.2-0.3 s of CPU). The runs
# of the study that settle stay at or below 0.26 of their bounds at the points checked: Example 1
# at 0.11 (|dx1/dt| h = 2.3 against y_limit 20, semi-implicit from (10, -9)), the pendulum at 0.26
# (|dx2/dt| h = 2.6e3 against state_limit 1e4, semi-implicit from (-10, -10), |uf| 5.1e6 at 0.5 ms).
#
# Issue 37: those bounds ended settling runs from beyond the study's box as "diverged" (false
# divergences): the rate bound compared |dx/dt| h with a bound on the state's size (the first
# control from x2(0) = 8000 brings x2 back to 0 at 2e7 per second: |dx2/dt| h = 1e4 > 1e4), and
# the fixed-time law overshoots y_limit 20 from x1(0) = 10, x2(0) = 9500 (to 31). The rate bound
# now moves the state on at its rate (:func:`carried_beyond`), and the bounds sit above every state
# the closed loop reaches while it settles from |x1(0)| <= 20, |x2(0)| <= 1e4 (21 x 21 grid, both
# examples, semi-implicit fixed-time law, no bound: |x1| <= 31.6, |x2| <= 10 090, |z| <= 2.6;
# ``make check-fail-fast``), with a margin of 3 (x1) and 100 (x2, z). A finite escape passes them
# within milliseconds of passing the old ones (x1 grows like 1 / (t_escape - t)). The step budget
# ended settling runs too: the first millisecond from (-20, -1e4) needs more than 500 000 steps
# (0.5 sin(x1^2 x2^2) oscillates at about 1e13 rad/s there); 2 000 000 compiled steps cost 0.7 s.
Y_LIMIT = 100.0
STATE_LIMIT = 1e6
MAX_STEPS = 2_000_000
RATE_HORIZON = 1.0


class StateLimitError(ValueError):
    """The plant's state left its range of validity (|x1|, |x2| or |z| above the limit)."""


def carried_beyond(state: Sequence[float], rate: Sequence[float], reach: float, x1_limit: float,
                   limit: float) -> bool:
    """The rate bound: whether the state, moved on at its present rate for ``reach`` seconds,
    would be beyond its bound (x1: ``x1_limit``; x2, z: ``limit``); never when ``reach`` is 0.

    The state itself counts, not only the rate: a large rate that brings a large state back (the
    first control of a settling run from x2(0) = 8000) is no escape; comparing the rate alone
    with the bound (before issue 37) ended such runs at t = 0."""
    return reach > 0.0 and (
        abs(state[0] + rate[0] * reach) > x1_limit
        or abs(state[1] + rate[1] * reach) > limit
        or abs(state[2] + rate[2] * reach) > limit
    )


def escape_rate(state: Sequence[float], rate: Sequence[float], t: float, reach: float, limit: float,
                y_limit: float, names: Sequence[str] = STATE_NAMES) -> str:
    """Why a step ends on the rate bound (:func:`carried_beyond`): the first state that ``rate``
    (dx/dt), held over ``reach`` seconds, carries beyond its bound (x1: ``y_limit`` or ``limit``,
    the smaller; x2, z: ``limit``); ``names``: the plant's names of the three states."""
    x1_bound = ("y_limit", y_limit) if y_limit <= limit else ("state_limit", limit)
    bounds = (x1_bound, ("state_limit", limit), ("state_limit", limit))
    i = next((i for i in range(3) if abs(state[i] + rate[i] * reach) > bounds[i][1]), 0)
    name, bound = bounds[i]
    return (
        f"d{names[i]}/dt = {rate[i]:.6g} at t = {t!r} would carry {names[i]} from {state[i]:.6g} to "
        f"{state[i] + rate[i] * reach:.6g}, beyond the plant's {name} {bound:g}, within {reach:g} s "
        f"(abs({names[i]} + d{names[i]}/dt * rate_horizon * h) > {name}: leaving its range of validity)"
    )


def beyond_limit(state: State, t: float, limit: float, y_limit: float) -> StateLimitError:
    """The error of an accepted step whose ``state`` at ``t`` is beyond a bound (x1: ``y_limit``)."""
    n1, n2, n3 = state
    name, bound = ("y_limit", y_limit) if abs(n1) > y_limit else ("state_limit", limit)
    return StateLimitError(
        f"state ({n1:.6g}, {n2:.6g}, {n3:.6g}) at t = {t!r} beyond the plant's "
        f"{name} {bound:g} (left its range of validity)"
    )


def budget_spent(max_steps: int, t: float, accepted: int, rejected: int) -> ValueError:
    """The error of a communication step that spent its ``max_steps`` integrator steps by ``t``."""
    return ValueError(
        f"step budget of {max_steps} integrator steps spent at t = {t!r} "
        f"({accepted} accepted, {rejected} rejected in this communication step)"
    )


def no_step_size(rtol: float, atol: float, t: float, accepted: int, rejected: int) -> ValueError:
    """The error of a trial step shrunk below 1e-12 h without meeting the tolerances."""
    return ValueError(
        f"no step size meets rtol = {rtol!r}, atol = {atol!r} at t = {t!r} "
        f"({accepted} steps accepted, {rejected} rejected in this communication step)"
    )


class AdaptiveStep(NamedTuple):
    """Result of :func:`dopri_hold_step`: the new states, the step size to try next, and how many
    steps were accepted and rejected (rejected steps cost the same 6 evaluations as accepted ones)."""

    state: State
    next_step: float
    accepted: int
    rejected: int


def dopri_hold_step(
    rhs: RightHandSide,
    t: float,
    state: Sequence[float],
    uf: float,
    h: float,
    rtol: float,
    atol: float,
    first_step: float,
    limit: float = math.inf,
    max_steps: int = MAX_STEPS,
    y_limit: float = math.inf,
    rate_horizon: float = 0.0,
    names: Sequence[str] = STATE_NAMES,
) -> AdaptiveStep:
    """Advance a plant over [t, t + h] with uf held, by Dormand-Prince 5(4) with step-size control.

    A step is accepted when the RMS over the states of err_i / (atol + rtol max(|y_i|, |y_new_i|))
    is at most 1 (Hairer's norm); the next size is 0.9 err^(-1/5) times this one, within
    [0.2, 10] (no growth right after a rejection). Local extrapolation: the 5th-order solution
    is kept. The step lands exactly on t + h.

    ``first_step`` is the size to try first: the ``next_step`` of the previous communication step.
    The input uf jumps at every communication point, but the solution is smooth within the step
    (uf is held), so the carried size stays a good guess; when the jump changes the local error
    scale, the first step is rejected and shrunk. A step that was shortened to land on t + h does
    not shrink the guess passed on. Raises ``ValueError``/``OverflowError`` when the states
    overflow the math functions, ``ValueError`` when no step size meets the tolerances within
    ``max_steps`` steps (accepted and rejected), and :class:`StateLimitError` as soon as an
    accepted step has a state of magnitude above ``limit`` or an output x1 above ``y_limit`` (fail
    fast: an escaping state is not followed with ever smaller steps), or when ``rate_horizon`` > 0
    and the right-hand side at t or at an accepted point inside the step would carry a state
    beyond its bound within ``rate_horizon * h`` (see :func:`escape_rate`): a held input that
    drives the state out of range is told at once, before the integrator crawls after it.
    ``names`` names the three states in the messages.
    """
    t_end = t + h
    y1, y2, y3 = state
    k11, k12, k13 = rhs(t, (y1, y2, y3), uf)
    reach = rate_horizon * h
    x1_limit = min(limit, y_limit)
    if carried_beyond((y1, y2, y3), (k11, k12, k13), reach, x1_limit, limit):
        raise StateLimitError(escape_rate((y1, y2, y3), (k11, k12, k13), t, reach, limit, y_limit, names))
    dt = min(first_step, h) if first_step > 0.0 else h
    accepted = rejected = 0
    grow = _FAC_MAX
    while True:
        remaining = t_end - t
        wanted = dt
        last = dt >= remaining * (1.0 - 1e-12)
        if last:
            dt = remaining
        try:
            k21, k22, k23 = rhs(t + _C2 * dt, (
                y1 + dt * _A21 * k11, y2 + dt * _A21 * k12, y3 + dt * _A21 * k13), uf)
            k31, k32, k33 = rhs(t + _C3 * dt, (
                y1 + dt * (_A31 * k11 + _A32 * k21),
                y2 + dt * (_A31 * k12 + _A32 * k22),
                y3 + dt * (_A31 * k13 + _A32 * k23)), uf)
            k41, k42, k43 = rhs(t + _C4 * dt, (
                y1 + dt * (_A41 * k11 + _A42 * k21 + _A43 * k31),
                y2 + dt * (_A41 * k12 + _A42 * k22 + _A43 * k32),
                y3 + dt * (_A41 * k13 + _A42 * k23 + _A43 * k33)), uf)
            k51, k52, k53 = rhs(t + _C5 * dt, (
                y1 + dt * (_A51 * k11 + _A52 * k21 + _A53 * k31 + _A54 * k41),
                y2 + dt * (_A51 * k12 + _A52 * k22 + _A53 * k32 + _A54 * k42),
                y3 + dt * (_A51 * k13 + _A52 * k23 + _A53 * k33 + _A54 * k43)), uf)
            t_new = t_end if last else t + dt
            k61, k62, k63 = rhs(t_new, (
                y1 + dt * (_A61 * k11 + _A62 * k21 + _A63 * k31 + _A64 * k41 + _A65 * k51),
                y2 + dt * (_A61 * k12 + _A62 * k22 + _A63 * k32 + _A64 * k42 + _A65 * k52),
                y3 + dt * (_A61 * k13 + _A62 * k23 + _A63 * k33 + _A64 * k43 + _A65 * k53)), uf)
            n1 = y1 + dt * (_B1 * k11 + _B3 * k31 + _B4 * k41 + _B5 * k51 + _B6 * k61)
            n2 = y2 + dt * (_B1 * k12 + _B3 * k32 + _B4 * k42 + _B5 * k52 + _B6 * k62)
            n3 = y3 + dt * (_B1 * k13 + _B3 * k33 + _B4 * k43 + _B5 * k53 + _B6 * k63)
            k71, k72, k73 = rhs(t_new, (n1, n2, n3), uf)
            e1 = dt * (_E1 * k11 + _E3 * k31 + _E4 * k41 + _E5 * k51 + _E6 * k61 + _E7 * k71)
            e2 = dt * (_E1 * k12 + _E3 * k32 + _E4 * k42 + _E5 * k52 + _E6 * k62 + _E7 * k72)
            e3 = dt * (_E1 * k13 + _E3 * k33 + _E4 * k43 + _E5 * k53 + _E6 * k63 + _E7 * k73)
            s1 = e1 / (atol + rtol * max(abs(y1), abs(n1)))
            s2 = e2 / (atol + rtol * max(abs(y2), abs(n2)))
            s3 = e3 / (atol + rtol * max(abs(y3), abs(n3)))
            err = math.sqrt((s1 * s1 + s2 * s2 + s3 * s3) / 3.0)
        except (ValueError, OverflowError):  # a trial step too long for an overflowing transient
            err = math.inf
        if err <= 1.0:  # accepted (False for nan)
            accepted += 1
            if abs(n1) > y_limit or abs(n1) > limit or abs(n2) > limit or abs(n3) > limit:
                raise beyond_limit((n1, n2, n3), t_new, limit, y_limit)
            fac = min(grow, _SAFETY * power(err, -0.2)) if err > 0.0 else grow
            proposal = dt * max(_FAC_MIN, fac)
            if last:
                return AdaptiveStep((n1, n2, n3), max(proposal, wanted), accepted, rejected)
            if accepted + rejected >= max_steps:
                raise budget_spent(max_steps, t_new, accepted, rejected)
            t, y1, y2, y3 = t_new, n1, n2, n3
            k11, k12, k13 = k71, k72, k73  # first same as last
            if carried_beyond((y1, y2, y3), (k11, k12, k13), reach, x1_limit, limit):
                raise StateLimitError(
                    escape_rate((y1, y2, y3), (k11, k12, k13), t, reach, limit, y_limit, names))
            dt = proposal
            grow = _FAC_MAX
        else:
            rejected += 1
            if dt <= 1e-12 * h:
                raise no_step_size(rtol, atol, t, accepted, rejected)
            if accepted + rejected >= max_steps:
                raise budget_spent(max_steps, t, accepted, rejected)
            dt *= max(_FAC_MIN, _SAFETY * power(err, -0.2)) if math.isfinite(err) else _FAC_MIN
            grow = 1.0


def pendulum_problems(p: PendulumParameters) -> list[str]:
    """Violated constraints of the pendulum parameters (empty if valid): M, L > 0, B >= 0."""
    problems = bound_problems(p, ("M", "L"), strict=True)
    problems += bound_problems(p, ("B",), strict=False)
    return problems + finite_problems(p, ("g", "d1", "d2"))


def integration_problems(initial: dict[str, float], max_step: float) -> list[str]:
    """Violated constraints of a plant's initial states (finite) and accuracy (max_step > 0)."""
    problems = [
        f"{name} must be a finite number (got {v!r})" for name, v in initial.items() if not math.isfinite(v)
    ]
    if not (math.isfinite(max_step) and max_step > 0.0):
        problems.append(f"max_step must satisfy max_step > 0 (got {max_step!r})")
    return problems
