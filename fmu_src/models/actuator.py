"""Actuator: input dead-zone (eq. 2-6) followed by the actuator fault (eq. 86-87, 100-101)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .checks import bound_problems, finite_problems

__all__ = ["ActuatorParameters", "actuator_output", "actuator_problems", "dead_zone"]


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


def actuator_problems(p: ActuatorParameters) -> list[str]:
    """Violated constraints of the actuator parameters (empty if valid).

    Slopes ``m_r, m_l`` and the lasting effectiveness ``K_inf`` are positive (so K(t) > 0);
    break points, ``K_amp`` and ``K_rate`` are non-negative; the rest finite (``t_fault`` may be
    +inf: never faulty).
    """
    problems = bound_problems(p, ("m_r", "m_l", "K_inf"), strict=True)
    problems += bound_problems(p, ("b_r", "b_l", "K_amp", "K_rate"), strict=False)
    problems += finite_problems(p, ("L_gain", "L_bias"))
    if math.isnan(p.t_fault):
        problems.append("t_fault must be a number (got nan)")
    return problems
