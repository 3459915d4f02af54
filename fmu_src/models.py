"""Plant, actuator and reference math (SPEC sections 2-3), shared by the FMUs and the
monolithic reference simulation. Pure Python floats: these run inside every FMU step.

Plant states are ordered ``(x1, x2, z)``; right-hand sides take ``(t, state, uf)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

__all__ = [
    "ActuatorParameters",
    "PendulumParameters",
    "ReferenceParameters",
    "actuator_output",
    "actuator_problems",
    "dead_zone",
    "example1_rhs",
    "hold_step",
    "integration_problems",
    "pendulum_problems",
    "pendulum_rhs",
    "reference_problems",
    "reference_signal",
]

State = tuple[float, float, float]
RightHandSide = Callable[[float, Sequence[float], float], State]


@dataclass(frozen=True)
class ReferenceParameters:
    """yd(t) = amplitude * sin(omega * t + phase) + offset."""

    amplitude: float = 0.5
    omega: float = 1.0
    phase: float = 0.0
    offset: float = 0.0


def reference_signal(t: float, p: ReferenceParameters) -> tuple[float, float, float]:
    """yd, yd' and yd'' at time t."""
    angle = p.omega * t + p.phase
    s, c = math.sin(angle), math.cos(angle)
    return (
        p.amplitude * s + p.offset,
        p.amplitude * p.omega * c,
        -p.amplitude * p.omega * p.omega * s,
    )


@dataclass(frozen=True)
class ActuatorParameters:
    """Dead-zone (eq. 2-6) and actuator fault (eq. 86-87, 100-101)."""

    m_r: float = 1.0
    m_l: float = 1.2
    b_r: float = 0.5
    b_l: float = 0.6
    K_inf: float = 0.4
    K_amp: float = 0.6
    K_rate: float = 0.2
    L_gain: float = 1.0
    L_bias: float = 0.0
    t_fault: float = 10.0


def dead_zone(v: float, p: ActuatorParameters) -> float:
    """u(v): m_r (v - b_r) above b_r, m_l (v + b_l) below -b_l, zero in between."""
    if v >= p.b_r:
        return p.m_r * (v - p.b_r)
    if v <= -p.b_l:
        return p.m_l * (v + p.b_l)
    return 0.0


def actuator_output(
    t: float, v: float, x1: float, x2: float, p: ActuatorParameters
) -> tuple[float, float]:
    """(uf, u_dz): before t_fault uf = v; from t_fault on uf = K(t) u(v) + L(t)."""
    u = dead_zone(v, p)
    if t < p.t_fault:
        return v, u
    K = p.K_inf + p.K_amp * math.exp(-p.K_rate * t)
    cos_x1 = math.cos(x1)
    L = p.L_gain * x2 * cos_x1 * cos_x1 + p.L_bias
    return K * u + L, u


def example1_rhs(t: float, state: Sequence[float], uf: float) -> State:
    """Example 1 (eq. 85): the plant with unmodeled dynamics z."""
    x1, x2, z = state
    return (
        (2.0 + math.sin(x1)) * x2 + 0.1 * math.sin(x1 * x2) + z * math.sin(x1 * x1),
        (2.0 + math.cos(x1 * x2)) * uf + 0.5 * math.sin(x1 * x1 * x2 * x2) + x1 * x1 * z,
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
        x2 + z * x1 + p.d1 * math.sin(t),
        uf / (p.M * p.L)
        - (p.g / p.L + p.B / p.M) * math.sin(x1 * x2)
        + z * x2 * math.sin(x1)
        + p.d2 * math.cos(t),
        -2.0 * z + 0.25 * x1 * x1,
    )


def hold_step(
    rhs: RightHandSide, t: float, state: Sequence[float], uf: float, h: float, max_step: float
) -> State:
    """Advance a plant over [t, t + h] with uf held, by classical RK4.

    The step is cut into ceil(h / max_step) equal sub-steps; the global error is
    O(max_step^4), so ``max_step`` is the integrator's accuracy parameter.
    """
    substeps = max(1, math.ceil(h / max_step - 1e-9))
    dt = h / substeps
    x1, x2, z = state
    for i in range(substeps):
        ti = t + i * dt
        a1, a2, a3 = rhs(ti, (x1, x2, z), uf)
        b1, b2, b3 = rhs(ti + 0.5 * dt, (x1 + 0.5 * dt * a1, x2 + 0.5 * dt * a2, z + 0.5 * dt * a3), uf)
        c1, c2, c3 = rhs(ti + 0.5 * dt, (x1 + 0.5 * dt * b1, x2 + 0.5 * dt * b2, z + 0.5 * dt * b3), uf)
        d1, d2, d3 = rhs(ti + dt, (x1 + dt * c1, x2 + dt * c2, z + dt * c3), uf)
        x1 += dt / 6.0 * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
        x2 += dt / 6.0 * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        z += dt / 6.0 * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
    return x1, x2, z


def _finite_problems(p: object, names: Sequence[str]) -> list[str]:
    """``name`` must be finite, for every name."""
    values = {name: getattr(p, name) for name in names}
    return [
        f"{name} must be a finite number (got {v!r})"
        for name, v in values.items() if not math.isfinite(v)
    ]


def _bound_problems(p: object, names: Sequence[str], strict: bool) -> list[str]:
    """``name > 0`` (strict) or ``name >= 0`` for every name, finite."""
    problems = []
    for name in names:
        value = getattr(p, name)
        ok = math.isfinite(value) and (value > 0.0 if strict else value >= 0.0)
        if not ok:
            relation = ">" if strict else ">="
            problems.append(f"{name} must satisfy {name} {relation} 0 (got {value!r})")
    return problems


def reference_problems(p: ReferenceParameters) -> list[str]:
    """Violated constraints of the reference parameters (empty if valid): all finite."""
    return _finite_problems(p, ("amplitude", "omega", "phase", "offset"))


def actuator_problems(p: ActuatorParameters) -> list[str]:
    """Violated constraints of the actuator parameters (empty if valid).

    Slopes ``m_r, m_l`` and the lasting effectiveness ``K_inf`` are positive (so K(t) > 0);
    break points, ``K_amp`` and ``K_rate`` are non-negative; the rest finite (``t_fault`` may be
    +inf: never faulty).
    """
    problems = _bound_problems(p, ("m_r", "m_l", "K_inf"), strict=True)
    problems += _bound_problems(p, ("b_r", "b_l", "K_amp", "K_rate"), strict=False)
    problems += _finite_problems(p, ("L_gain", "L_bias"))
    if math.isnan(p.t_fault):
        problems.append("t_fault must be a number (got nan)")
    return problems


def pendulum_problems(p: PendulumParameters) -> list[str]:
    """Violated constraints of the pendulum parameters (empty if valid): M, L > 0, B >= 0."""
    problems = _bound_problems(p, ("M", "L"), strict=True)
    problems += _bound_problems(p, ("B",), strict=False)
    return problems + _finite_problems(p, ("g", "d1", "d2"))


def integration_problems(initial: dict[str, float], max_step: float) -> list[str]:
    """Violated constraints of a plant's initial states (finite) and accuracy (max_step > 0)."""
    problems = [
        f"{name} must be a finite number (got {v!r})" for name, v in initial.items() if not math.isfinite(v)
    ]
    if not (math.isfinite(max_step) and max_step > 0.0):
        problems.append(f"max_step must satisfy max_step > 0 (got {max_step!r})")
    return problems
