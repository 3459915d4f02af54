# SPDX-License-Identifier: BSD-2-Clause
"""Issue 45, item 1: how often the semi-implicit cap replaced the paper's law, from a run's outputs.

Oracle: the paper's feedback magnitude phi_i = k_i |z_i|^(2 alpha - 1) + q_i |z_i|^(2 beta - 1) +
eta_hat_i |z_i| P_i^T P_i / (2 a_i^2) (eq. 37, 54, 68) written out here and compared with the cap
|z_i| / (b_max h) at every sample: the cap binds where phi_i is the larger. The rows are the law's
own outputs (z_i, zeta_i, v) at states along a trajectory, as the FMU records them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.law import evaluate
from controller.params import SEMI_IMPLICIT, ControllerParameters
from orchestrator.experiments.caps import (
    CAP_NAMES,
    LIMIT_NAME,
    Sampling,
    cap_cell,
    cap_fractions,
    rows_cap_cell,
    scenario_sampling,
)


def _rows(params: ControllerParameters, states: list[tuple[list[float], list[float], list[float]]]
          ) -> tuple[np.ndarray, list[list[bool]]]:
    """The recorded outputs of the law at ``states`` (state, x, yd) and, per step, whether phi_i
    exceeds the cap there (the oracle)."""
    n = params.n
    names = ["controller.v", *(f"controller.z{i}" for i in range(1, n + 1)),
             *(f"controller.zeta{i}" for i in range(1, n))]
    rows = np.zeros(len(states), dtype=[(name, float) for name in names])
    truth: list[list[bool]] = [[] for _ in range(n)]
    bh = params.b_max * params.sample_time
    for k, (state, x, yd) in enumerate(states):
        terms = evaluate(state, x, yd, params)
        rows["controller.v"][k] = terms.v
        for i in range(n):
            rows[f"controller.z{i + 1}"][k] = terms.z[i]
            if i < n - 1:
                rows[f"controller.zeta{i + 1}"][k] = terms.zeta[i]
            a = abs(terms.z[i])
            phi = (params.k[i] * a ** (2 * params.alpha - 1) + params.q[i] * a ** (2 * params.beta - 1)
                   + state[1 + i] * a * terms.ptp[i] / (2 * params.a[i] ** 2))
            truth[i].append(phi > a / bh)
    return rows, truth


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_the_share_is_the_samples_where_phi_exceeds_the_cap(n: int) -> None:
    params = ControllerParameters(k=(10.0,) * n, q=(8.0,) * n, a=(5.0,) * n, kappa=(2.0,) * n,
                                  rho=(2.0,) * n, rho_bar=(1.0,) * n, beta=0.9,
                                  discretization=SEMI_IMPLICIT, sample_time=1e-3, b_max=50.0)
    rng = np.random.default_rng(45 + n)
    states = []
    for scale in np.geomspace(1e-6, 5.0, 60):  # from deep inside the boundary layer to far outside
        yd = list(rng.normal(0.0, 0.1, n + 1))
        state = [0.3, *rng.uniform(0.0, 2.0, n)]
        x = [yd[0] + rng.normal(0.0, scale)] + [0.0] * (n - 1)
        for i in range(1, n):  # z_(i+1) of the same scale: x_(i+1) near the virtual control zeta_i
            x[i] = evaluate(state, x, yd, params).zeta[i - 1] + rng.normal(0.0, scale)
        states.append((state, x, yd))
    rows, truth = _rows(params, states)
    shares = cap_fractions(rows, {}, Sampling(SEMI_IMPLICIT, 1e-3, 50.0))
    for i in range(n):
        expected = float(np.mean(truth[i]))
        assert 0.0 < expected < 1.0  # both cases occur
        assert shares[CAP_NAMES[i]] == expected
    assert all(math.isnan(shares[name]) for name in CAP_NAMES[n:])
    assert math.isnan(shares[LIMIT_NAME])
    # the run's overrides win over the scenario's sampling: another b_max, another share
    other = cap_fractions(rows, {"controller.b_max": 5000.0}, Sampling(SEMI_IMPLICIT, 1e-3, 50.0))
    assert other[CAP_NAMES[0]] != shares[CAP_NAMES[0]]
    # an explicit run has no cap
    explicit = cap_fractions(rows, {"controller.discretization": 0}, Sampling(SEMI_IMPLICIT, 1e-3, 50.0))
    assert all(math.isnan(explicit[name]) for name in CAP_NAMES)


def test_the_limit_share_counts_samples_beyond_u_max() -> None:
    rows = np.zeros(4, dtype=[("controller.v", float), ("controller.z1", float)])
    rows["controller.v"] = [-300.0, 50.0, 100.0, 101.0]
    shares = cap_fractions(rows, {"actuator.u_max": 100.0}, Sampling(0, 1e-3, 1.0))
    assert shares[LIMIT_NAME] == 0.5 and math.isnan(shares[CAP_NAMES[0]])


def test_the_cell_says_when_the_law_never_acted() -> None:
    never = "1 / 1 (v = the cap at every sample: the paper's law never acted)"
    assert cap_cell([[1.0, 1.0], [1.0, 1.0]]) == never
    assert cap_cell([[0.5, 0.25], [0.0, 1.0]]) == "0.375 / 0.5"
    assert cap_cell([[math.nan], [math.nan]]) == "-"
    rows = [{"cap1_active": 0.1, "cap2_active": 0.2, "cap3_active": None, "cap4_active": None},
            {"cap1_active": 0.3, "cap2_active": 0.4, "cap3_active": None, "cap4_active": None}]
    assert rows_cap_cell(rows) == "0.2 / 0.3"


def test_the_scenarios_sampling_is_their_parameter_files() -> None:
    """The shipped scenarios: example1_smooth at 1 ms with b_max 3, pendulum_smooth at 0.5 ms with
    b_max 1, the manipulator at 1 ms with b_max 70 (issue 45), example1 explicit."""
    assert scenario_sampling("example1_smooth") == Sampling(SEMI_IMPLICIT, 1e-3, 3.0)
    assert scenario_sampling("pendulum_smooth") == Sampling(SEMI_IMPLICIT, 5e-4, 1.0)
    assert scenario_sampling("manipulator") == Sampling(SEMI_IMPLICIT, 1e-3, 70.0)
    assert scenario_sampling("example1").discretization == 0
