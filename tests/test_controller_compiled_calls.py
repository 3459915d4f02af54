# SPDX-License-Identifier: BSD-2-Clause
"""The controller FMUs' do_step and refresh_outputs in C (controller/_law.c step_slave and
refresh_slave, bound by fmu_src.controller_core.compiled_controller_calls), which the FMU's shim
calls, against the Python functions on a twin slave in this process: the same result, the same bits
of every ``__dict__`` entry and the same messages after every call, on the usual path (done in C, no
Python frame) and on every other one (before initialization, the semi-implicit law's step-size
warning, a non-finite state, a value of another type: the Python functions', called by the C
code)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial
from types import ModuleType
from typing import Any

import pytest
from fmu_helpers import Frames, Real, compiled_extension, handed, outcome, plain, shim_calls

from controller import native
from fmu_src.fixed_time_controller import FixedTimeController
from fmu_src.fixed_time_controller1 import FixedTimeController1
from fmu_src.fixed_time_controller3 import FixedTimeController3
from fmu_src.fixed_time_controller4 import FixedTimeController4

ORDERS = {1: FixedTimeController1, 2: FixedTimeController, 3: FixedTimeController3, 4: FixedTimeController4}
H = 1e-3


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """_law.c compiled as the FMU build compiles it and made the module the controllers step with,
    as in a built FMU (where controller.native.COMPILED is true)."""
    module = compiled_extension("controller._law", tmp_path_factory.mktemp("law"))
    patch = pytest.MonkeyPatch()
    patch.setattr(native, "_law", module)
    patch.setattr(native, "COMPILED", True)
    yield module
    patch.undo()


def started(n: int, **parameters: Any) -> Any:
    """A controller of order ``n`` through initialization, ``parameters`` set before it ends."""
    slave = ORDERS[n](instance_name="twin")
    for name, value in parameters.items():
        setattr(slave, name, value)
    slave.exit_initialization_mode()
    return slave


def set_inputs(slaves: tuple[Any, ...], k: int, n: int) -> None:
    """Step k's inputs, a closed loop's size (x near yd = 0.5 sin t), as the shim sets them: the
    outputs are stale after (they depend on the inputs directly)."""
    t = k * H
    for slave in slaves:
        for i in range(1, n + 1):
            setattr(slave, f"x{i}", 0.5 * math.sin(t + 0.3 * i) + 0.01 * i)
        slave.yd, slave.yd_dot = 0.5 * math.sin(t), 0.5 * math.cos(t)
        for name in ("yd_ddot", "yd_dddot", "yd_ddddot")[: n - 1]:
            setattr(slave, name, -0.5 * math.sin(t))
        slave.__dict__["_fmu_stale"] = True


def refresh_both(fast: Any, slow: Any) -> None:
    """The refresh in C and in Python: the same outcome and entries; the outputs then current."""
    assert outcome(shim_calls(fast)[1]) == outcome(slow.refresh_outputs)
    fast.__dict__["_fmu_stale"] = slow.__dict__["_fmu_stale"] = False  # as the shim does
    assert plain(fast) == plain(slow)


def step_both(fast: Any, slow: Any, t: float, h: float) -> Any:
    """One step of ``fast`` in C and of ``slow`` in Python: the same outcome and entries."""
    result = outcome(shim_calls(fast)[0], t, h)
    assert result == outcome(slow.do_step, t, h)
    fast.__dict__["_fmu_stale"] = True  # as the shim does after every step
    assert plain(fast) == plain(slow)
    return result


def test_the_binding_is_the_compiled_calls(compiled: ModuleType) -> None:
    """fmu_support hands the shim partials of _law.step_slave and refresh_slave, bound to the slave's
    own __dict__ and its Python functions; the Python functions where nothing is compiled."""
    slave = started(2)
    step, refresh, capsule, binding = handed(slave)
    assert isinstance(step, partial) and step.func is compiled.step_slave
    assert isinstance(refresh, partial) and refresh.func is compiled.refresh_slave
    assert step.args == refresh.args == (binding,) and binding[0] is slave.__dict__
    assert capsule is compiled.direct_calls
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(native, "_law", None)
        step, refresh, capsule, binding = handed(slave)
    assert step.__func__.__name__ == "step_controller" and refresh == slave.refresh_outputs
    assert capsule is binding is None


@pytest.mark.parametrize("n", sorted(ORDERS))
@pytest.mark.parametrize("parameters", [{}, {"mode": 1, "k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0},
                                        {"substeps": 3}, {"nn_term": 0}])
def test_usual_steps_are_the_python_steps_bits_without_a_frame(compiled: ModuleType, n: int,
                                                                parameters: dict[str, Any]) -> None:
    """200 steps, the outputs read before two of three (the step then starts from their stage): the
    same states, stage and outputs to the bit, and not one Python frame in the C calls."""
    fast, slow = started(n, **parameters), started(n, **parameters)
    step, refresh = shim_calls(fast)
    for k in range(200):
        set_inputs((fast, slow), k, n)
        if k % 3:
            with Frames() as frames:
                refresh()
            assert frames.entered == [], k
            slow.refresh_outputs()
            fast.__dict__["_fmu_stale"] = slow.__dict__["_fmu_stale"] = False
            assert plain(fast) == plain(slow), k
        with Frames() as frames:
            assert step(k * H, H) is True
        assert frames.entered == [], k
        assert slow.do_step(k * H, H) is True
        fast.__dict__["_fmu_stale"] = True
        assert plain(fast) == plain(slow), k


def test_before_initialization_the_python_functions_answer(compiled: ModuleType) -> None:
    """No law yet: the refresh validates the parameters set so far (the Python function's outputs),
    the step fails as the Python step fails."""
    fast, slow = FixedTimeController(instance_name="twin"), FixedTimeController(instance_name="twin")
    fast.r0 = slow.r0 = 0.25
    refresh_both(fast, slow)
    assert fast.r == 0.25
    assert step_both(fast, slow, 0.0, H)[0] == "AssertionError"


def test_the_semi_implicit_law_warns_once_in_c_as_in_python(compiled: ModuleType) -> None:
    """discretization 1: steps of the sample time in C; another step size warns once (the Python
    step's message), and the steps after are the C ones again, the same bits."""
    fast, slow = started(2, discretization=1), started(2, discretization=1)
    for k, h in enumerate((H, H, 2 * H, 2 * H, H)):
        set_inputs((fast, slow), k, 2)
        refresh_both(fast, slow)
        step = shim_calls(fast)[0]
        with Frames() as frames:
            assert outcome(step, k * H, h) is True
        assert ("_check_step" in frames.entered) == ("step_controller" in frames.entered) == (k == 2), k
        assert slow.do_step(k * H, h) is True
        fast.__dict__["_fmu_stale"] = True
        assert plain(fast) == plain(slow), k
    assert sum("differs from sample_time" in str(m) for m in fast.log_queue) == 1


def test_a_non_finite_state_is_rejected_by_the_python_step(compiled: ModuleType) -> None:
    """A nan input makes the state nan: the step is the Python one's, False with its message, the
    state of the last good step left."""
    fast, slow = started(2), started(2)
    set_inputs((fast, slow), 0, 2)
    assert step_both(fast, slow, 0.0, H) is True
    fast.x1 = slow.x1 = math.nan
    assert step_both(fast, slow, H, H) is False
    assert "non-finite state" in str(fast.log_queue[-1])


@pytest.mark.parametrize(("name", "value"), [
    ("x1", 1), ("x1", Real(0.5)), ("yd", "0.5"), ("_state", [0.0, 0.0, 0.0]), ("_state", (0.0, 0.0)),
    ("_state", (0.0, Real(0.0), 0.0)), ("_stage", None), ("_stage", (0.0,) * 3), ("_fmu_stale", 0),
    ("_step_unchecked", 1), ("_law", None), ("_law", object()),
])
def test_other_values_take_the_python_path(compiled: ModuleType, name: str, value: Any) -> None:
    """An entry of another type than the FMU's own (an int, a float subclass, a string, a list, a
    shorter state or stage, a law of another kind): the Python functions, whatever they make of it
    (a result or an exception), the same entries after."""
    fast, slow = started(2), started(2)
    set_inputs((fast, slow), 0, 2)
    refresh_both(fast, slow)
    fast.__dict__[name] = value
    slow.__dict__[name] = value
    with Frames() as frames:
        outcome(shim_calls(fast)[0], 0.0, H)
    assert "step_controller" in frames.entered
    fast2, slow2 = started(2), started(2)
    set_inputs((fast2, slow2), 0, 2)
    refresh_both(fast2, slow2)
    fast2.__dict__[name] = slow2.__dict__[name] = value
    step_both(fast2, slow2, 0.0, H)
    fast3, slow3 = started(2), started(2)
    set_inputs((fast3, slow3), 0, 2)
    fast3.__dict__[name] = slow3.__dict__[name] = value
    assert outcome(shim_calls(fast3)[1]) == outcome(slow3.refresh_outputs)
    assert plain(fast3) == plain(slow3)


def test_a_bad_binding_is_refused(compiled: ModuleType) -> None:
    with pytest.raises(TypeError, match="binding not made by compiled_controller_calls"):
        compiled.step_slave((), 0.0, H)
    with pytest.raises(TypeError, match="binding not made by compiled_controller_calls"):
        compiled.refresh_slave(None)
