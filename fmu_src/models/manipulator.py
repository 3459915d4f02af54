# SPDX-License-Identifier: BSD-2-Clause
"""A third-order plant from the literature: a single-link robot manipulator driven by a brush DC
motor, written from its source paper.

Source: D. M. Dawson, J. J. Carroll and M. Schneider, "Integrator backstepping control of a brush DC
motor turning a robotic load", IEEE Transactions on Control Systems Technology 2(3), 233-244, 1994.
The electromechanical model (their eq. 1-2), with the link angle q, the armature current I and the
motor voltage V:

    M q'' + B q' + N sin(q) = I,      L I' = V - R I - K_B q',

    M = J / K_tau + m L0^2 / (3 K_tau) + M0 L0^2 / K_tau + 2 M0 R0^2 / (5 K_tau),
    N = m L0 G / (2 K_tau) + M0 L0 G / K_tau,      B = B0 / K_tau,

the link (length L0, mass m) carrying a load (a sphere of radius R0, mass M0) at its tip, motor
inertia J, viscous friction B0, torque constant K_tau, back-emf constant K_B, inductance L,
resistance R. Their simulation values are the defaults of :class:`ManipulatorParameters`
(J = 1.625e-3 kg m^2, L0 = 0.305 m, m = 0.506 kg, R0 = 0.023 m, M0 = 0.434 kg, B0 = 16.25e-3
N m s/rad, L = 25.0e-3 H, R = 5.0 Ohm, K_tau = 0.90 N m/A, K_B = 0.90 V s/rad, G = 9.81 m/s^2);
the neural-network backstepping literature uses this plant with these values as its classic
strict-feedback benchmark of order three. They give M = 0.0642, N = 2.28, B = 0.0181.

In the states x1 = q, x2 = q', x3 = I and with the input V = uf (the actuator's output), this is the
paper's system (1) with n = 3, no unmodeled dynamics and y = x1:

    x1' = x2
    x2' = (x3 - B x2 - N sin x1) / M          g2 = 1 / M = 15.6
    x3' = (uf - R x3 - K_B x2) / L            g3 = 1 / L = 40

so its input gains are g1 = 1, g2 = 1/M, g3 = 1/L: b_m = 1 and b_M = 1/L = 40 (Assumption 3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from controller.fmath import sin

from .checks import bound_problems, finite_problems
from .plants import RightHandSide, State

__all__ = [
    "STATE_NAMES",
    "ManipulatorParameters",
    "input_gains",
    "manipulator_constants",
    "manipulator_problems",
    "manipulator_rhs",
    "manipulator_rhs_for",
]

STATE_NAMES = ("x1", "x2", "x3")  # link angle, link velocity, motor current


@dataclass(frozen=True)
class ManipulatorParameters:
    """The link, load and motor of Dawson, Carroll and Schneider (1994), with their values."""

    J: float = 1.625e-3  # rotor inertia, kg m^2
    m: float = 0.506  # link mass, kg
    L0: float = 0.305  # link length, m
    M0: float = 0.434  # load mass, kg
    R0: float = 0.023  # load radius, m
    B0: float = 16.25e-3  # viscous friction at the joint, N m s/rad
    L: float = 25.0e-3  # armature inductance, H
    R: float = 5.0  # armature resistance, Ohm
    K_tau: float = 0.90  # torque constant, N m/A
    K_B: float = 0.90  # back-emf constant, V s/rad
    G: float = 9.81  # gravitational acceleration, m/s^2


def manipulator_constants(p: ManipulatorParameters) -> tuple[float, float, float]:
    """(M, N, B) of the paper's model: inertia, gravity and friction coefficients per unit current."""
    k = p.K_tau
    inertia = (p.J / k + p.m * p.L0 * p.L0 / (3.0 * k) + p.M0 * p.L0 * p.L0 / k
               + 2.0 * p.M0 * p.R0 * p.R0 / (5.0 * k))
    gravity = p.m * p.L0 * p.G / (2.0 * k) + p.M0 * p.L0 * p.G / k
    return inertia, gravity, p.B0 / k


def input_gains(p: ManipulatorParameters) -> tuple[float, float, float]:
    """g1, g2, g3 of the paper's system (1): 1, 1/M, 1/L."""
    inertia, _, _ = manipulator_constants(p)
    return 1.0, 1.0 / inertia, 1.0 / p.L


def manipulator_rhs(t: float, state: Sequence[float], uf: float, p: ManipulatorParameters) -> State:
    """x' for the states (q, q', I) and the voltage uf."""
    return manipulator_rhs_for(p)(t, state, uf)


def manipulator_rhs_for(p: ManipulatorParameters) -> RightHandSide:
    """:func:`manipulator_rhs` with the constants bound (the FMU's hot path; the compiled step in
    ``_dopri.c`` evaluates the same expressions)."""
    inertia, gravity, friction = manipulator_constants(p)
    inductance, resistance, back_emf = p.L, p.R, p.K_B

    def rhs(t: float, state: Sequence[float], uf: float) -> State:
        x1, x2, x3 = state
        return (
            x2,
            (x3 - friction * x2 - gravity * sin(x1)) / inertia,
            (uf - resistance * x3 - back_emf * x2) / inductance,
        )

    return rhs


def manipulator_problems(p: ManipulatorParameters) -> list[str]:
    """Violated constraints (empty if valid): the masses, lengths, inertia, inductance, resistance and
    torque constant positive; friction, load radius and back-emf non-negative; G finite."""
    problems = bound_problems(p, ("J", "m", "L0", "L", "R", "K_tau"), strict=True)
    problems += bound_problems(p, ("M0", "R0", "B0", "K_B"), strict=False)
    problems += finite_problems(p, ("G",))
    if not problems:  # the derived constants finite, M > 0 (extreme values could overflow or underflow)
        values = manipulator_constants(p)
        if not (all(math.isfinite(v) for v in values) and values[0] > 0.0):
            problems.append(f"the derived M, N, B must be finite and M > 0 (got {values})")
    return problems


