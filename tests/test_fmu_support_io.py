# SPDX-License-Identifier: BSD-2-Clause
"""fmu_support's get/set (value reference -> attribute, outputs refreshed once per change), on the
slave classes in this process: what pythonfmu's binary calls for fmi2Get/SetReal/Integer."""

from __future__ import annotations

import math

import pytest

from fmu_src.actuator import Actuator
from fmu_src.example1_plant import Example1Plant
from fmu_src.fmu_support import assigned
from fmu_src.reference import Reference


def refs(slave) -> dict[str, int]:
    return {v.name: vr for vr, v in slave.vars.items()}


def test_outputs_follow_parameters_inputs_and_steps() -> None:
    plant = Example1Plant(instance_name="p")
    vr = refs(plant)
    plant.set_real([vr["x1_0"]], [0.25])
    assert plant.get_real([vr["x1"], vr["y"]]) == [0.25, 0.25]  # initialization mode: the parameter
    plant.exit_initialization_mode()
    plant.set_real([vr["uf"]], [1.0])
    plant.do_step(0.0, 1e-3)
    x1, x2, z, y = plant.get_real([vr["x1"], vr["x2"], vr["z"], vr["y"]])
    assert (x1, x2, z) == plant.state and y == x1 and x1 != 0.25

    reference = Reference(instance_name="r")
    vr = refs(reference)
    reference.exit_initialization_mode()
    reference.do_step(0.0, 0.5)
    assert reference.get_real([vr["yd"], vr["yd_dot"]]) == [0.5 * math.sin(0.5), 0.5 * math.cos(0.5)]


def test_direct_feedthrough_is_recomputed_after_each_set() -> None:
    actuator = Actuator(instance_name="a")
    vr = refs(actuator)
    actuator.exit_initialization_mode()
    for v in (3.0, -2.0, 0.25):
        actuator.set_real([vr["v"]], [v])
        assert actuator.get_real([vr["uf"]]) == [v]  # before the fault uf = v


def test_wrong_types_and_causalities_are_refused() -> None:
    plant = Example1Plant(instance_name="p")
    vr = refs(plant)
    with pytest.raises(TypeError, match=f"valueReference={vr['x1']} is not a Real input or parameter"):
        plant.set_real([vr["x1"]], [1.0])
    with pytest.raises(TypeError, match=f"valueReference={vr['method']} is not of type Real"):
        plant.get_real([vr["x1"], vr["method"]])
    with pytest.raises(TypeError, match=f"valueReference={vr['rtol']} is not of type Integer"):
        plant.get_integer([vr["rtol"]])
    with pytest.raises(TypeError, match="is not an Integer parameter"):
        plant.set_integer([vr["uf"]], [1])


def test_assigned_parameters_are_recorded() -> None:
    plant = Example1Plant(instance_name="p")
    vr = refs(plant)
    plant.set_real([vr["uf"]], [2.0])
    assert assigned(plant) == frozenset()  # inputs are not parameters
    plant.set_real([vr["max_step"]], [1e-4])
    plant.set_integer([vr["method"]], [0])
    assert assigned(plant) == {"max_step", "method"}
    assert plant.get_integer([vr["method"]]) == [0]
