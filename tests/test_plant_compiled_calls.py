# SPDX-License-Identifier: BSD-2-Clause
"""The plants' do_step and refresh_outputs in C (fmu_src/models/_dopri.c step_slave and
refresh_slave, bound by fmu_src.plant_core.compiled_plant_calls), which the FMU's shim calls,
against the Python methods on a twin slave in this process: the same result, the same bits of
every ``__dict__`` entry and the same messages after every call, on the usual path (done in C, no
Python frame) and on every other one (RK4, a state beyond its limits, a wrong type, before
initialization: the Python methods', called by the C code)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial
from types import ModuleType
from typing import Any

import pytest
from fmu_helpers import Frames, Real, compiled_extension, handed, outcome, plain, shim_calls

from fmu_src import plant_core
from fmu_src.example1_plant import Example1Plant
from fmu_src.manipulator_plant import ManipulatorPlant
from fmu_src.models import native
from fmu_src.models.plants import RK4
from fmu_src.pendulum_plant import PendulumPlant

PLANTS = {"Example1Plant": Example1Plant, "PendulumPlant": PendulumPlant,
          "ManipulatorPlant": ManipulatorPlant}
H = 1e-3


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """_dopri.c compiled as the FMU build compiles it and made the module the plants step with,
    as in a built FMU (where fmu_src.models.native.COMPILED is true)."""
    module = compiled_extension("fmu_src.models._dopri", tmp_path_factory.mktemp("dopri"))
    patch = pytest.MonkeyPatch()
    patch.setattr(native, "_dopri", module)
    patch.setattr(native, "COMPILED", True)
    patch.setattr(plant_core, "COMPILED", True)
    yield module
    patch.undo()


def started(model: str, **parameters: Any) -> Any:
    """A slave of ``model`` through initialization, ``parameters`` set before it ends."""
    slave = PLANTS[model](instance_name="twin")
    for name, value in parameters.items():
        setattr(slave, name, value)
    slave.exit_initialization_mode()
    return slave


def twins(model: str, **parameters: Any) -> tuple[Any, Any]:
    return started(model, **parameters), started(model, **parameters)


def step_both(fast: Any, slow: Any, t: float, h: float) -> Any:
    """One step and refresh of ``fast`` in C and of ``slow`` in Python: the same outcome and
    entries; returns the outcome."""
    step, refresh = shim_calls(fast)
    a = outcome(step, t, h)
    b = outcome(slow.do_step, t, h)
    assert a == b
    fast.__dict__["_fmu_stale"] = True  # as the shim does after every step
    assert plain(fast) == plain(slow)
    assert outcome(refresh) == outcome(slow.refresh_outputs)  # None, or the Python function's error
    slow.__dict__["_fmu_stale"] = False  # as the shim does after the refresh
    fast.__dict__["_fmu_stale"] = False
    assert plain(fast) == plain(slow)
    return a


def test_the_binding_is_the_compiled_calls(compiled: ModuleType) -> None:
    """fmu_support hands the shim partials of _dopri.step_slave and refresh_slave, bound to the
    slave's own __dict__ and its Python methods; None where nothing is compiled."""
    slave = started("Example1Plant")
    step, refresh, capsule, binding = handed(slave)
    assert isinstance(step, partial) and step.func is compiled.step_slave
    assert isinstance(refresh, partial) and refresh.func is compiled.refresh_slave
    assert step.args == refresh.args == (binding,) and capsule is compiled.direct_calls
    assert binding[0] is slave.__dict__
    assert binding[1].__self__ is slave and binding[2] == slave.refresh_outputs


def test_without_the_compiled_integrator_the_python_methods_stay(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(native, "COMPILED", False)
    slave = started("Example1Plant")
    step, refresh = shim_calls(slave)
    assert refresh == slave.refresh_outputs and step.__func__.__name__ == "do_step"


@pytest.mark.parametrize("model", sorted(PLANTS))
def test_usual_steps_are_the_python_steps_bits_without_a_frame(compiled: ModuleType, model: str) -> None:
    """300 steps under a varying input: the same states, step sizes and outputs to the bit, and
    not one Python frame in the C step and refresh."""
    fast, slow = twins(model)
    step, refresh = shim_calls(fast)
    for k in range(300):
        uf = 300.0 * math.cos(7.0 * k * H) + (50.0 if k == 0 else 0.0)
        fast.uf = slow.uf = uf
        assert step_both(fast, slow, k * H, H) is True
        fast.uf = slow.uf = -uf
        with Frames() as frames:
            assert step(k * H, H) is True
            refresh()
        assert frames.entered == [], k
        assert slow.do_step(k * H, H) is True
        slow.refresh_outputs()
        fast.__dict__["_fmu_stale"] = slow.__dict__["_fmu_stale"] = False
        assert plain(fast) == plain(slow), k


def test_before_initialization_the_python_methods_answer(compiled: ModuleType) -> None:
    """No state yet: the refresh gives the initial-value parameters (the Python function's), the
    step raises what the Python step raises."""
    fast, slow = PLANTS["PendulumPlant"](instance_name="twin"), PLANTS["PendulumPlant"](instance_name="twin")
    fast.x1_0 = slow.x1_0 = 0.25
    step, refresh = shim_calls(fast)
    refresh()
    slow.refresh_outputs()
    assert plain(fast) == plain(slow) and fast.x1 == fast.y == 0.25
    failed = outcome(step, 0.0, H)
    assert failed == outcome(slow.do_step, 0.0, H) and failed[0] == "TypeError"
    assert plain(fast) == plain(slow)


@pytest.mark.parametrize("model", sorted(PLANTS))
def test_rk4_steps_are_the_python_ones(compiled: ModuleType, model: str) -> None:
    """method = RK4: the Python step (called by the C one), the same bits."""
    fast, slow = twins(model, method=RK4)
    with Frames() as frames:
        shim_calls(fast)[0](0.0, H)
    assert "step_plant" in frames.entered
    fast, slow = twins(model, method=RK4)
    for k in range(20):
        fast.uf = slow.uf = 10.0 * k
        assert step_both(fast, slow, k * H, H) is True


@pytest.mark.parametrize(
    ("parameters", "uf", "reason"),
    [
        ({"state_limit": 0.6, "rate_horizon": 0.0}, 1000.0, "state_limit"),  # the step's own check
        ({"y_limit": 0.52, "rate_horizon": 0.0}, 1e5, "y_limit"),
        ({"state_limit": 0.6}, 1000.0, "state_limit"),  # the rate bound
        ({}, 1e300, "rate_horizon"),
        ({"state_limit": math.inf, "y_limit": math.inf, "rate_horizon": 0.0}, 1e150, "no step size"),
        ({"max_steps": 2}, 1e5, "step budget"),
    ],
)
def test_rejected_steps_are_the_python_ones(compiled: ModuleType, parameters: dict[str, Any], uf: float,
                                           reason: str) -> None:
    """A step rejected (fmi2Discard): the same False, the same message, the state of the last good
    step left, in C as in Python."""
    fast, slow = twins("Example1Plant", **parameters)
    assert step_both(fast, slow, 0.0, H) is True
    fast.uf = slow.uf = uf
    assert step_both(fast, slow, H, H) is False
    assert "step rejected (fmi2Discard)" in str(fast.log_queue[-1])
    assert reason in str(fast.log_queue[-1])


@pytest.mark.parametrize(
    ("name", "value"),
    [("uf", "1.0"), ("max_steps", 2.5e6), ("state", [0.5, 0.5, 0.0]), ("state", (0.5, 0.5)), ("rtol", None),
     ("state_limit", 10**6), ("y_limit", 10**30 + 1), ("_method", 0.0), ("_native", (0, (0.0,) * 6)),
     ("_next_step", "0.001"), ("uf", 10**400), ("state_limit", math.nan), ("uf", Real(5.0)),
     ("_method", Real(0.0)), ("max_steps", True), ("state", (0.5, Real(0.5), 0.0))],
)
def test_other_values_take_the_python_path(compiled: ModuleType, name: str, value: Any) -> None:
    """An entry of another type than the FMU's own (a list, an int, a string, a shorter state, a
    float subclass) or a nan limit: the Python step, whatever it makes of it (a result, an
    exception, a rejection)."""
    fast, slow = twins("Example1Plant")
    fast.uf = slow.uf = 5.0
    step_both(fast, slow, 0.0, H)
    fast.__dict__[name] = value
    slow.__dict__[name] = value
    snapshot, queued = dict(fast.__dict__), list(fast.log_queue)
    with Frames() as frames:
        outcome(shim_calls(fast)[0], H, H)
    assert "step_plant" in frames.entered
    fast.__dict__.clear()  # and again, compared with the Python step
    fast.__dict__.update(snapshot)
    fast.log_queue[:] = queued
    step_both(fast, slow, H, H)


def test_a_nan_y_limit_is_no_limit_in_c_as_in_python(compiled: ModuleType) -> None:
    """min(state_limit, nan) is state_limit in Python: the C step's check of the new state too."""
    fast, slow = twins("Example1Plant")
    fast.y_limit = slow.y_limit = math.nan
    assert step_both(fast, slow, 0.0, H) is True


def test_a_deleted_entry_takes_the_python_path(compiled: ModuleType) -> None:
    fast, slow = twins("PendulumPlant")
    del fast.__dict__["rate_horizon"], slow.__dict__["rate_horizon"]
    assert outcome(shim_calls(fast)[0], 0.0, H) == outcome(slow.do_step, 0.0, H)
    assert plain(fast) == plain(slow)


def test_a_bad_binding_is_refused(compiled: ModuleType) -> None:
    with pytest.raises(TypeError, match="not a plant binding"):
        compiled.step_slave((), 0.0, H)
    with pytest.raises(TypeError, match="not a plant binding"):
        compiled.refresh_slave(None)
