# SPDX-License-Identifier: BSD-2-Clause
"""RBF basis (eq. 24) against hand-computed values, and the fast P^T P against the basis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.params import DEFAULT_CENTERS
from controller.rbf import rbf_basis, rbf_energy


def test_basis_matches_hand_computed_distances() -> None:
    # X = [1, 0, -1, 0.5], tau = 2 (tau^2 = 4). Squared distances to mu * ones, by hand:
    # mu = -1: 2^2 + 1^2 + 0^2 + 1.5^2 = 7.25;  mu = 0: 1 + 0 + 1 + 0.25 = 2.25;
    # mu = 1: 0 + 1 + 4 + 0.25 = 5.25;          mu = 0.5: 0.25 + 0.25 + 2.25 + 0 = 2.75.
    expected = [math.exp(-7.25 / 4), math.exp(-2.25 / 4), math.exp(-5.25 / 4), math.exp(-2.75 / 4)]
    got = rbf_basis([1.0, 0.0, -1.0, 0.5], [-1.0, 0.0, 1.0, 0.5], 2.0)
    assert got == pytest.approx(expected, rel=1e-15)


def test_basis_at_origin_with_paper_centers() -> None:
    # X = 0 in two dimensions: ||0 - mu * ones||^2 = 2 mu^2, so P_j = exp(-2 mu^2 / 4).
    expected = [math.exp(-mu * mu / 2.0) for mu in (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5)]
    assert rbf_basis([0.0, 0.0], DEFAULT_CENTERS, 2.0) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("dim", [1, 2, 4, 7, 10, 13])
def test_energy_equals_squared_norm_of_basis(dim: int) -> None:
    rng = np.random.default_rng(dim)
    for width in (0.5, 2.0, 3.0):
        for _ in range(20):
            X = rng.uniform(-3.0, 3.0, size=dim)
            basis = np.array(rbf_basis(X, DEFAULT_CENTERS, width))
            got = rbf_energy(float(np.sum(X)), float(np.sum(X * X)), dim, DEFAULT_CENTERS, width)
            assert got == pytest.approx(float(np.sum(basis**2)), rel=1e-12, abs=1e-300)
