# SPDX-License-Identifier: BSD-2-Clause
"""The plants' Dormand-Prince step compiled (``_dopri.c`` beside this module): the same
algorithm as :func:`~fmu_src.models.plants.dopri_hold_step`, giving the same bits, the same
exceptions and messages, about 11 times faster (0.36 us per integrator step of Example 1
against 3.9 us, replaying a finite escape of 174 416 steps).

``_dopri`` also steps a plant FMU's slave and refreshes its outputs for the FMU's shim with no
Python frame (``step_slave``, ``refresh_slave``: see :func:`fmu_src.plant_core.compiled_plant_calls`).

The FMU build (:mod:`fmu_src.toolchain.build`) compiles ``_dopri.c`` into every plant FMU, so an FMU always
steps with it (``tests/test_plant_native.py`` checks that the built FMUs load it; an FMU that
cannot load it fails to instantiate rather than step slower). In the source tree, where nothing
is compiled, :data:`COMPILED` is False and the plants use the Python reference, which the tests
compare the compiled step against.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import NamedTuple

from .manipulator import STATE_NAMES as MANIPULATOR_STATES
from .manipulator import ManipulatorParameters, manipulator_constants
from .plants import (
    STATE_NAMES,
    AdaptiveStep,
    PendulumParameters,
    StateLimitError,
    beyond_limit,
    budget_spent,
    escape_rate,
    no_step_size,
)

try:
    from . import _dopri  # type: ignore[attr-defined]  # compiled by the FMU build
except ImportError:
    if __name__.startswith("_ftc_"):  # bundled in an FMU (fmu_src/toolchain/build.py names the package so)
        raise  # a built plant FMU carries it: without it the build is broken, not slower
    _dopri = None  # the source tree: the Python reference steps

__all__ = ["COMPILED", "EXAMPLE1", "NativePlant", "compiled_module", "manipulator_native", "native_hold_step",
           "pendulum_native"]

COMPILED = _dopri is not None
# Status codes of _dopri.hold_step (see _dopri.c).
_OK, _RATE, _BEYOND, _BUDGET, _NO_STEP, _DOMAIN = range(6)


class NativePlant(NamedTuple):
    """A plant as the compiled step knows it: ``kind`` (0: Example 1, 1: the pendulum, 2: the
    manipulator) and six constants (the pendulum's d1, d2, M L and g / L + B / M; the manipulator's
    M, N, B, L, R, K_B; unused ones zero), and the names of its three states (for the messages)."""

    kind: int
    constants: tuple[float, float, float, float, float, float]
    names: tuple[str, str, str] = STATE_NAMES


EXAMPLE1 = NativePlant(0, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))


def pendulum_native(p: PendulumParameters) -> NativePlant:
    """The pendulum with the constants bound as :func:`~fmu_src.models.plants.pendulum_rhs_for`
    computes them (the same operations, so the same values)."""
    return NativePlant(1, (p.d1, p.d2, p.M * p.L, p.g / p.L + p.B / p.M, 0.0, 0.0))


def manipulator_native(p: ManipulatorParameters) -> NativePlant:
    """The manipulator with the constants bound as
    :func:`~fmu_src.models.manipulator.manipulator_rhs_for` computes them."""
    inertia, gravity, friction = manipulator_constants(p)
    return NativePlant(2, (inertia, gravity, friction, p.L, p.R, p.K_B), MANIPULATOR_STATES)


def compiled_module() -> ModuleType | None:
    """The compiled ``_dopri`` if :data:`COMPILED`, else None (looked up at every call: the tests
    put a compiled one in the source tree's place)."""
    return _dopri if COMPILED else None


def native_hold_step(
    plant: NativePlant,
    t: float,
    state: Sequence[float],
    uf: float,
    h: float,
    rtol: float,
    atol: float,
    first_step: float,
    limit: float,
    max_steps: int,
    y_limit: float,
    rate_horizon: float,
) -> AdaptiveStep:
    """:func:`~fmu_src.models.plants.dopri_hold_step` for ``plant``, compiled: the same result
    and the same exceptions (requires :data:`COMPILED`)."""
    if _dopri is None:
        raise RuntimeError("the compiled integrator _dopri is not built (it is built into the plant FMUs)")
    status, at, a, b, c, next_step, accepted, rejected, *rate = _dopri.hold_step(
        plant.kind, *plant.constants, t, *state, uf, h, rtol, atol, first_step, limit, max_steps, y_limit,
        rate_horizon,
    )
    if status == _OK:
        return AdaptiveStep((a, b, c), next_step, accepted, rejected)
    if status == _RATE:
        raise StateLimitError(escape_rate((a, b, c), rate, at, rate_horizon * h, limit, y_limit, plant.names))
    if status == _BEYOND:
        raise beyond_limit((a, b, c), at, limit, y_limit)
    if status == _BUDGET:
        raise budget_spent(max_steps, at, accepted, rejected)
    if status == _NO_STEP:
        raise no_step_size(rtol, atol, at, accepted, rejected)
    assert status == _DOMAIN, status
    raise ValueError("math domain error")  # what math.sin says of an infinite argument
