# SPDX-License-Identifier: BSD-2-Clause
"""The co-simulated closed loop against the monolithic reference of the controller library.

The orchestrator's default master samples the controller and actuator at t_k and holds them over
the step: the monolithic reference with ``sample_time=h`` computes the same sampled system with
solve_ivp (rtol 1e-10) between samples, so the two differ only by the plant FMU's RK4 error
(about 1e-10 per step with max_step = 25 us). The sampled loop has short chattering bursts
(sig(z)^0.5 terms under a 1 ms or 0.5 ms hold) that amplify such differences: measured over 30 s, plant.y
stays within 1e-8 for the first second and within 5e-4 overall. Against the continuous
controller of the paper the zero-order hold itself is the difference, O(h): about 0.01 (Example 1
at 1 ms; the pendulum at 0.5 ms likewise, 0.025 at 1 ms) at the stiff start, when |v| is in the
hundreds or thousands. Measured for the pendulum at its 0.5 ms step: 5.7e-9 in the first second,
9.8e-5 over 30 s, 0.010 against the continuous law.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from references import group, reference

import orchestrator
from controller.params import SEMI_IMPLICIT

REPO = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.system


# (scenario, example, the communication step the scenario ships with)
@pytest.mark.parametrize(("scenario", "number", "step"), [pytest.param("example1", 1, 1e-3, marks=group(1)),
                                                         pytest.param("pendulum", 2, 5e-4, marks=group(2))])
def test_cosimulated_plant_output_matches_the_monolithic_reference(built, scenario, number, step):
    cosim = orchestrator.run(built / "ssp" / f"{scenario}.ssp").rows
    sampled = reference(number, sample_time=step)
    continuous = reference(number)
    # The master's grid is the double nearest to k*h (integer nanoseconds); the reference's is k*h.
    assert np.max(np.abs(cosim["time"] - sampled["time"])) <= 1e-12
    early = cosim["time"] <= 1.0
    deviation = np.abs(cosim["plant.y"] - sampled["y"])
    every = round(1e-3 / step)  # the continuous law is recorded on the 1 ms grid
    assert np.max(np.abs(cosim["time"][::every] - continuous["time"])) <= 1e-12
    to_continuous = np.abs(cosim["plant.y"][::every] - continuous["y"])
    print(f"{scenario}: max |plant.y - y_ref| first 1 s {deviation[early].max():.2e}, "
          f"0-30 s {deviation.max():.2e}; against the continuous law {to_continuous.max():.2e}")
    assert deviation[early].max() <= 1e-6
    assert deviation.max() <= 2e-3
    assert to_continuous.max() <= 0.05


@pytest.mark.parametrize(("scenario", "number", "step"),
                         [pytest.param("example1_smooth", 1, 1e-3, marks=group(1)),
                          pytest.param("pendulum_smooth", 2, 5e-4, marks=group(2))])
def test_semi_implicit_cosimulation_matches_the_monolithic_discrete_law(built, scenario, number, step):
    """Issue 11: the co-simulated semi-implicit controller FMU (the n = 2 path) against the monolithic
    reference of the same discrete law (the general-n library law, solve_ivp between samples), to the
    tolerances of the test above; without chattering bursts nothing amplifies the plant's integrator
    error, so they agree far closer: measured 3.3e-12 (example1_smooth) and 2.6e-13 (pendulum_smooth)
    in plant.y over 30 s, against up to 5e-4 for the explicit law, so 1e-9 is asserted too."""
    cosim = orchestrator.run(built / "ssp" / f"{scenario}.ssp").rows
    sampled = reference(number, sample_time=step, discretization=SEMI_IMPLICIT)
    assert np.max(np.abs(cosim["time"] - sampled["time"])) <= 1e-12
    early = cosim["time"] <= 1.0
    deviation = np.abs(cosim["plant.y"] - sampled["y"])
    v_deviation = np.abs(cosim["controller.v"] - sampled["v"])
    print(f"{scenario}: max |plant.y - y_ref| first 1 s {deviation[early].max():.2e}, 0-30 s "
          f"{deviation.max():.2e}; max |v - v_ref| after 1 s {v_deviation[~early].max():.2e}")
    assert deviation[early].max() <= 1e-6
    assert deviation.max() <= 1e-9  # inside the 2e-3 of the explicit scenarios above
