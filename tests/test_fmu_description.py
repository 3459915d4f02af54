# SPDX-License-Identifier: BSD-2-Clause
"""The model descriptions: validity, the interface contract of SPEC section 5, descriptions,
units, DefaultExperiment and the ModelStructure dependencies pythonfmu does not write itself."""

from __future__ import annotations

import zipfile

import fmpy
import pytest
from fmpy.validation import validate_fmu
from fmu_helpers import MODELS

pytestmark = pytest.mark.system

# SPEC 11: the controller for plant order n; yd's derivatives named yd_dot, yd_ddot, yd_dddot, yd_ddddot
ORDERS = {"FixedTimeController1": 1, "FixedTimeController": 2, "FixedTimeController3": 3,
          "FixedTimeController4": 4}
DERIVATIVES = ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")


def controller_interface(n: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(inputs, outputs) of the controller FMU of order n, written out from SPEC 11."""
    inputs = tuple(f"x{i}" for i in range(1, n + 1)) + DERIVATIVES[: n + 1]
    outputs = ("v", *(f"z{i}" for i in range(1, n + 1)), *(f"zeta{i}" for i in range(1, n)),
               *(f"eta{i}_hat" for i in range(1, n + 1)), "r")
    return inputs, outputs


def controller_parameters(n: int) -> dict[str, tuple[float, str | None]]:
    """Parameter -> (default, unit) of the controller FMU of order n: Example 1's gains, steps beyond 2
    repeating step 2's (SPEC 11)."""
    gains = {"k": (10, 10), "q": (8, 8), "a": (5, 2), "kappa": (2, 2), "rho": (2, 2), "rho_bar": (1, 1)}
    out: dict[str, tuple[float, str | None]] = {
        f"{g}{i}": (d[min(i, 2) - 1], None) for g, d in gains.items() for i in range(1, n + 1)}
    out |= {"alpha": (1.5, None), "beta": (0.75, None), "mode": (0, None), "a_bar": (1.0, "1/s"),
            "gamma_gain": (2.5, None), "gamma_power": (4.0, None), "d_r": (0.625, None), "r0": (0.0, None),
            "tau": (2.0, None), "substeps": (1, None), "discretization": (0, None),
            "sample_time": (1e-3, "s"), "b_max": (1.0, None), "nn_term": (1, None)}
    out |= {f"eta{i}_0": (0.0, None) for i in range(1, n + 1)}
    out |= {f"mu{j}": (c, None) for j, c in enumerate((-1.5, -1, -0.5, 0, 0.5, 1, 1.5), start=1)}
    return out


def controller_dependencies(n: int) -> dict[str, tuple[str, ...]]:
    """Output -> the inputs it depends on directly: z_i = x_i - zeta_(i-1) and zeta_i on x_1..x_i,
    yd..yd^(i) (X_i of SPEC 1); z_n and v on every input; the states on none."""
    inputs, _ = controller_interface(n)
    out = {"v": inputs, "z1": ("x1", "yd")}
    for i in range(2, n + 1):
        out[f"z{i}"] = inputs if i == n else (*inputs[:i], *DERIVATIVES[:i])
    for i in range(1, n):
        out[f"zeta{i}"] = (*inputs[:i], *DERIVATIVES[: i + 1])
    return out | {f"eta{i}_hat": () for i in range(1, n + 1)} | {"r": ()}


INTERFACE = {  # model -> (inputs, outputs)
    "Reference": ((), ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")),
    **{model: controller_interface(n) for model, n in ORDERS.items() if n != 2},
    "ManipulatorPlant": (("uf",), ("x1", "x2", "x3", "y")),
    "FixedTimeController": (
        ("x1", "x2", "yd", "yd_dot", "yd_ddot"),
        ("v", "z1", "z2", "zeta1", "eta1_hat", "eta2_hat", "r"),
    ),
    "Actuator": (("v", "x1", "x2"), ("uf", "u_dz")),
    "Example1Plant": (("uf",), ("x1", "x2", "z", "y")),
    "PendulumPlant": (("uf",), ("x1", "x2", "z", "y")),
}
CONTROLLER_PARAMETERS = (
    [f"{g}{i}" for g in ("k", "q", "a", "kappa", "rho", "rho_bar") for i in (1, 2)]
    + ["alpha", "beta", "mode", "a_bar", "gamma_gain", "gamma_power", "d_r", "r0", "eta1_0", "eta2_0"]
    + [f"mu{j}" for j in range(1, 8)]
    + ["tau", "substeps", "discretization", "sample_time", "b_max", "nn_term"]
)
PARAMETERS = {  # model -> parameter -> (default, unit)
    "Reference": {
        "amplitude": (0.5, None),
        "omega": (1.0, "rad/s"),
        "phase": (0.0, "rad"),
        "offset": (0.0, None),
    },
    "FixedTimeController": {
        **{
            f"{g}{i}": (d[i - 1], None)
            for g, d in {
                "k": (10, 10),
                "q": (8, 8),
                "a": (5, 2),
                "kappa": (2, 2),
                "rho": (2, 2),
                "rho_bar": (1, 1),
            }.items()
            for i in (1, 2)
        },
        "alpha": (1.5, None),
        "beta": (0.75, None),
        "mode": (0, None),
        "a_bar": (1.0, "1/s"),
        "gamma_gain": (2.5, None),
        "gamma_power": (4.0, None),
        "d_r": (0.625, None),
        "r0": (0.0, None),
        "eta1_0": (0.0, None),
        "eta2_0": (0.0, None),
        "tau": (2.0, None),
        "substeps": (1, None),
        "discretization": (0, None),
        "sample_time": (1e-3, "s"),
        "b_max": (1.0, None),
        "nn_term": (1, None),
        **{f"mu{j}": (c, None) for j, c in enumerate((-1.5, -1, -0.5, 0, 0.5, 1, 1.5), start=1)},
    },
    "Actuator": {
        "m_r": (1.0, None),
        "m_l": (1.2, None),
        "b_r": (0.5, None),
        "b_l": (0.6, None),
        "K_inf": (0.4, None),
        "K_amp": (0.6, None),
        "K_rate": (0.2, "1/s"),
        "L_gain": (1.0, None),
        "L_bias": (0.0, None),
        "t_fault": (10.0, "s"),
        "u_max": (1e300, None),
    },
    "Example1Plant": {"x1_0": (0.5, None), "x2_0": (0.5, None), "z_0": (0.0, None)},
    **{model: controller_parameters(n) for model, n in ORDERS.items() if n != 2},
    "ManipulatorPlant": {  # Dawson, Carroll and Schneider (1994)
        "J": (1.625e-3, "kg.m2"), "m": (0.506, "kg"), "L0": (0.305, "m"), "M0": (0.434, "kg"),
        "R0": (0.023, "m"), "B0": (16.25e-3, "N.m.s/rad"), "L": (25.0e-3, "H"), "R": (5.0, "Ohm"),
        "K_tau": (0.90, "N.m/A"), "K_B": (0.90, "V.s/rad"), "G": (9.81, "m/s2"), "x1_0": (0.5, "rad"),
        "x2_0": (0.0, "rad/s"), "x3_0": (0.0, "A"),
    },
    "PendulumPlant": {
        "M": (0.25, "kg"),
        "L": (4.0, "m"),
        "B": (0.25, "kg/s2"),
        "g": (10.0, "m/s2"),
        "d1": (0.2, "rad/s"),
        "d2": (0.3, "rad/s2"),
        "x1_0": (0.6, "rad"),
        "x2_0": (0.1, "rad/s"),
        "z_0": (0.0, None),
    },
}
# plant integrator parameters, in declaration order (Integer method: 0 Dormand-Prince, 1 RK4), then
# the fail-fast bounds (issue 20)
INTEGRATOR = ("max_step", "method", "rtol", "atol", "state_limit", "max_steps", "y_limit", "rate_horizon")
# output -> the inputs it depends on directly (SPEC section 5; z1 and zeta1 use fewer inputs)
DEPENDENCIES = {
    "Reference": {"yd": (), "yd_dot": (), "yd_ddot": (), "yd_dddot": (), "yd_ddddot": ()},
    **{model: controller_dependencies(n) for model, n in ORDERS.items() if n != 2},
    "ManipulatorPlant": {"x1": (), "x2": (), "x3": (), "y": ()},
    "FixedTimeController": {
        "v": ("x1", "x2", "yd", "yd_dot", "yd_ddot"),
        "z1": ("x1", "yd"),
        "z2": ("x1", "x2", "yd", "yd_dot", "yd_ddot"),
        "zeta1": ("x1", "yd", "yd_dot"),
        "eta1_hat": (),
        "eta2_hat": (),
        "r": (),
    },
    "Actuator": {"uf": ("v", "x1", "x2"), "u_dz": ("v",)},
    "Example1Plant": {"x1": (), "x2": (), "z": (), "y": ()},
    "PendulumPlant": {"x1": (), "x2": (), "z": (), "y": ()},
}
SI = {
    "s": {"s": 1},
    "1/s": {"s": -1},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "m": {"m": 1},
    "kg": {"kg": 1},
    "m/s2": {"m": 1, "s": -2},
    "kg/s2": {"kg": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    "A": {"A": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "H": {"kg": 1, "m": 2, "s": -2, "A": -2},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "kg.m2": {"kg": 1, "m": 2},
    "N.m/A": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "V.s/rad": {"kg": 1, "m": 2, "s": -2, "A": -1, "rad": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
}


@pytest.mark.parametrize("model", MODELS)
def test_validates_and_dumps(fmus: dict, model: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert validate_fmu(str(fmus[model])) == []
    fmpy.dump(str(fmus[model]))
    assert model in capsys.readouterr().out


@pytest.mark.parametrize("model", MODELS)
def test_interface_descriptions_and_experiment(fmus: dict, model: str) -> None:
    md = fmpy.read_model_description(str(fmus[model]))
    assert md.modelName == model
    assert md.coSimulation.modelIdentifier == model
    assert md.coSimulation.canGetAndSetFMUstate
    inputs, outputs = INTERFACE[model]
    assert tuple(v.name for v in md.modelVariables if v.causality == "input") == inputs
    assert tuple(v.name for v in md.modelVariables if v.causality == "output") == outputs
    parameters = [v.name for v in md.modelVariables if v.causality == "parameter"]
    expected = list(PARAMETERS[model]) + (list(INTEGRATOR) if "Plant" in model else [])
    assert sorted(parameters) == sorted(expected)
    if model == "FixedTimeController":
        assert sorted(parameters) == sorted(CONTROLLER_PARAMETERS)
        assert PARAMETERS[model] == controller_parameters(2)  # the order-n rule gives today's n = 2
        assert INTERFACE[model] == controller_interface(2)
        assert DEPENDENCIES[model] == controller_dependencies(2)
    assert all(v.description for v in md.modelVariables)
    assert md.description
    experiment = md.defaultExperiment
    assert (float(experiment.startTime), float(experiment.stopTime), float(experiment.stepSize)) == (
        0,
        30,
        0.001,
    )


@pytest.mark.parametrize("model", MODELS)
def test_parameter_defaults_and_units(fmus: dict, model: str) -> None:
    md = fmpy.read_model_description(str(fmus[model]))
    variables = {v.name: v for v in md.modelVariables}
    for name, (default, unit) in PARAMETERS[model].items():
        assert float(variables[name].start) == default, name
        assert variables[name].variability == "fixed", name
        assert variables[name].unit == unit, name
    if "Plant" in model:
        assert variables["max_step"].unit == "s"
        assert 0 < float(variables["max_step"].start) <= 1e-4
        assert variables["method"].type == "Integer" and int(variables["method"].start) == 0
        for name in ("rtol", "atol"):  # tight enough for the 2.5e-8 of tests/test_fmu_plants.py
            assert variables[name].unit is None and variables[name].variability == "fixed", name
            assert 0 < float(variables[name].start) <= 1e-9, name
        # added after every earlier variable: the value references of those do not move
        assert [v.name for v in md.modelVariables][-len(INTEGRATOR):] == list(INTEGRATOR)
        assert variables["max_steps"].type == "Integer"
    if model == "Actuator":  # the saturation limit came last (issue 24): no value reference moved
        assert md.modelVariables[-1].name == "u_max"
        assert max(v.valueReference for v in md.modelVariables) == variables["u_max"].valueReference
    if model == "PendulumPlant":
        assert (variables["x1"].unit, variables["x2"].unit, variables["y"].unit) == ("rad", "rad/s", "rad")
        assert variables["uf"].unit == "N"
    if model == "Reference":  # the third and fourth derivatives came last (issue 35)
        assert [v.name for v in md.modelVariables][-2:] == ["yd_dddot", "yd_ddddot"]
    if model == "ManipulatorPlant":
        assert (variables["x1"].unit, variables["x3"].unit, variables["uf"].unit) == ("rad", "A", "V")
    if model in ORDERS:
        assert {variables[n].type for n in ("mode", "substeps", "discretization", "nn_term")} == {"Integer"}
        # issue 11's parameters, then issue 37's, were added last: the value references of the others
        # do not move
        last = ["discretization", "sample_time", "b_max", "nn_term"]
        assert [v.name for v in md.modelVariables][-4:] == last
    # every unit used is defined, with SI base-unit exponents
    used = {v.unit for v in md.modelVariables if v.unit}
    defined = {u.name: u.baseUnit for u in md.unitDefinitions}
    assert used == set(defined)
    for name, base in defined.items():
        exponents = {
            k: getattr(base, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad") if getattr(base, k)
        }
        assert exponents == SI[name], name


@pytest.mark.parametrize("model", MODELS)
def test_output_dependencies(fmus: dict, model: str) -> None:
    md = fmpy.read_model_description(str(fmus[model]))
    found = {u.variable.name: tuple(d.name for d in u.dependencies) for u in md.outputs}
    assert found == DEPENDENCIES[model]
    # the XML carries an explicit (possibly empty) list for every output
    with zipfile.ZipFile(fmus[model]) as archive:
        xml = archive.read("modelDescription.xml").decode()
    outputs_xml = xml.split("<Outputs>")[1].split("</Outputs>")[0]
    assert outputs_xml.count("dependencies=") == len(DEPENDENCIES[model])
    initial = {u.variable.name for u in md.initialUnknowns}
    assert initial == set(DEPENDENCIES[model])
