# SPDX-License-Identifier: BSD-2-Clause
"""What every plant FMU shares: three states (x1, x2 and z, or the plant's own third) in
``slave.state``, advanced over a
communication step with the input held, by the integrator the parameter ``method`` selects
(:data:`~fmu_src.models.plants.DOPRI`: Dormand-Prince 5(4) with ``rtol``/``atol``, the default;
:data:`~fmu_src.models.plants.RK4`: fixed sub-steps of at most ``max_step``). Functions, not a
base class (see :mod:`fmu_src.fmu_support`); the slave keeps only plain values so that state
snapshots are cheap deep copies.

In a built FMU the shim steps a plant and refreshes its outputs in C (:func:`compiled_plant_calls`,
``_dopri.step_slave`` and ``_dopri.refresh_slave``): the usual path of :func:`step_plant` and
:func:`refresh_plant_outputs` on the same ``__dict__`` entries, with no interpreter frame; every
other path (RK4, a rejected step, an error, initialization) is these Python functions'."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from functools import partial
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave

from .fmu_support import assigned, declare, mark_stale, report
from .models.native import COMPILED, NativePlant, compiled_module, native_hold_step
from .models.plants import (
    DOPRI,
    MAX_STEPS,
    RATE_HORIZON,
    RK4,
    STATE_LIMIT,
    Y_LIMIT,
    RightHandSide,
    State,
    dopri_hold_step,
    hold_step,
    integration_problems,
)

__all__ = [
    "DEFAULT_ATOL",
    "compiled_plant_calls",
    "DEFAULT_MAX_STEP",
    "DEFAULT_RTOL",
    "declare_integrator",
    "declare_plant_outputs",
    "plant_problems",
    "refresh_plant_outputs",
    "resolved_method",
    "start_plant",
    "step_plant",
]

# RK4 sub-step bound (40 sub-steps per 1 ms communication step). With the paper's huge initial
# controls (|uf| ~ 770 for Example 1, ~15000 for the pendulum in the first ms) the states stay
# within 3e-8 of solve_ivp (rtol 1e-10) over 30 s at h = 1 ms; 5e-5 gives 4e-7, 1e-4 gives 7e-6
# (tests/test_fmu_plants.py). One doStep costs about 70 us.
DEFAULT_MAX_STEP = 2.5e-5
# Dormand-Prince tolerances: over the 30 s of tests/test_fmu_plants.py within 1.3e-9 (Example 1)
# and 2.6e-10 (pendulum) of solve_ivp, where the RK4 above gives 2.5e-8 and 6.9e-10. In the
# closed loops one accepted step (7 evaluations) per communication step after the stiff first
# 50 ms; one doStep costs about 2.5 us compiled (native.py), 9 us in Python.
DEFAULT_RTOL = 1e-10
DEFAULT_ATOL = 1e-12


def declare_plant_outputs(
    slave: Fmi2Slave,
    x1_unit: str | None,
    x2_unit: str | None,
    third: tuple[str, str, str | None] = ("z", "Unmodeled dynamics z", None),
    labels: tuple[str, str] = ("Plant state x1", "Plant state x2"),
) -> None:
    """Register x1, x2, the third state (``third``: name, description, unit; the examples' z) and
    y = x1; none depends directly on the input uf. Their initial values are the parameters
    ``<name>_0``."""
    out = Fmi2Causality.output
    name, description, unit = third
    slave._states = ("x1", "x2", name)
    for state in (*slave._states, "y"):
        setattr(slave, state, 0.0)  # written by refresh_plant_outputs
    declare(slave, "x1", out, labels[0], unit=x1_unit, depends_on=())
    declare(slave, "x2", out, labels[1], unit=x2_unit, depends_on=())
    declare(slave, name, out, description, unit=unit, depends_on=())
    declare(slave, "y", out, "Plant output y = x1", unit=x1_unit, depends_on=())


def declare_integrator(slave: Fmi2Slave) -> None:
    """Register ``max_step`` and, after every other variable (value references are a contract),
    ``method``, ``rtol`` and ``atol``, then the fail-fast bounds ``state_limit``, ``max_steps``,
    ``y_limit`` and ``rate_horizon``, with their defaults."""
    parameter = Fmi2Causality.parameter
    slave.max_step = DEFAULT_MAX_STEP
    slave.method = DOPRI
    slave.rtol = DEFAULT_RTOL
    slave.atol = DEFAULT_ATOL
    slave.state_limit = STATE_LIMIT
    slave.max_steps = MAX_STEPS
    slave.y_limit = Y_LIMIT
    slave.rate_horizon = RATE_HORIZON
    slave.state = None
    slave._method = DOPRI  # resolved at exit_initialization_mode
    slave._next_step = 0.0  # Dormand-Prince step size carried to the next communication step
    declare(
        slave,
        "max_step",
        parameter,
        "Largest RK4 sub-step inside a communication step (method 1)",
        unit="s",
        minimum=0.0,
    )
    declare(
        slave,
        "method",
        parameter,
        "Integrator: 0 = Dormand-Prince 5(4) with error control (rtol, atol), 1 = RK4 with sub-steps of "
        "at most max_step; if only max_step is set, 1",
        integer=True,
        minimum=0,
        maximum=1,
    )
    declare(
        slave, "rtol", parameter, "Relative tolerance of the local error (method 0)", minimum=0.0, maximum=1.0
    )
    declare(slave, "atol", parameter, "Absolute tolerance of the local error (method 0)", minimum=0.0)
    declare(
        slave,
        "state_limit",
        parameter,
        "Range of validity: a state of magnitude above it ends the step with fmi2Discard (fail fast)",
        minimum=0.0,
    )
    declare(
        slave,
        "max_steps",
        parameter,
        "Step budget of the integrator per communication step (method 0, accepted and rejected): "
        "spent, fmi2Discard",
        integer=True,
        minimum=1,
    )
    declare(
        slave,
        "y_limit",
        parameter,
        "Range of validity of the output y = x1: |x1| above it ends the step with fmi2Discard "
        "(fail fast on a finite escape)",
        minimum=0.0,
    )
    declare(
        slave,
        "rate_horizon",
        parameter,
        "Rate bound, in communication steps h: a state that its derivative would carry beyond its bound "
        "(x1: y_limit, x2 and z: state_limit) within rate_horizon * h (|x + dx/dt * rate_horizon * h| above "
        "it, at the step's start or at an accepted point inside it) ends the step with fmi2Discard "
        "(fail fast on a held input that drives the state out of range); 0: no rate bound",
        minimum=0.0,
    )


def resolved_method(slave: Fmi2Slave) -> int:
    """The integrator to use: ``method`` if the importer set it; otherwise RK4 if it set
    ``max_step`` (what setting max_step meant before ``method`` existed), else Dormand-Prince."""
    names = assigned(slave)
    if "method" not in names and "max_step" in names:
        return RK4
    return slave.method


def plant_problems(slave: Fmi2Slave) -> list[str]:
    """Violated constraints of the initial states and integrator parameters (empty if valid)."""
    initial = {f"{name}_0": getattr(slave, f"{name}_0") for name in slave._states}
    problems = integration_problems(initial, slave.max_step)
    if slave.method not in (DOPRI, RK4):
        problems.append(f"method must be {DOPRI} (Dormand-Prince) or {RK4} (RK4) (got {slave.method!r})")
    if not 0.0 < slave.rtol < 1.0:
        problems.append(f"rtol must satisfy 0 < rtol < 1 (got {slave.rtol!r})")
    if not (math.isfinite(slave.atol) and slave.atol > 0.0):
        problems.append(f"atol must satisfy atol > 0 (got {slave.atol!r})")
    if not slave.state_limit > 0.0:  # +inf: no limit
        problems.append(f"state_limit must satisfy state_limit > 0 (got {slave.state_limit!r})")
    if slave.max_steps < 1:
        problems.append(f"max_steps must satisfy max_steps >= 1 (got {slave.max_steps!r})")
    if not slave.y_limit > 0.0:  # +inf: no limit
        problems.append(f"y_limit must satisfy y_limit > 0 (got {slave.y_limit!r})")
    elif not abs(slave.x1_0) <= slave.y_limit:
        problems.append(f"x1_0 must satisfy |x1_0| <= y_limit = {slave.y_limit!r} (got {slave.x1_0!r})")
    if not (math.isfinite(slave.rate_horizon) and slave.rate_horizon >= 0.0):
        problems.append(f"rate_horizon must satisfy rate_horizon >= 0, finite (got {slave.rate_horizon!r})")
    return problems


def start_plant(slave: Fmi2Slave) -> None:
    """Leave initialization: the initial states, the integrator chosen, no step size carried yet."""
    slave.state = _initial(slave)
    slave._method = resolved_method(slave)
    slave._next_step = 0.0
    mark_stale(slave)


def _initial(slave: Fmi2Slave) -> State:
    x1, x2, x3 = (getattr(slave, f"{name}_0") for name in slave._states)
    return x1, x2, x3


def refresh_plant_outputs(slave: Fmi2Slave) -> None:
    """The outputs: the states now (the initial-value parameters until initialization has finished)."""
    d = slave.__dict__
    state = d["state"] if d["state"] is not None else _initial(slave)
    first, second, third = d["_states"]
    d[first] = d["y"] = state[0]
    d[second] = state[1]
    d[third] = state[2]


def step_plant(
    slave: Fmi2Slave, rhs: RightHandSide, native: NativePlant, current_time: float, step_size: float
) -> bool:
    """Advance over [t, t + h] with ``slave.uf`` held: by Dormand-Prince, compiled in a built FMU
    (``native``, :mod:`~fmu_src.models.native`: the same bits) and in Python (``rhs``) in the
    source tree; or by RK4 (``rhs``).

    Returns False (fmi2Discard, with a logged reason) if the states stop being finite, leave
    ``state_limit`` (x1: ``y_limit``), change fast enough to leave it within ``rate_horizon``
    communication steps, or the integrator spends its ``max_steps`` (the states of the last good
    step stay).
    """
    new: State
    limit = slave.state_limit
    try:
        if slave._method == DOPRI and COMPILED:
            new, slave._next_step, _, _ = native_hold_step(
                native, current_time, slave.state, slave.uf, step_size, slave.rtol, slave.atol,
                slave._next_step, limit, slave.max_steps, slave.y_limit, slave.rate_horizon,
            )
        elif slave._method == DOPRI:
            new, slave._next_step, _, _ = dopri_hold_step(
                rhs, current_time, slave.state, slave.uf, step_size, slave.rtol, slave.atol, slave._next_step,
                limit, slave.max_steps, slave.y_limit, slave.rate_horizon, native.names,
            )
        else:
            new = hold_step(
                rhs, current_time, slave.state, slave.uf, step_size, slave.max_step,
                limit, slave.y_limit, slave.rate_horizon, native.names,
            )
    except (ValueError, OverflowError) as error:  # overflow, state limit, step budget
        report(
            slave,
            f"{error}; step to t = {current_time + step_size!r} with uf = {slave.uf!r}; "
            "step rejected (fmi2Discard)",
        )
        return False
    y_limit = slave.y_limit
    if not (abs(new[0]) <= min(limit, y_limit) and abs(new[1]) <= limit and abs(new[2]) <= limit):  # nan too
        finite = all(map(math.isfinite, new))
        bound = f"y_limit {y_limit:g}" if abs(new[0]) > y_limit else f"state_limit {limit:g}"
        problem = f"state beyond {bound}" if finite else "non-finite state"
        report(
            slave,
            f"{problem} {new} at t = {current_time + step_size!r} "
            f"with uf = {slave.uf!r}; step rejected (fmi2Discard)",
        )
        return False
    slave.state = new  # the outputs are stale now (fmu_model marks them after every step)
    return True


# The __dict__ entries _dopri.step_slave and refresh_slave read and write, in the binding's order
# (_dopri.c: B_STATE ... B_Y; "_native" is the slave's NativePlant).
_BOUND_KEYS = ("state", "uf", "rtol", "atol", "_next_step", "state_limit", "max_steps", "y_limit",
               "rate_horizon", "_method", "_native", "_states", "y")


def compiled_plant_calls(
    slave: Fmi2Slave, step: Callable[[float, float], bool], refresh: Callable[[], None]
) -> tuple[Callable[[float, float], bool], Callable[[], None], Any, tuple[Any, ...]] | None:
    """The plant's ``compiled_calls`` (:func:`~fmu_src.fmu_support.fmu_model`): ``do_step`` and
    ``refresh_outputs`` in C for the shim, ``_dopri.step_slave`` and ``_dopri.refresh_slave`` bound
    to the slave's ``__dict__``, its two Python methods (``step``, ``refresh``: every path but the
    usual one, so that messages and statuses stay theirs) and the interned keys; None where
    nothing is compiled (the source tree). The slave's ``_native`` is its NativePlant. Then
    ``_dopri.direct_calls`` and the binding: the same two as C entries the shim calls with no Python
    call between (``controller/direct_calls.h``).

    Why: the Python frames around the compiled integrator cost about ten times what it does in a
    communication step (some 24,000 instructions against 2,500); the state stays in the
    ``__dict__``, so snapshots and every other path see what the Python step would have left."""
    compiled = compiled_module()
    if compiled is None:
        return None
    binding = (slave.__dict__, step, refresh, DOPRI, NativePlant, *map(sys.intern, _BOUND_KEYS))
    return (partial(compiled.step_slave, binding), partial(compiled.refresh_slave, binding),
            compiled.direct_calls, binding)
