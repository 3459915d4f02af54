# SPDX-License-Identifier: BSD-2-Clause
"""Reference and Actuator FMUs against the formulas of SPEC sections 2 and 5, through
fmpy.simulate_fmu, fmpy's FMI API and libcosim."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmu_helpers import (
    dead_zone_formula,
    libcosim_add,
    libcosim_execution,
    open_slave,
    reference_formula,
    uf_formula,
)

pytestmark = pytest.mark.system

ACTUATOR = {
    "m_r": 1.0,
    "m_l": 1.2,
    "b_r": 0.5,
    "b_l": 0.6,
    "K_inf": 0.4,
    "K_amp": 0.6,
    "K_rate": 0.2,
    "L_gain": 1.0,
    "L_bias": 0.0,
    "t_fault": 10.0,
}


@pytest.mark.parametrize(
    "parameters",
    [{}, {"amplitude": 1.0, "omega": 0.5, "phase": 0.3, "offset": -0.2}],
)
def test_reference_matches_formula(fmus: dict, parameters: dict) -> None:
    p = {"amplitude": 0.5, "omega": 1.0, "phase": 0.0, "offset": 0.0, **parameters}
    result = simulate_fmu(
        fmus["Reference"], start_time=0.25, stop_time=3.0, output_interval=0.01, start_values=parameters
    )
    expected = np.array([reference_formula(t, **p) for t in result["time"]])
    assert result["time"][0] == 0.25
    for i, name in enumerate(("yd", "yd_dot", "yd_ddot")):
        np.testing.assert_allclose(result[name], expected[:, i], rtol=0, atol=1e-14)


def test_reference_in_libcosim(fmus: dict) -> None:
    from libcosimpy.CosimObserver import CosimObserver

    execution = libcosim_execution(0.01)
    index, refs = libcosim_add(execution, fmus["Reference"], "reference")
    execution.real_initial_value(index, refs["omega"], 2.0)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.step(50)
    values = observer.last_real_values(index, [refs["yd"], refs["yd_dot"], refs["yd_ddot"]])
    np.testing.assert_allclose(values, reference_formula(0.5, 0.5, 2.0, 0.0, 0.0), rtol=0, atol=1e-12)


POINTS = [  # (v, x1, x2): every branch, the break points and just inside / outside them
    (2.0, 0.3, -0.4),
    (0.5, 0.1, 0.2),
    (0.5 + 1e-9, 0.1, 0.2),
    (0.5 - 1e-9, 0.1, 0.2),
    (0.0, 1.0, 2.0),
    (-0.6, -0.5, 0.7),
    (-0.6 + 1e-9, -0.5, 0.7),
    (-0.6 - 1e-9, -0.5, 0.7),
    (-3.0, 2.0, -1.5),
    (770.0, 0.5, 0.5),
]


@pytest.mark.parametrize("t", [0.0, 5.0, 10.0 - 1e-9, 10.0, 10.0 + 1e-9, 12.5, 30.0])
def test_actuator_dead_zone_and_fault(fmus: dict, t: float) -> None:
    """Reach time t exactly (one doStep from 0 to t) and read uf, u_dz for every input point."""
    with open_slave(fmus["Actuator"]) as slave:
        slave.initialize()
        if t > 0:
            slave.step(0.0, t)
        for v, x1, x2 in POINTS:
            slave.set(v=v, x1=x1, x2=x2)
            uf, u_dz = slave.get("uf", "u_dz")
            assert u_dz == pytest.approx(dead_zone_formula(v, ACTUATOR), rel=1e-15, abs=1e-15), (t, v)
            assert uf == pytest.approx(uf_formula(t, v, x1, x2, ACTUATOR), rel=1e-14, abs=1e-15), (t, v)


def test_dead_zone_break_points_exactly(fmus: dict) -> None:
    with open_slave(fmus["Actuator"]) as slave:
        slave.initialize(b_r=0.25, b_l=0.75, m_r=2.0, m_l=3.0)
        for v, expected in [(0.25, 0.0), (-0.75, 0.0), (0.0, 0.0), (1.25, 2.0), (-1.75, -3.0)]:
            slave.set(v=v)
            assert slave.get("u_dz") == [expected]
            assert slave.get("uf") == [v]  # before t_fault: no fault, no dead-zone


def test_fault_switches_on_the_communication_grid(fmus: dict) -> None:
    """On a 1 ms grid the FMU learns t_k as t_{k-1} + h, an ulp away from k h: still faulted at t_fault."""
    h = 1e-3
    with open_slave(fmus["Actuator"]) as slave:
        slave.initialize(start_time=9.990, t_fault=10.0)
        slave.set(v=2.0, x1=0.0, x2=0.0)
        for k in range(9990, 10002):
            t = k * h
            expected = uf_formula(t if abs(t - 10.0) > 1e-12 else 10.0, 2.0, 0.0, 0.0, ACTUATOR)
            assert slave.get("uf")[0] == pytest.approx(expected, rel=1e-12), t
            slave.step(t, h)


def test_actuator_through_simulate_fmu(fmus: dict) -> None:
    """K(t) follows the absolute time; inputs held at constant values through the run."""
    values = {"v": 1.7, "x1": 0.4, "x2": -0.3, "t_fault": 0.5, "K_rate": 2.0}
    p = {**ACTUATOR, **values}
    result = simulate_fmu(fmus["Actuator"], stop_time=2.0, output_interval=0.01, start_values=values)
    expected = [uf_formula(t, 1.7, 0.4, -0.3, p) for t in result["time"]]
    np.testing.assert_allclose(result["uf"], expected, rtol=1e-13)
    np.testing.assert_allclose(result["u_dz"], dead_zone_formula(1.7, p), rtol=1e-15)
    assert result["uf"][0] == 1.7 and result["uf"][-1] != 1.7


def test_outputs_during_initialization_use_the_parameters_set_so_far(fmus: dict) -> None:
    with open_slave(fmus["Reference"]) as reference, open_slave(fmus["Actuator"], "actuator") as actuator:
        reference.fmu.setupExperiment(startTime=1.0)
        reference.fmu.enterInitializationMode()
        reference.set(amplitude=2.0, offset=0.5)
        assert reference.get("yd") == pytest.approx([2.0 * math.sin(1.0) + 0.5], abs=1e-15)
        actuator.fmu.setupExperiment(startTime=0.0)
        actuator.fmu.enterInitializationMode()
        actuator.set(t_fault=0.0, v=2.0, x1=0.0, x2=0.0, K_amp=0.0)
        assert actuator.get("uf") == [pytest.approx(0.4 * 1.5)]  # K_inf (v - b_r)
