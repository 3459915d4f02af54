# SPDX-License-Identifier: BSD-2-Clause
"""Gaussian RBF network basis of the paper (eq. 24) and the fast form of P^T P the law uses."""

from __future__ import annotations

from collections.abc import Sequence

from .fmath import exp

__all__ = ["rbf_basis", "rbf_energy"]


def rbf_basis(X: Sequence[float], centers: Sequence[float], width: float) -> list[float]:
    """Basis vector P(X): neuron j is exp(-||X - mu_j * ones||^2 / tau^2) (eq. 24).

    Plain floats: the controller FMU carries no third-party package (no NumPy)."""
    return [exp(-sum((float(x) - mu) * (float(x) - mu) for x in X) / (width * width)) for mu in centers]


def rbf_energy(s1: float, s2: float, dim: int, centers: Sequence[float], width: float) -> float:
    """P^T P from s1 = sum(X) and s2 = sum(X^2) alone.

    Because every center is mu_j * ones, ||X - mu_j||^2 = s2 - 2 mu_j s1 + dim mu_j^2, so the
    law never needs the vector X itself: this is what keeps one controller step cheap.
    """
    scale = -2.0 / (width * width)
    total = 0.0
    for mu in centers:  # a plain loop: about twice as fast as sum() over a generator
        total += exp(scale * (s2 - 2.0 * mu * s1 + dim * mu * mu))
    return total
