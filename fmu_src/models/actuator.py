# SPDX-License-Identifier: BSD-2-Clause
"""Actuator: saturation (beyond the paper, SPEC section 10), input dead-zone (eq. 2-6), then the
actuator fault (eq. 86-87, 100-101)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from controller.fmath import cos, exp

from .checks import bound_problems, finite_problems

__all__ = ["NO_LIMIT", "ActuatorParameters", "actuator_output", "actuator_problems", "dead_zone", "saturate"]

# Default of ``u_max``: no limit in effect, with no special "off" value (clip(v, -u_max, u_max) =
# v for every |v| <= 1e300, beyond any control a finite run computes) and a start value every XML
# reader takes (neither "inf" nor the largest double, which the model description prints rounded
# up, i.e. as an overflow). +inf may be set.
NO_LIMIT = 1e300


@dataclass(frozen=True)
class ActuatorParameters:
    """Dead-zone (eq. 2-6), actuator fault (eq. 86-87, 100-101) and the saturation limit ``u_max``
    (last: the FMU declares the fields in this order, and value references must not move)."""

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
    u_max: float = NO_LIMIT


def saturate(v: float, u_max: float) -> float:
    """v_sat = clip(v, -u_max, u_max): the amplifier's limit (SPEC section 10)."""
    return max(-u_max, min(u_max, v))


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
    """(uf, u_dz) with v_sat = clip(v, -u_max, u_max): before t_fault uf = v_sat; from t_fault on
    uf = K(t) u(v_sat) + L(t). The saturation acts first, as a real amplifier's limit does."""
    v = saturate(v, p.u_max)
    u = dead_zone(v, p)
    if t < p.t_fault:
        return v, u
    K = p.K_inf + p.K_amp * exp(-p.K_rate * t)
    cos_x1 = cos(x1)
    L = p.L_gain * x2 * cos_x1 * cos_x1 + p.L_bias
    return K * u + L, u


def actuator_problems(p: ActuatorParameters) -> list[str]:
    """Violated constraints of the actuator parameters (empty if valid).

    Slopes ``m_r, m_l`` and the lasting effectiveness ``K_inf`` are positive (so K(t) > 0);
    break points, ``K_amp`` and ``K_rate`` are non-negative; the rest finite (``t_fault`` may be
    +inf: never faulty); ``u_max`` is positive (+inf: no limit, as the default).
    """
    problems = bound_problems(p, ("m_r", "m_l", "K_inf"), strict=True)
    problems += bound_problems(p, ("b_r", "b_l", "K_amp", "K_rate"), strict=False)
    problems += finite_problems(p, ("L_gain", "L_bias"))
    if math.isnan(p.t_fault):
        problems.append("t_fault must be a number (got nan)")
    if not p.u_max > 0.0:  # nan too
        problems.append(f"u_max must satisfy u_max > 0 (got {p.u_max!r})")
    return problems
