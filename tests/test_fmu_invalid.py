# SPDX-License-Identifier: BSD-2-Clause
"""Invalid parameters are rejected at fmi2ExitInitializationMode, never turned into NaN.

pythonfmu turns the raised exception into fmi2Fatal (its binary has no other way to fail an FMI
call); the message names the parameter and its allowed range. The binary forwards it to the
FMI logger only when logging is on, so it also goes to the Python logger of fmu_support.
"""

from __future__ import annotations

import logging

import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException

pytestmark = pytest.mark.system

CASES = [
    ("FixedTimeController", {"beta": 1.2}, "beta must satisfy 0.5 < beta < 1 (got 1.2)"),
    ("FixedTimeController", {"k1": -1.0}, "k1 must satisfy k1 > 0 (got -1.0)"),
    ("FixedTimeController", {"mode": 3}, "mode must be 0 (fixed-time) or 1 (finite-time) (got 3)"),
    ("FixedTimeController", {"alpha": 1.0}, "alpha must satisfy alpha > 1"),
    ("FixedTimeController", {"rho_bar2": 0.0}, "rho_bar2 must satisfy rho_bar2 > 0"),
    ("FixedTimeController", {"eta2_0": -1.0}, "eta2_0 must satisfy eta2_0 >= 0"),
    ("FixedTimeController", {"tau": 0.0}, "tau must satisfy tau > 0"),
    ("FixedTimeController", {"substeps": 0}, "substeps must satisfy substeps >= 1"),
    ("FixedTimeController", {"discretization": 2},
     "discretization must be 0 (explicit) or 1 (semi-implicit) (got 2)"),
    ("FixedTimeController", {"discretization": 1, "sample_time": 0.0},
     "sample_time must satisfy sample_time > 0 (got 0.0)"),
    ("FixedTimeController", {"discretization": 1, "b_max": -3.0}, "b_max must satisfy b_max > 0 (got -3.0)"),
    ("Actuator", {"m_r": -1.0}, "m_r must satisfy m_r > 0 (got -1.0)"),
    ("Actuator", {"K_inf": 0.0}, "K_inf must satisfy K_inf > 0"),
    ("Reference", {"omega": float("inf")}, "omega must be a finite number"),
    ("Example1Plant", {"max_step": 0.0}, "max_step must satisfy max_step > 0 (got 0.0)"),
    ("Example1Plant", {"x1_0": float("nan")}, "x1_0 must be a finite number"),
    ("PendulumPlant", {"M": 0.0}, "M must satisfy M > 0 (got 0.0)"),
    ("PendulumPlant", {"max_step": -1e-3}, "max_step must satisfy max_step > 0"),
    ("Example1Plant", {"method": 2}, "method must be 0 (Dormand-Prince) or 1 (RK4) (got 2)"),
    ("Example1Plant", {"rtol": 0.0}, "rtol must satisfy 0 < rtol < 1 (got 0.0)"),
    ("PendulumPlant", {"atol": -1e-9}, "atol must satisfy atol > 0 (got -1e-09)"),
    ("PendulumPlant", {"rtol": float("nan")}, "rtol must satisfy 0 < rtol < 1 (got nan)"),
]


@pytest.mark.parametrize(("model", "values", "message"), CASES)
def test_invalid_parameter_is_fatal_and_named(
    fmus: dict, model: str, values: dict, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    received = []

    def logger(component: object, instance: bytes, status: int, category: bytes, text: bytes) -> None:
        received.append((status, text.decode()))

    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        with pytest.raises(
            FMICallException, match=r"fmi2ExitInitializationMode failed with status 4 \(fatal\)"
        ):
            simulate_fmu(
                fmus[model],
                stop_time=0.01,
                output_interval=1e-3,
                start_values=values,
                debug_logging=True,
                logger=logger,
            )
    assert any(status == 4 and message in text for status, text in received), received
    assert any(message in record.getMessage() and model in record.getMessage() for record in caplog.records)


def test_all_problems_reported_at_once(fmus: dict, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        with pytest.raises(FMICallException):
            simulate_fmu(
                fmus["FixedTimeController"], stop_time=0.01, start_values={"beta": 1.2, "q2": -1, "mode": 7}
            )
    text = caplog.text
    assert "beta must satisfy" in text and "q2 must satisfy" in text and "mode must be" in text


def test_finite_time_mode_ignores_k(fmus: dict) -> None:
    """k is unused in finite-time mode (SPEC section 1), so k = 0 is accepted there."""
    result = simulate_fmu(
        fmus["FixedTimeController"], stop_time=0.01, start_values={"mode": 1, "k1": 0.0, "k2": 0.0}
    )
    assert len(result) > 0


def test_diverging_plant_step_is_discarded_with_a_message(
    fmus: dict, caplog: pytest.LogCaptureFixture
) -> None:
    """A state that overflows is not returned: doStep gives fmi2Discard (fmpy stops the run there)."""
    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        result = simulate_fmu(
            fmus["Example1Plant"], stop_time=0.01, output_interval=1e-3, start_values={"uf": 1e300}
        )
    assert "step rejected (fmi2Discard)" in caplog.text
    assert len(result) <= 2
