# SPDX-License-Identifier: BSD-2-Clause
"""The plants' compiled Dormand-Prince step (fmu_src/models/_dopri.c, fmu_src.models.native)
against the Python reference (fmu_src.models.plants.dopri_hold_step), a second implementation of
the same algorithm: the same bits of every result and the same exception and message, on
random states, inputs, step sizes, tolerances and bounds of both plants; and the built plant
FMUs step with it, giving the reference's bits."""

from __future__ import annotations

import math
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest
from fmu_helpers import compiled_extension, open_slave
from hypothesis import given, settings
from hypothesis import strategies as st

from fmu_src.models import native
from fmu_src.models.manipulator import ManipulatorParameters, manipulator_rhs_for
from fmu_src.models.plants import PendulumParameters, dopri_hold_step, example1_rhs, pendulum_rhs_for
from fmu_src.toolchain.build import collect_bundle

PENDULUM = PendulumParameters()
MANIPULATOR = ManipulatorParameters()
PLANTS = {"example1": (native.EXAMPLE1, example1_rhs),
          "pendulum": (native.pendulum_native(PENDULUM), pendulum_rhs_for(PENDULUM)),
          "manipulator": (native.manipulator_native(MANIPULATOR), manipulator_rhs_for(MANIPULATOR))}


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """_dopri.c compiled as the FMU build compiles it, loaded into this process as the one
    fmu_src.models.native steps with (as in a built FMU)."""
    module = compiled_extension("fmu_src.models._dopri", tmp_path_factory.mktemp("dopri"))
    saved, native._dopri = native._dopri, module
    yield module
    native._dopri = saved


def outcome(step, *args):
    """The result of a step, or its exception's type and message."""
    try:
        return step(*args)
    except (ValueError, OverflowError) as error:
        return type(error).__name__, str(error)


def both(plant: str, *args):
    """The Python reference's and the compiled step's outcomes for the same arguments."""
    native_plant, rhs = PLANTS[plant]
    return (outcome(dopri_hold_step, rhs, *args, native_plant.names),
            outcome(native.native_hold_step, native_plant, *args))


magnitudes = st.one_of(st.floats(-1.0, 1.0), st.floats(-20.0, 20.0), st.floats(-1e4, 1e4),
                       st.floats(-1e8, 1e8))


@settings(max_examples=400, deadline=None)
@given(
    plant=st.sampled_from(sorted(PLANTS)),
    t=st.floats(0.0, 30.0),
    state=st.tuples(magnitudes, magnitudes, magnitudes),
    uf=st.one_of(st.just(0.0), st.floats(-1e3, 1e3), st.floats(-1e8, 1e8)),
    h=st.sampled_from([1e-3, 5e-4, 1e-2, 0.1]),
    rtol=st.sampled_from([1e-10, 1e-6, 1e-3]),
    first=st.sampled_from([0.0, 1.0, 1 / 7, 1e-4]),
    limit=st.sampled_from([math.inf, 1e4, 1e6]),
    max_steps=st.sampled_from([50_000, 200, 3, 1]),
    y_limit=st.sampled_from([math.inf, 20.0]),
    rate_horizon=st.sampled_from([0.0, 1.0, 3.0]),
)
def test_compiled_step_gives_the_references_bits_and_errors(compiled, plant, t, state, uf, h, rtol,
                                                            first, limit, max_steps, y_limit, rate_horizon):
    reference, fast = both(plant, t, state, uf, h, rtol, rtol * 1e-2, first * h, limit,
                           max_steps, y_limit, rate_horizon)
    assert fast == reference


@pytest.mark.parametrize("plant", sorted(PLANTS))
def test_overflowing_states_are_the_references_domain_errors_and_rejections(compiled, plant):
    """math.sin(inf) raises where C's sin gives nan: at the first evaluation a math domain error;
    inside a trial step a rejected step, then smaller ones."""
    huge = (math.inf, 0.0, 0.0) if plant == "manipulator" else (1e200, 1e200, 0.0)  # sin(inf) in the rhs
    reference, fast = both(plant, 0.0, huge, 0.0, 1e-3, 1e-10, 1e-12, 0.0, math.inf,
                           50_000, math.inf, 0.0)
    assert fast == reference
    assert fast == ("ValueError", "math domain error")
    growing = (1e150, 1e-150, 1e150)  # finite products at the first evaluation, infinite ones inside the step
    reference, fast = both(plant, 0.0, growing, 1e300, 1e-3, 1e-10, 1e-12, 0.0, math.inf,
                           1000, math.inf, 0.0)
    assert fast == reference


def test_finite_escape_trajectory_is_the_references(compiled):
    """Example 1 under a held control that drives it out of range (x1 from 6 towards -20, the
    kind of run a finite escape is): step after step the same states, step sizes and counts,
    until both end on the same bound with the same message."""
    h, bounds = 1e-3, (1e4, 50_000, 20.0, 1.0)  # state_limit, max_steps, y_limit, rate_horizon
    state, guess = (6.0, 0.0, 0.0), 0.0
    for k in range(2000):
        t = k * h
        uf = -150.0 + 40.0 * math.sin(3.0 * t)
        a = outcome(dopri_hold_step, example1_rhs, t, state, uf, h, 1e-10, 1e-12, guess, *bounds)
        b = outcome(native.native_hold_step, native.EXAMPLE1, t, state, uf, h, 1e-10, 1e-12, guess, *bounds)
        assert a == b, k
        if isinstance(a[0], str):  # both ended the run
            assert "y_limit" in a[1] or "state_limit" in a[1]
            return
        state, guess = a.state, a.next_step
    pytest.fail("the held control did not drive the state out of range")


def test_only_the_plants_bundle_the_extension():
    """_dopri in the plants, _law in the controllers, _signals in the reference and the actuator,
    controller/fmath's compiled functions in all."""
    for model in ("Example1Plant", "PendulumPlant", "ManipulatorPlant"):
        assert set(collect_bundle(model).extensions) == {"fmu_src.models._dopri", "controller._fmath"}
    for model in ("Reference", "Actuator"):
        assert set(collect_bundle(model).extensions) == {"fmu_src.models._signals", "controller._fmath"}
    for model in ("FixedTimeController", "FixedTimeController1", "FixedTimeController3",
                  "FixedTimeController4"):
        assert set(collect_bundle(model).extensions) == {"controller._law", "controller._fmath"}


@pytest.mark.system
@pytest.mark.parametrize("model", ["Example1Plant", "PendulumPlant", "ManipulatorPlant"])
def test_built_plant_fmus_step_with_the_compiled_integrator(fmus, model):
    """The FMU loads its own _dopri (from its unpacked resources) into the host's Python and steps
    the reference's bits: 200 steps under a varying input, against dopri_hold_step in Python."""
    plant = {"Example1Plant": example1_rhs, "PendulumPlant": pendulum_rhs_for(PENDULUM),
             "ManipulatorPlant": manipulator_rhs_for(MANIPULATOR)}[model]
    states = ("x1", "x2", "x3") if model == "ManipulatorPlant" else ("x1", "x2", "z")
    with open_slave(fmus[model]) as slave:
        slave.initialize()
        state, guess, h = tuple(slave.get(*states)), 0.0, 1e-3
        for k in range(200):
            uf = 300.0 * math.cos(7.0 * k * h)
            slave.set(uf=uf)
            slave.step(k * h, h)
            state, guess, _, _ = dopri_hold_step(plant, k * h, state, uf, h, 1e-10, 1e-12, guess, 1e4, 50_000,
                                                 20.0, 1.0)
            assert tuple(slave.get(*states)) == state, k
    loaded = [module for name, module in list(sys.modules.items())
              if name.startswith(f"_ftc_{model.lower()}_") and name.endswith(".models._dopri")]
    assert loaded and all(Path(str(module.__file__)).name == "_dopri.abi3.so" for module in loaded)


@pytest.mark.system
def test_a_plant_fmu_without_its_compiled_step_does_not_instantiate(fmus, tmp_path):
    """A built FMU whose _dopri.abi3.so is missing is broken: it fails to instantiate instead of
    stepping with the Python reference (slower, and silently)."""
    broken = tmp_path / "Example1Plant.fmu"
    with zipfile.ZipFile(fmus["Example1Plant"]) as source, zipfile.ZipFile(broken, "w") as target:
        members = [info for info in source.infolist() if not info.filename.endswith("_dopri.abi3.so")]
        assert len(members) == len(source.infolist()) - 1
        for info in members:
            target.writestr(info, source.read(info))
    script = ("import sys; sys.path.insert(0, sys.argv[2]); from pathlib import Path; "
              "from fmu_helpers import open_slave\n"
              "try:\n    open_slave(Path(sys.argv[1])).__enter__()\nexcept Exception as e:\n    print(e)")
    # a fresh interpreter: in this one the FMU's package may be imported already, _dopri included
    done = subprocess.run([sys.executable, "-c", script, str(broken), str(Path(__file__).parent)],
                          capture_output=True, text=True, timeout=120)
    last = done.stdout.strip().splitlines()[-1:]
    assert last == ["Failed to instantiate model"], (done.stdout, done.stderr)
