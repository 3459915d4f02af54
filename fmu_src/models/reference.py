# SPDX-License-Identifier: BSD-2-Clause
"""Reference trajectory yd(t) = A sin(omega t + phase) + offset and its derivatives (SPEC section 2)."""

from __future__ import annotations

from dataclasses import dataclass

from controller.fmath import cos, sin

from .checks import finite_problems

__all__ = ["ReferenceParameters", "reference_derivatives", "reference_problems", "reference_signal"]


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
    s, c = sin(angle), cos(angle)
    return (
        p.amplitude * s + p.offset,
        p.amplitude * p.omega * c,
        -p.amplitude * p.omega * p.omega * s,
    )


def reference_derivatives(t: float, p: ReferenceParameters) -> tuple[float, float, float, float, float]:
    """yd and its derivatives up to the fourth at time t, as a plant of order n <= 4 needs them
    (yd^(j) = amplitude omega^j sin(omega t + phase + j pi / 2)); the first three as
    :func:`reference_signal` computes them (the same values)."""
    angle = p.omega * t + p.phase
    s, c = sin(angle), cos(angle)
    a, w = p.amplitude, p.omega
    return (a * s + p.offset, a * w * c, -a * w * w * s, -a * w * w * w * c, a * w * w * w * w * s)


def reference_problems(p: ReferenceParameters) -> list[str]:
    """Violated constraints of the reference parameters (empty if valid): all finite."""
    return finite_problems(p, ("amplitude", "omega", "phase", "offset"))
