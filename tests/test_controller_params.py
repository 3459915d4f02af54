# SPDX-License-Identifier: BSD-2-Clause
"""Every design constraint of SPEC section 1 is rejected with the parameter, its value and the range."""

from __future__ import annotations

import math

import pytest

from controller.params import (
    FINITE_TIME,
    FIXED_TIME,
    ControllerParameters,
    ParameterError,
)
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2

GAINS = ("k", "q", "a", "kappa", "rho", "rho_bar")


def test_examples_are_valid_and_second_order() -> None:
    for params in (EXAMPLE1.controller, EXAMPLE2.controller):
        assert params.n == 2
        assert params.mode == FIXED_TIME
        assert params.eta0 == (0.0, 0.0)
        assert params.r0 == 0.0


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"alpha": 1.0}, ["alpha", "alpha > 1", "1.0"]),
        ({"alpha": 0.5}, ["alpha", "alpha > 1", "0.5"]),
        ({"alpha": math.nan}, ["alpha", "alpha > 1", "nan"]),
        ({"alpha": math.inf}, ["alpha", "alpha > 1", "inf"]),
        ({"beta": 0.5}, ["beta", "0.5 < beta < 1", "0.5"]),
        ({"beta": 1.0}, ["beta", "0.5 < beta < 1", "1.0"]),
        ({"beta": 1.2}, ["beta", "0.5 < beta < 1", "1.2"]),
        ({"beta": 0.2}, ["beta", "0.5 < beta < 1", "0.2"]),
        ({"beta": math.nan}, ["beta", "0.5 < beta < 1", "nan"]),
        ({"mode": "fast"}, ["mode", "fixed-time", "finite-time", "'fast'"]),
        ({"a_bar": 0.0}, ["a_bar", "a_bar > 0", "0.0"]),
        ({"width": -2.0}, ["width", "width > 0", "-2.0"]),
        ({"gamma_gain": -1.0}, ["gamma_gain", ">= 0", "-1.0"]),
        ({"d_r": math.nan}, ["d_r", ">= 0", "nan"]),
        ({"r0": -0.1}, ["r0", ">= 0", "-0.1"]),
        ({"eta0": (0.0, -1.0)}, ["eta0[2]", ">= 0", "-1.0"]),
    ],
)
def test_scalar_constraints(changes: dict, expected: list[str]) -> None:
    with pytest.raises(ParameterError) as info:
        EXAMPLE1.controller.with_changes(**changes)
    for text in expected:
        assert text in str(info.value)


@pytest.mark.parametrize("name", GAINS)
@pytest.mark.parametrize("index", [1, 2])
@pytest.mark.parametrize("bad", [0.0, -3.0, math.nan, math.inf])
def test_each_gain_must_be_positive_per_index(name: str, index: int, bad: float) -> None:
    values = list(getattr(EXAMPLE1.controller, name))
    values[index - 1] = bad
    with pytest.raises(ParameterError) as info:
        EXAMPLE1.controller.with_changes(**{name: tuple(values)})
    message = str(info.value)
    assert f"{name}[{index}]" in message
    assert f"{name}[{index}] > 0" in message
    assert f"(got {bad!r})" in message


@pytest.mark.parametrize("name", ("k", "a", "kappa", "rho", "rho_bar", "eta0"))
def test_wrong_lengths(name: str) -> None:
    with pytest.raises(ParameterError) as info:
        EXAMPLE1.controller.with_changes(**{name: (1.0, 1.0, 1.0)})
    assert f"{name} must have n = 2 entries (got 3)" in str(info.value)


def test_q_defines_the_order() -> None:
    # n = len(q): a three-entry q makes every other per-step tuple the wrong length.
    with pytest.raises(ParameterError) as info:
        EXAMPLE1.controller.with_changes(q=(1.0, 1.0, 1.0))
    for name in ("k", "a", "kappa", "rho", "rho_bar", "eta0"):
        assert f"{name} must have n = 3 entries (got 2)" in str(info.value)
    with pytest.raises(ParameterError, match="q must have at least one entry"):
        ControllerParameters(k=(), q=(), a=(), kappa=(), rho=(), rho_bar=())


def test_every_problem_is_reported_at_once() -> None:
    with pytest.raises(ParameterError) as info:
        EXAMPLE1.controller.with_changes(alpha=0.9, beta=1.5, q=(8.0, -8.0))
    message = str(info.value)
    assert "alpha" in message and "beta" in message and "q[2]" in message


def test_parameter_error_is_a_value_error() -> None:
    assert issubclass(ParameterError, ValueError)


def test_finite_time_mode_ignores_k() -> None:
    params = EXAMPLE1.controller.with_changes(mode=FINITE_TIME, k=(0.0, 0.0))
    assert params.k_effective == (0.0, 0.0)
    assert EXAMPLE1.controller.k_effective == (10.0, 10.0)


def test_with_changes_validates() -> None:
    with pytest.raises(ParameterError, match="beta"):
        EXAMPLE2.controller.with_changes(beta=2.0)


def test_order_one_is_supported() -> None:
    params = ControllerParameters(k=(1,), q=(1,), a=(1,), kappa=(1,), rho=(1,), rho_bar=(1,))
    assert params.n == 1 and params.eta0 == (0.0,)
