"""The paper's plants (SPEC section 3) and their integrator over a communication step.

Plant states are ordered ``(x1, x2, z)``; right-hand sides take ``(t, state, uf)``. Pure Python
floats: these run inside every FMU step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from .checks import bound_problems, finite_problems

__all__ = [
    "PendulumParameters",
    "RightHandSide",
    "State",
    "example1_rhs",
    "hold_step",
    "integration_problems",
    "pendulum_problems",
    "pendulum_rhs",
]

State = tuple[float, float, float]
RightHandSide = Callable[[float, Sequence[float], float], State]


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
