# SPDX-License-Identifier: BSD-2-Clause
"""The shim's direct calls (fmu_src/toolchain/shim/cosimulation.c) against pythonfmu's own
path, which FTC_FMU_DIRECT=0 restores: the oracle is the same FMU driven through pythonfmu.

Every communication step's fmi2DoStep/GetReal/SetReal of the project's FMUs goes past
pythonfmu's per-call machinery when the shim has claimed the slave. These tests check that the
two paths cannot be told apart: identical co-simulation results (bit for bit), the same status
and message when do_step raises (replayed through pythonfmu), the same fmi2Discard, last
successful time and terminate wish, messages queued during a step reaching the host's logger,
and a new binding after fmi2Reset. The plants' step and refresh on the direct path are compiled
(fmu_src/models/_dopri.c step_slave and refresh_slave): no Python frame on their usual path, the
Python methods' status and message on every other one.
"""

from __future__ import annotations

import functools
import gc
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Discard,
    fmi2LastSuccessfulTime,
    fmi2Terminated,
)
from fmu_helpers import Frames, unzipped

import orchestrator
from orchestrator import RunOptions

pytestmark = pytest.mark.system

PATHS = ("direct", "pythonfmu")


@pytest.fixture(params=PATHS)
def path(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Which path the instances created in the test take (the shim reads FTC_FMU_DIRECT at
    fmi2Instantiate)."""
    monkeypatch.setenv("FTC_FMU_DIRECT", "1" if request.param == "direct" else "0")
    return str(request.param)


class Messages:
    """An FMI logger that keeps (status, message) of every call."""

    def __init__(self) -> None:
        self.seen: list[tuple[int, str]] = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)

    def _log(self, env, name, status, category, message) -> None:  # noqa: ANN001 - ctypes callback
        self.seen.append((status, message.decode()))


def instantiate(fmu: Path, messages: Messages, name: str = "instance") -> tuple[FMU2Slave, dict[str, int]]:
    """One instance with logging on, and its value references by name."""
    md = read_model_description(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped(fmu),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    slave.instantiate(callbacks=messages.callbacks, loggingOn=True)
    return slave, {v.name: v.valueReference for v in md.modelVariables}


@contextmanager
def instance(fmu: Path, messages: Messages) -> Iterator[tuple[FMU2Slave, dict[str, int]]]:
    """:func:`instantiate`, freed on every path."""
    slave, vr = instantiate(fmu, messages)
    try:
        yield slave, vr
    finally:
        slave.freeInstance()


def unclaimed() -> bool:
    """Whether a slave constructed in this thread is still waiting for the shim to claim it."""
    return threading.get_ident() in sys.__dict__.get("_ftc_fmu_slaves", {})


@pytest.mark.parametrize("scenario", ["example1", "pendulum", "manipulator"])
def test_results_identical_on_both_paths(built: Path, monkeypatch: pytest.MonkeyPatch, scenario: str) -> None:
    """Every column of a 1 s co-simulation is the same to the bit, direct (the plant stepped and
    refreshed in C) or through pythonfmu (the plant's Python methods)."""
    results = {}
    for value in ("1", "0"):
        monkeypatch.setenv("FTC_FMU_DIRECT", value)
        results[value] = orchestrator.run(built / "ssp" / f"{scenario}.ssp", RunOptions(stop_time=1.0)).rows
    direct, plain = results["1"], results["0"]
    assert direct.dtype.names == plain.dtype.names
    assert len(direct) == len(plain) > 1000
    for column in direct.dtype.names:
        assert np.array_equal(direct[column], plain[column]), column


def test_instances_are_claimed(fmus: dict[str, Path], path: str) -> None:
    """The shim claims each slave pythonfmu constructs, in fmi2Instantiate and in fmi2Reset, on both
    paths: with the direct path off too, to give a slave reused from the pool the new instance's
    name (issue 44); it then forwards every call (test_results_identical_on_both_paths)."""
    for fmu in fmus.values():
        with instance(fmu, Messages()) as (slave, _):
            assert not unclaimed()
            slave.reset()
            assert not unclaimed()


def test_forty_live_instances_of_each_fmu_step_as_one(fmus: dict[str, Path], path: str) -> None:
    """40 instances of one FMU alive at once, each constructed by pythonfmu (the pool holds at most
    16 freed ones), step as one instance does: the same outputs to the bit. pythonfmu 0.7.0 runs the
    FMU's entry module again for every construction and then releases a reference to its namespace
    that it never took; when the entry stopped re-making the model's class, the second construction
    found the namespace freed (fmi2Instantiate returned NULL) until the entry kept one per run
    (fmu_src/toolchain/build.py, _entry)."""
    for model in ("Reference", "Actuator"):
        md = read_model_description(str(fmus[model]))
        outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
        inputs = [v.valueReference for v in md.modelVariables if v.causality == "input"]
        slaves = []
        try:
            for k in range(40):
                slave, _ = instantiate(fmus[model], Messages(), f"{model}_{k}")
                slaves.append(slave)
                slave.setupExperiment(startTime=0.0)
                slave.enterInitializationMode()
                slave.exitInitializationMode()
            seen = []
            for slave in slaves:
                for step in range(20):
                    slave.setReal(inputs, [2.0 + 0.1 * step] * len(inputs))
                    slave.doStep(step * 0.05, 0.05)
                seen.append(slave.getReal(outputs))
        finally:
            for slave in slaves:
                slave.freeInstance()
        assert len(seen) == 40 and all(values == seen[0] for values in seen), model
        assert any(v != 0.0 for v in seen[0]), model  # they moved


def test_a_step_before_initialization_is_refused_on_both_paths(fmus: dict[str, Path], path: str) -> None:
    """A do_step before initialization never reaches the slave (whose own check raised, which
    pythonfmu made fmi2Fatal): the shim's guard answers fmi2Error with one message naming the call
    and the state, on both paths, and the instance can then be freed (after pythonfmu's fatal,
    freeing it corrupted the heap)."""
    messages = Messages()
    slave, _ = instantiate(fmus["FixedTimeController"], messages)
    with pytest.raises(FMICallException) as raised:
        slave.doStep(0.0, 1e-3)
    assert raised.value.status == 3  # fmi2Error
    assert messages.seen[-1] == (3, "fmi2DoStep: not allowed in Instantiated")
    slave.freeInstance()


def test_discard_and_step_status(fmus: dict[str, Path], path: str) -> None:
    """A plant step whose state overflows is fmi2Discard with the plant's message; the last successful
    time and the terminate wish are those pythonfmu's fmi2DoStep records."""
    messages = Messages()
    with instance(fmus["Example1Plant"], messages) as (slave, vr):
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.setReal([vr["uf"]], [1.0])
        slave.doStep(0.0, 1e-3)
        assert slave.getRealStatus(fmi2LastSuccessfulTime) == 1e-3
        assert not slave.getBooleanStatus(fmi2Terminated)
        states = slave.getReal([vr["x1"], vr["x2"], vr["z"]])
        assert states != [0.5, 0.5, 0.0]  # the step moved the initial state
        slave.setReal([vr["uf"]], [1e300])
        with pytest.raises(FMICallException) as raised:
            slave.doStep(1e-3, 1e-3)
        assert raised.value.status == fmi2Discard
        assert slave.getRealStatus(fmi2LastSuccessfulTime) == 1e-3
        assert slave.getBooleanStatus(fmi2Terminated)
        assert slave.getReal([vr["y"]]) == [slave.getReal([vr["x1"]])[0]]
        assert slave.getReal([vr["x1"], vr["x2"], vr["z"]]) == states  # the rejected step left it
    assert any("step rejected (fmi2Discard)" in text for _, text in messages.seen)


def test_warning_in_do_step_reaches_the_host(fmus: dict[str, Path], path: str) -> None:
    """A message the slave queues in a successful step (the semi-implicit controller stepped at
    another step than its sample time) reaches the host's logger, once."""
    messages = Messages()
    with instance(fmus["FixedTimeController"], messages) as (slave, vr):
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setInteger([vr["discretization"]], [1])
        slave.exitInitializationMode()
        for k in range(3):
            slave.doStep(k * 2e-3, 2e-3)
    warnings = [text for status, text in messages.seen if "differs from sample_time" in text]
    assert len(warnings) == 1
    assert "communication step 0.002 s at t = 0.0" in warnings[0]


def test_reset_gives_a_fresh_instance(fmus: dict[str, Path], path: str) -> None:
    """After fmi2Reset the new slave answers: the same outputs as the first run, step by step."""
    def run(slave: FMU2Slave, vr: dict) -> list[float]:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        rows = []
        for k in range(5):
            slave.setReal([vr["x1"], vr["x2"], vr["yd"]], [0.5 - 0.01 * k, 0.5, 0.0])
            rows += slave.getReal([vr["v"], vr["eta1_hat"], vr["r"]])
            slave.doStep(k * 1e-3, 1e-3)
        return rows

    with instance(fmus["FixedTimeController"], Messages()) as (slave, vr):
        first = run(slave, vr)
        slave.reset()
        assert run(slave, vr) == first
        assert len(set(first)) > 5  # the outputs moved


class _ExplodingLaw:
    """Stands in for a controller's law: ``advance`` raises, as a bug in a model's step would (the
    first time only: a path that ran the step twice would then succeed)."""

    def __init__(self) -> None:
        self.calls = 0

    def advance(self, *args: object) -> object:
        self.calls += 1
        if self.calls == 1:
            raise ZeroDivisionError("the law exploded on purpose")
        return args[2]  # the state, unchanged


def test_an_exception_in_do_step_is_reported_as_pythonfmu_reports_it(
        fmus: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """A do_step that raises: on the direct path the shim keeps the exception and pythonfmu's
    fmi2DoStep raises that very object again: the same status and the same messages as on
    pythonfmu's own path (which names the exception, not its traceback)."""
    seen = {}
    for path in PATHS:
        monkeypatch.setenv("FTC_FMU_DIRECT", "1" if path == "direct" else "0")
        messages = Messages()
        slave, _ = instantiate(fmus["FixedTimeController"], messages, name=f"exploding-{path}")
        try:
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            (model,) = [o for o in gc.get_objects() if type(o).__name__ == "FixedTimeController"
                        and getattr(o, "instance_name", None) == f"exploding-{path}"]
            model._law = _ExplodingLaw()
            with pytest.raises(FMICallException) as raised:
                slave.doStep(0.0, 1e-3)
            assert model._law.calls == 1  # the step ran once: the exception kept, not the step redone
            seen[path] = raised.value.status, messages.seen
            del model
        finally:
            slave.freeInstance()
    assert seen["direct"] == seen["pythonfmu"]
    status, logged = seen["direct"]
    assert status == 4  # fmi2Fatal: what pythonfmu makes of an exception in do_step
    text = "\n".join(message for _, message in logged)
    assert "ZeroDivisionError('the law exploded on purpose')" in text, text


PLANTS = ("Example1Plant", "PendulumPlant", "ManipulatorPlant")


def the_slave(model: str, name: str) -> Any:
    """The slave object of instance ``name`` of ``model`` in this process (the host's Python)."""
    (slave,) = [o for o in gc.get_objects()
                if type(o).__name__ == model and getattr(o, "instance_name", None) == name]
    return slave


def shims_binding(slave: Any) -> tuple[Any, ...]:
    """The binding the shim holds for ``slave`` (nothing else keeps it once claimed)."""
    (binding,) = [o for o in gc.get_objects() if type(o) is tuple and len(o) == 12 and o[1] is slave.__dict__]
    return binding


# The FMUs the shim steps in C (their classes' compiled_calls): the extension, the inputs set per step k,
# the outputs read, the Python functions pythonfmu's path runs instead.
IN_C: dict[str, tuple[str, dict[str, Callable[[int], float]], tuple[str, ...], set[str]]] = {
    **{plant: (".models._dopri", {"uf": lambda k: 10.0 * (k % 7) - 30.0}, ("x1", "x2", "y"),
               {"step_plant", "refresh_plant_outputs"}) for plant in PLANTS},
    **{f"FixedTimeController{n}": (".controller._law",
                                   {"x1": lambda k: 0.5 - 1e-3 * k, "yd": lambda k: 1e-3 * k},
                                   ("v", "z1", "eta1_hat", "r"),
                                   {"step_controller", "refresh_controller_outputs"})
       for n in ("", "1", "3", "4")},
}


@pytest.mark.parametrize("model", sorted(IN_C))
def test_the_shim_steps_models_in_c(fmus: dict[str, Path], path: str, model: str) -> None:
    """On the direct path the shim got the FMU's own step_slave and refresh_slave (of its extension)
    and their C entries, bound to the slave: 50 steps with their outputs read enter no Python
    function of the FMU; through pythonfmu (the oracle of the other tests) its Python step and refresh run."""
    extension, inputs, outputs, python = IN_C[model]
    name = f"compiled-{model}-{path}"
    slave, vr = instantiate(fmus[model], Messages(), name=name)
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        model_object = the_slave(model, name)
        if path == "direct":
            binding = shims_binding(model_object)
            (module,) = {module for key, module in sys.modules.items()
                         if key.startswith(f"_ftc_{model.lower()}_") and key.endswith(extension)}
            step, refresh = binding[2], binding[3]
            assert isinstance(step, functools.partial) and step.func is module.step_slave
            assert isinstance(refresh, functools.partial) and refresh.func is module.refresh_slave
            assert step.args[0][0] is refresh.args[0][0] is model_object.__dict__
            assert binding[10] is module.direct_calls and binding[11] is step.args[0]  # its C entries
        read = [vr[n] for n in outputs]
        with Frames("/_ftc_") as frames:  # any FMU's bundled package: its first copy may be another's
            for k in range(50):
                slave.setReal([vr[n] for n in inputs], [value(k) for value in inputs.values()])
                slave.doStep(k * 1e-3, 1e-3)
                values = slave.getReal(read)
                assert values[0] == model_object.__dict__[outputs[0]]
        if path == "direct":
            assert frames.entered == []
        else:
            assert python <= set(frames.entered)
        del model_object
    finally:
        slave.freeInstance()


def plant_run(fmu: Path, name: str, reals: dict[str, float], integers: dict[str, int],
              inputs: list[float]) -> tuple[list[Any], list[tuple[int, str]]]:
    """Per step of 1 ms with input uf: the states read, or the status of a step that failed (then
    the run ends); the messages logged."""
    messages = Messages()
    seen: list[Any] = []
    slave, vr = instantiate(fmu, messages, name=name)
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal([vr[n] for n in reals], list(reals.values()))
        slave.setInteger([vr[n] for n in integers], list(integers.values()))
        slave.exitInitializationMode()
        states = [vr[n] for n in ("x1", "x2", "z", "y")]
        for k, uf in enumerate(inputs):
            slave.setReal([vr["uf"]], [uf])
            try:
                slave.doStep(k * 1e-3, 1e-3)
            except FMICallException as error:
                seen += [error.status, slave.getRealStatus(fmi2LastSuccessfulTime), slave.getReal(states)]
                break
            seen.append(slave.getReal(states))
    finally:
        slave.freeInstance()
    return seen, messages.seen


@pytest.mark.parametrize(("reals", "integers", "inputs"), [
    ({"state_limit": 0.6, "rate_horizon": 0.0}, {}, [0.0, 0.0, 1000.0, 0.0]),  # beyond state_limit
    ({"y_limit": 0.6}, {}, [0.0, 1e5]),  # carried beyond y_limit within the rate horizon
    ({}, {"max_steps": 2}, [0.0, 1e5]),  # the step budget spent
    ({"max_step": 1e-4}, {"method": 1}, [0.0, 50.0, -50.0, 1e300]),  # RK4, then the rate bound
])
def test_plant_steps_off_the_usual_path_are_the_python_ones(
        fmus: dict[str, Path], monkeypatch: pytest.MonkeyPatch, reals: dict[str, float],
        integers: dict[str, int], inputs: list[float]) -> None:
    """RK4 and rejected steps (fmi2Discard), which the C step leaves to the plant's Python step:
    the same states, status, last successful time and messages, direct or through pythonfmu."""
    seen = {}
    for path in PATHS:
        monkeypatch.setenv("FTC_FMU_DIRECT", "1" if path == "direct" else "0")
        seen[path] = plant_run(fmus["Example1Plant"], f"off-{path}", reals, integers, inputs)
    assert seen["direct"] == seen["pythonfmu"]
    states, messages = seen["direct"]
    assert states[-3] == fmi2Discard, states
    assert any("step rejected (fmi2Discard)" in text for _, text in messages)
