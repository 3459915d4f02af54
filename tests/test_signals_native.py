# SPDX-License-Identifier: BSD-2-Clause
"""The Reference and Actuator FMUs' compiled step and refresh (fmu_src/models/_signals.c) against
their Python methods, which stay the oracle: the same bits in every output, the same dict, and on
every other path (parameters not frozen yet, a value that is not a float, an fmath error) the
Python method's own result or exception.

In-process: the extension compiled as the FMU build compiles it, called through the very
partials the classes hand the shim (``compiled_calls``), against a twin slave that runs the Python
methods. Through the built FMUs (fmpy, the shim's direct calls): the binding the shim gets holds
the C functions, and the outputs over a run equal the pure-Python functions' to the bit.
"""

from __future__ import annotations

import gc
import math
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmu_helpers import compiled_extension, handed, shim_calls, unzipped
from test_fmu_direct import Messages, instantiate

from fmu_src.actuator import FAULT_TIME_TOLERANCE, Actuator
from fmu_src.models import signals_native
from fmu_src.models.actuator import ActuatorParameters, actuator_output
from fmu_src.models.reference import ReferenceParameters, reference_derivatives
from fmu_src.reference import Reference

REFERENCE_OUTPUTS = ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")
ACTUATOR_OUTPUTS = ("uf", "u_dz")
REFERENCE_CASES = [  # (amplitude, omega, phase, offset)
    (0.5, 1.0, 0.0, 0.0),
    (1.0, 0.5, 0.3, -0.2),
    (2.5, 7.0, -1.25, 0.75),
    (-0.3, 123.456, 3.0, 1e-3),
    (0.7, 1.3, 0.1, 0.0),
    (1.1, 0.37, -2.2, 0.4),
]
# Saturation at 1.5, the dead-zone's break points, then the three branches (and -0.0, nan).
ACTUATOR_POINTS = [  # (v, x1, x2)
    (2.0, 0.3, -0.4), (1.5, 0.2, 0.1), (0.5, 0.1, 0.2), (0.5 + 1e-9, 0.1, 0.2), (0.5 - 1e-9, 0.1, 0.2),
    (0.0, 1.0, 2.0), (-0.0, 1.0, 2.0), (-0.6, -0.5, 0.7), (-0.6 + 1e-9, -0.5, 0.7),
    (-0.6 - 1e-9, -0.5, 0.7), (-1.2, 2.0, -1.5), (-3.0, 2.0, -1.5), (770.0, 0.5, 0.5),
    (math.nan, 0.5, 0.5), (1.0, math.nan, 0.5), (1.0, 0.5, math.nan),
]
ACTUATOR_PARAMETERS = {"u_max": 1.5, "t_fault": 10.0, "K_rate": 0.7, "L_gain": 1.3, "L_bias": -0.1}


def bits(values: Any) -> list[str]:
    """Floats as their exact hexadecimal form (-0.0 and nan told apart from 0.0 and each other)."""
    return [float(value).hex() for value in values]


def state(slave: Any, names: tuple[str, ...]) -> list[str]:
    return bits(slave.__dict__[name] for name in names)


# ----------------------------------------------------------------------------------------------
# In-process: the compiled functions against the Python methods


@pytest.fixture(scope="module")
def signals(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """_signals.c compiled as the FMU build compiles it, in place of the source tree's missing one."""
    module = compiled_extension("fmu_src.models._signals", tmp_path_factory.mktemp("signals"))
    saved = signals_native._signals
    signals_native._signals = module
    yield module
    signals_native._signals = saved


def made(cls: type, **parameters: float) -> Any:
    """An instance with the parameters set and frozen (exit_initialization_mode)."""
    slave = cls(instance_name="native-test")
    for name, value in parameters.items():
        setattr(slave, name, value)
    slave.exit_initialization_mode()
    return slave


def test_the_binding_holds_the_compiled_functions(signals: ModuleType) -> None:
    for cls, refresh, capsule in ((Reference, signals.reference_refresh, signals.reference_direct_calls),
                                  (Actuator, signals.actuator_refresh, signals.actuator_direct_calls)):
        step_c, refresh_c, entries, binding = handed(made(cls))
        assert isinstance(step_c, partial) and step_c.func is signals.step_slave
        assert isinstance(refresh_c, partial) and refresh_c.func is refresh
        assert entries is capsule and step_c.args == refresh_c.args == (binding,)


def test_no_compiled_calls_without_the_extension(monkeypatch: pytest.MonkeyPatch) -> None:
    """In the source tree (nothing compiled) the shim keeps the Python methods."""
    monkeypatch.setattr(signals_native, "_signals", None)
    slave = made(Reference)
    step, refresh = shim_calls(slave)
    assert not isinstance(step, partial) and step.__self__ is slave
    assert refresh == slave.refresh_outputs


@pytest.mark.parametrize("parameters", REFERENCE_CASES)
def test_reference_same_bits_as_python(signals: ModuleType, parameters: tuple[float, ...]) -> None:
    """Step and refresh over 0.25 .. 40 s in steps of 0.37 s: the same time and outputs, to the bit."""
    named = dict(zip(("amplitude", "omega", "phase", "offset"), parameters, strict=True))
    python, native = made(Reference, **named), made(Reference, **named)
    step, refresh = shim_calls(native)
    t = python.time = native.time = 0.25
    while t < 40.0:
        python.refresh_outputs()
        assert refresh() is None
        assert state(native, REFERENCE_OUTPUTS) == state(python, REFERENCE_OUTPUTS), t
        assert python.do_step(t, 0.37) is True and step(t, 0.37) is True
        assert state(native, ("time",)) == state(python, ("time",))
        t = python.time
    expected = reference_derivatives(t, ReferenceParameters(*parameters))
    native.refresh_outputs()  # the Python method on the C side's state: what the C refresh wrote
    assert state(native, REFERENCE_OUTPUTS) == bits(expected)


def actuator_expected(t: float, v: float, x1: float, x2: float, p: ActuatorParameters) -> list[str]:
    """The pure-Python functions, with the refresh's snap of t to t_fault."""
    if math.isfinite(p.t_fault) and abs(t - p.t_fault) <= FAULT_TIME_TOLERANCE * max(1.0, abs(p.t_fault)):
        t = p.t_fault
    return bits(actuator_output(t, v, x1, x2, p))


@pytest.mark.parametrize("t", [0.0, 10.0, 1e6, 1e300])
def test_an_infinite_fault_time_is_never_faulty(signals: ModuleType, t: float) -> None:
    """t_fault = +inf (actuator_problems: never faulty): uf = v at every time, in Python and in C.
    The refresh's snap of a time near t_fault took inf - inf <= 1e-12 inf for near, and applied
    the fault (uf 0.6 for v = 2)."""
    python, native = made(Actuator, t_fault=math.inf), made(Actuator, t_fault=math.inf)
    for slave in (python, native):
        slave.v, slave.x1, slave.x2, slave.time = 2.0, 0.3, -0.2, t
    python.refresh_outputs()
    shim_calls(native)[1]()
    assert (python.uf, python.u_dz) == (native.uf, native.u_dz) == (2.0, 1.5)  # u_dz = m_r (v - b_r)


@pytest.mark.parametrize("start", [9.5, 10.0 - 5e-13])
def test_actuator_same_bits_as_python(signals: ModuleType, start: float) -> None:
    """Across t_fault (with the snap of a time an ulp away), every point: saturation, the three
    branches of the dead-zone, nan inputs."""
    python, native = made(Actuator, **ACTUATOR_PARAMETERS), made(Actuator, **ACTUATOR_PARAMETERS)
    step, refresh = shim_calls(native)
    params = native._params
    t = python.time = native.time = start
    seen_fault = seen_before = False
    for _ in range(12):
        for v, x1, x2 in ACTUATOR_POINTS:
            for slave in (python, native):
                slave.v, slave.x1, slave.x2 = v, x1, x2
            python.refresh_outputs()
            assert refresh() is None
            assert state(native, ACTUATOR_OUTPUTS) == state(python, ACTUATOR_OUTPUTS), (t, v)
            assert state(native, ACTUATOR_OUTPUTS) == actuator_expected(t, v, x1, x2, params), (t, v)
        seen_fault |= t >= 10.0
        seen_before |= t < 10.0
        h = 0.1 if start == 9.5 else 1e-13
        assert python.do_step(t, h) is True and step(t, h) is True
        assert state(native, ("time",)) == state(python, ("time",))
        t = python.time
    assert seen_fault and seen_before


def test_parameters_not_frozen_yet_fall_back(signals: ModuleType) -> None:
    """Before exit_initialization_mode (``_params`` None) the outputs use the parameters set so far."""
    slave = Reference(instance_name="r")
    slave.amplitude, slave.time = 2.0, 1.0
    _, refresh = shim_calls(slave)
    refresh()
    assert state(slave, REFERENCE_OUTPUTS) == bits(reference_derivatives(1.0, ReferenceParameters(2.0)))
    actuator = Actuator(instance_name="a")
    actuator.t_fault, actuator.v, actuator.K_amp = 0.0, 2.0, 0.0
    _, refresh = shim_calls(actuator)
    refresh()
    assert state(actuator, ACTUATOR_OUTPUTS) == bits((0.4 * 1.5, 1.5))


def outcome(call: Any) -> tuple[Any, ...]:
    try:
        return ("returned", call())
    except Exception as error:  # noqa: BLE001 - the outcome compared, whatever it is
        return ("raised", type(error), str(error))


@pytest.mark.parametrize(
    ("change", "expected_error"),
    [
        ({"x1": math.inf}, ValueError),  # cos(inf) after the fault
        ({"x1": -math.inf}, ValueError),
        ({"time": -1e4, "_params": ActuatorParameters(t_fault=-1e6)}, OverflowError),  # exp(2000)
        ({"v": "1.0"}, TypeError),  # not a number
        ({"v": 3}, None),  # an int: Python's arithmetic
        ({"x2": 2**1100}, OverflowError),  # an int too large for a float
        ({"time": None}, TypeError),
    ],
)
def test_actuator_other_paths_are_the_python_methods(
        signals: ModuleType, change: dict[str, Any], expected_error: type | None) -> None:
    """Every path but the usual one: the Python refresh's result or exception, and where it raises
    the dict as the Python method left it."""
    python, native = made(Actuator, t_fault=1.0), made(Actuator, t_fault=1.0)
    _, refresh = shim_calls(native)
    for slave in (python, native):
        slave.time, slave.v, slave.x1, slave.x2 = 2.0, 1.0, 0.5, 0.5
        vars(slave).update(change)
        if "_params" in change:
            slave._param_values = signals_native.param_values(slave._params)
    before = dict(vars(native))
    got, want = outcome(refresh), outcome(python.refresh_outputs)
    assert got == want
    if expected_error is not None:
        assert want[:2] == ("raised", expected_error)
        assert vars(native) == before  # nothing written
    else:
        assert state(native, ACTUATOR_OUTPUTS) == state(python, ACTUATOR_OUTPUTS)


def test_reference_other_paths_are_the_python_methods(signals: ModuleType) -> None:
    for time, expected in ((math.inf, ValueError), (-math.inf, ValueError), (math.nan, None), (1, None)):
        python, native = made(Reference), made(Reference)
        python.time = native.time = time
        _, refresh = shim_calls(native)
        before = dict(vars(native))
        got, want = outcome(refresh), outcome(python.refresh_outputs)
        assert got == want
        if expected is None:
            assert state(native, REFERENCE_OUTPUTS) == state(python, REFERENCE_OUTPUTS)
        else:
            assert want[:2] == ("raised", expected) and vars(native) == before


def test_replaced_parameters_are_not_read_from_the_stale_copy(signals: ModuleType) -> None:
    """A ``_params`` that is no longer the one the copy was made of (a snapshot of another state,
    a change by hand): the Python refresh, with the parameters it reads."""
    slave = made(Reference)
    _, refresh = shim_calls(slave)
    slave._params = ReferenceParameters(amplitude=3.0)
    slave.time = 0.5
    refresh()
    assert state(slave, REFERENCE_OUTPUTS) == bits(reference_derivatives(0.5, ReferenceParameters(3.0)))


def test_a_restored_snapshot_keeps_the_compiled_path(signals: ModuleType) -> None:
    """fmi2SetFMUstate deep-copies the dict in one go: the copy of the values still names the copy
    of ``_params``, so the compiled refresh keeps reading them (and gives the Python bits)."""
    slave = made(Actuator, **ACTUATOR_PARAMETERS)
    _, refresh = shim_calls(slave)
    snapshot = slave._get_fmu_state()
    slave._set_fmu_state(snapshot)
    assert slave._param_values[0] is slave._params and slave._params is not snapshot["_params"]
    slave.time, slave.v, slave.x1, slave.x2 = 12.0, 1.2, 0.3, -0.4
    refresh()
    assert state(slave, ACTUATOR_OUTPUTS) == actuator_expected(12.0, 1.2, 0.3, -0.4, slave._params)


def test_step_with_other_than_floats_is_the_python_method(signals: ModuleType) -> None:
    """The callable step_slave (the shim's C entry takes doubles only) with ints or a string."""
    slave = made(Reference)
    step = handed(slave)[0]
    assert step(1, 2) is True and type(slave.time) is int and slave.time == 3
    assert step(0.1, 0.2) is True and slave.time == 0.1 + 0.2
    with pytest.raises(TypeError):
        step("a", 1.0)


# ----------------------------------------------------------------------------------------------
# Through the built FMUs and the shim


class Instance:
    """One instance of a built FMU through fmpy (this process's Python runs its slave)."""

    def __init__(self, fmu: Path, name: str) -> None:
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped(fmu),
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.name = name

    def slave(self, model: str) -> Any:
        """The Python slave behind the instance."""
        (found,) = [o for o in gc.get_objects() if type(o).__name__ == model
                    and getattr(o, "instance_name", None) == self.name]
        return found

    def start(self, t0: float, **parameters: float) -> None:
        self.fmu.setupExperiment(startTime=t0)
        self.fmu.enterInitializationMode()
        self.set(**parameters)
        self.fmu.exitInitializationMode()

    def set(self, **values: float) -> None:
        for name, value in values.items():
            self.fmu.setReal([self.vr[name]], [value])

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[name] for name in names])


@pytest.fixture
def fmu(
    fmus: dict[str, Path], monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> Iterator[Any]:
    """Instances with the shim's direct calls on; freed at the end."""
    monkeypatch.setenv("FTC_FMU_DIRECT", "1")
    made: list[Instance] = []

    def open_instance(model: str) -> Instance:
        instance = Instance(fmus[model], f"{request.node.name}-{len(made)}")
        made.append(instance)
        return instance

    yield open_instance
    for instance in made:
        instance.fmu.freeInstance()


def assert_compiled(slave: Any, refresh_name: str) -> None:
    """The binding the FMU's slave hands the shim holds the FMU's own compiled functions."""
    step, refresh, capsule, _ = handed(slave)
    module = step.func.__self__
    assert module.__name__.startswith("_ftc_") and module.__name__.endswith(".models._signals")
    assert module.__file__.endswith(".abi3.so")
    assert step.func is module.step_slave and refresh.func is getattr(module, refresh_name)
    assert capsule is getattr(module, refresh_name.replace("_refresh", "_direct_calls"))


@pytest.mark.system
@pytest.mark.parametrize("parameters", REFERENCE_CASES)
def test_reference_fmu_gives_the_python_bits(fmu: Any, parameters: tuple[float, ...]) -> None:
    instance = fmu("Reference")
    named = dict(zip(("amplitude", "omega", "phase", "offset"), parameters, strict=True))
    instance.start(0.25, **named)
    assert_compiled(instance.slave("Reference"), "reference_refresh")
    p = ReferenceParameters(*parameters)
    t, h = 0.25, 0.013
    assert bits(instance.get(*REFERENCE_OUTPUTS)) == bits(reference_derivatives(t, p))
    for k in range(300):
        current = 0.25 + k * h
        instance.fmu.doStep(current, h)
        t = current + h
        assert bits(instance.get(*REFERENCE_OUTPUTS)) == bits(reference_derivatives(t, p)), t


@pytest.mark.system
def test_actuator_fmu_gives_the_python_bits(fmu: Any) -> None:
    """A run over 9.9 .. 10.1 s in 1 ms steps (the master's t0 + k h, the FMU's t + h an ulp away
    at t_fault), every input point at every step: before and after the fault, the dead-zone's
    three branches, saturation."""
    instance = fmu("Actuator")
    instance.start(9.9, **ACTUATOR_PARAMETERS)
    assert_compiled(instance.slave("Actuator"), "actuator_refresh")
    p = ActuatorParameters(**{**ActuatorParameters().__dict__, **ACTUATOR_PARAMETERS})
    h, t = 1e-3, 9.9
    for k in range(201):
        for v, x1, x2 in ACTUATOR_POINTS:
            instance.set(v=v, x1=x1, x2=x2)
            assert bits(instance.get(*ACTUATOR_OUTPUTS)) == actuator_expected(t, v, x1, x2, p), (t, v)
        current = 9.9 + k * h
        instance.fmu.doStep(current, h)
        t = current + h
    assert t > 10.0


@pytest.mark.system
def test_actuator_fmu_infinite_input_outcome(fmus: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """An infinite x1 after the fault (fmath.cos raises): the same error status and messages through
    the compiled refresh as through pythonfmu's own path (the Python method)."""
    seen = {}
    for direct in ("1", "0"):
        monkeypatch.setenv("FTC_FMU_DIRECT", direct)
        messages = Messages()
        slave, vr = instantiate(fmus["Actuator"], messages, name=f"infinite-{direct}")
        try:
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.setReal([vr["t_fault"]], [0.0])
            slave.exitInitializationMode()
            slave.setReal([vr["v"], vr["x1"], vr["x2"]], [1.0, math.inf, 0.5])
            with pytest.raises(FMICallException) as raised:
                slave.getReal([vr["uf"]])
            seen[direct] = raised.value.status, [(status, text.replace(f"infinite-{direct}", "NAME"))
                                                 for status, text in messages.seen]
        finally:
            slave.freeInstance()
    assert seen["1"] == seen["0"]
    status, logged = seen["1"]
    assert status == 4  # fmi2Fatal: what pythonfmu makes of an exception in refresh_outputs
    assert any("math domain error" in text for _, text in logged), logged
