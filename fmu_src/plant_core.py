"""What every plant FMU shares: states (x1, x2, z) in ``slave.state``, advanced over a
communication step with the input held by :func:`fmu_src.models.plants.hold_step` (RK4 with sub-steps
of at most ``slave.max_step``). Functions, not a base class (see :mod:`fmu_src.fmu_support`);
the slave keeps only plain values so that state snapshots are cheap deep copies."""

from __future__ import annotations

import math
from collections.abc import Callable

from pythonfmu import Fmi2Causality, Fmi2Slave

from .fmu_support import declare, report
from .models.plants import RightHandSide, State, hold_step

__all__ = ["DEFAULT_MAX_STEP", "current_state", "declare_plant_outputs", "step_plant"]

# RK4 sub-step bound (40 sub-steps per 1 ms communication step). With the paper's huge initial
# controls (|uf| ~ 770 for Example 1, ~15000 for the pendulum in the first ms) the states stay
# within 3e-8 of solve_ivp (rtol 1e-10) over 30 s at h = 1 ms; 5e-5 gives 4e-7, 1e-4 gives 7e-6
# (tests/test_fmu_plants.py). One doStep costs about 70 us.
DEFAULT_MAX_STEP = 2.5e-5


def current_state(slave: Fmi2Slave) -> State:
    """The states now: the initial-value parameters until initialization has finished."""
    return slave.state if slave.state is not None else (slave.x1_0, slave.x2_0, slave.z_0)


def declare_plant_outputs(slave: Fmi2Slave, x1_unit: str | None, x2_unit: str | None) -> None:
    """Register x1, x2, z and y = x1; none depends directly on the input uf."""
    out = Fmi2Causality.output

    def state_getter(i: int) -> Callable[[], float]:
        return lambda: current_state(slave)[i]

    declare(slave, "x1", out, "Plant state x1", unit=x1_unit, depends_on=(), getter=state_getter(0))
    declare(slave, "x2", out, "Plant state x2", unit=x2_unit, depends_on=(), getter=state_getter(1))
    declare(slave, "z", out, "Unmodeled dynamics z", depends_on=(), getter=state_getter(2))
    declare(slave, "y", out, "Plant output y = x1", unit=x1_unit, depends_on=(), getter=state_getter(0))


def step_plant(slave: Fmi2Slave, rhs: RightHandSide, current_time: float, step_size: float) -> bool:
    """Advance over [t, t + h] with ``slave.uf`` held.

    Returns False (fmi2Discard, with a logged reason) if the states stop being finite.
    """
    try:
        new = hold_step(rhs, current_time, current_state(slave), slave.uf, step_size, slave.max_step)
    except (ValueError, OverflowError) as error:  # math functions of an overflowed state
        new = (math.nan,) * 3
        reason = str(error)
    else:
        reason = "non-finite state"
    if not all(math.isfinite(value) for value in new):
        report(
            slave,
            f"{reason} {new} at t = {current_time + step_size!r} "
            f"with uf = {slave.uf!r}; step rejected (fmi2Discard)",
        )
        return False
    slave.state = new
    return True
