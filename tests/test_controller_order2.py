# SPDX-License-Identifier: BSD-2-Clause
"""The n = 2 scalar path (controller.order2, what the controller FMU ran before issue 35) against the
general-n library path (controller.law.evaluate, controller.stepping.AdaptiveController), its
independent oracle: the same law at random states, inputs and gains, and the same states over many
steps, to round-off and (since the general law gives +0.0 at z = 0, issue 35) bit for bit."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from controller.law import evaluate
from controller.order2 import Order2Controller
from controller.params import (
    DEFAULT_CENTERS,
    EXPLICIT,
    FINITE_TIME,
    FIXED_TIME,
    SEMI_IMPLICIT,
    ControllerParameters,
)
from controller.stepping import AdaptiveController
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2

TOLERANCE = 1e-12  # relative, with an absolute floor of the same size

values = st.floats(-3.0, 3.0, allow_nan=False)
positive = st.floats(0.0, 2.0, allow_nan=False)
gain = st.floats(0.1, 30.0)


@st.composite
def parameters(draw: st.DrawFn) -> ControllerParameters:
    """Valid gains of either mode and either discretization (issue 11; sample times from 0.1 to 10 ms,
    so both sides of the semi-implicit law's boundary layer are drawn); the FMU's seven centers, or
    another number (the loop path)."""
    pair = st.tuples(gain, gain)
    centers = draw(st.one_of(st.just(DEFAULT_CENTERS), st.lists(values, min_size=1, max_size=9)))
    return ControllerParameters(
        k=draw(pair), q=draw(pair), a=draw(pair), kappa=draw(pair), rho=draw(pair), rho_bar=draw(pair),
        alpha=draw(st.floats(1.05, 3.0)), beta=draw(st.floats(0.55, 0.95)),
        mode=draw(st.sampled_from([FIXED_TIME, FINITE_TIME])), r0=draw(positive),
        eta0=(draw(positive), draw(positive)), centers=tuple(centers), width=draw(st.floats(0.5, 4.0)),
        discretization=draw(st.sampled_from([EXPLICIT, SEMI_IMPLICIT])),
        sample_time=draw(st.floats(1e-4, 1e-2)), b_max=draw(st.floats(0.2, 5.0)),
        nn_term=draw(st.booleans()),  # issue 37's ablation switch, both ways
    )


def assert_close(fast: float, general: float) -> None:
    assert abs(fast - general) <= TOLERANCE * max(1.0, abs(general)), (fast, general)


@settings(max_examples=300, deadline=None)
@given(params=parameters(), state=st.tuples(positive, positive, positive),
       x=st.tuples(values, values), yd=st.tuples(values, values, values))
@example(params=EXAMPLE1.controller, state=(0.0, 0.0, 0.0), x=(0.5, 0.2), yd=(0.5, 0.1, 0.0))  # z1 = 0
def test_law_equals_the_general_law(params: ControllerParameters, state: tuple, x: tuple, yd: tuple) -> None:
    """The same bits (at z = 0 both give zeta = +0.0; the general law gave -0.0 before issue 35)."""
    general = evaluate(list(state), x, yd, params)
    fast = Order2Controller(params).law(*state, *x, *yd)
    expected = (general.v, *general.z, general.zeta[0], *general.ptp, *general.derivative)
    for a, b in zip(fast, expected, strict=True):
        assert_close(a, b)
        assert struct.pack("<d", a) == struct.pack("<d", b), (a, b)


@settings(max_examples=40, deadline=None)
@given(params=parameters(), seed=st.integers(0, 2**32 - 1), substeps=st.integers(1, 3))
def test_many_steps_equal_the_general_controller(
    params: ControllerParameters, seed: int, substeps: int
) -> None:
    """300 steps of 1 ms with inputs that jump every step (as a sampled loop's): the same states,
    with the output's law reused as the first stage (as the FMU does) and without."""
    rng = np.random.default_rng(seed)
    general = AdaptiveController(params, substeps)
    reused, fresh = Order2Controller(params, substeps), Order2Controller(params, substeps)
    for _ in range(300):
        x, yd = rng.uniform(-2, 2, 2).tolist(), rng.uniform(-1, 1, 3).tolist()
        terms = general.output(x, yd)
        general.advance(x, yd, 1e-3)
        first = reused.stage(*x, *yd)
        assert first[0] == reused.law(reused.r, reused.eta1, reused.eta2, *x, *yd)
        assert_close(first[0][0], terms.v)
        reused.advance(*x, *yd, 1e-3, first)
        fresh.advance(*x, *yd, 1e-3)
        for a, b, c in zip(reused.state, fresh.state, general.state, strict=True):
            assert_close(a, c)
            assert a == b
    assert all(math.isfinite(v) for v in general.state)


@pytest.mark.parametrize("discretization", [EXPLICIT, SEMI_IMPLICIT])
@pytest.mark.parametrize("example", [EXAMPLE1, EXAMPLE2], ids=["example1", "pendulum"])
def test_output_terms_and_reset(example, discretization) -> None:
    params = example.controller.with_changes(discretization=discretization)
    fast, general = Order2Controller(params), AdaptiveController(params)
    x, yd = (0.5, 0.5), (0.0, 0.5, 0.0)
    for _ in range(5):
        fast.advance(*x, *yd, 1e-3)
        general.advance(x, yd, 1e-3)
    a, b = fast.output(x, yd), general.output(x, yd)
    for name in ("v", "z", "zeta", "ptp", "derivative"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=TOLERANCE, atol=TOLERANCE)
    fast.reset()
    assert fast.state == [params.r0, *params.eta0]


@pytest.mark.parametrize("unused", [{"sample_time": 0.0}, {"b_max": 0.0}])
def test_explicit_law_ignores_the_semi_implicit_constants(unused: dict) -> None:
    """The explicit law does not use (nor validate) sample_time and b_max: a zero there evaluates
    and steps as the general path does (hoisting |z1| / (b h) out of the stages once divided by it)."""
    params = EXAMPLE1.controller.with_changes(discretization=EXPLICIT, **unused)
    fast, general = Order2Controller(params), AdaptiveController(params)
    x, yd = (0.5, 0.5), (0.0, 0.5, 0.0)
    for _ in range(3):
        terms = general.output(x, yd)
        assert_close(fast.stage(*x, *yd)[0][0], terms.v)
        fast.advance(*x, *yd, 1e-3, fast.stage(*x, *yd))
        general.advance(x, yd, 1e-3)
        for a, b in zip(fast.state, general.state, strict=True):
            assert_close(a, b)


def test_only_order_two() -> None:
    one = ControllerParameters(k=(1,), q=(1,), a=(1,), kappa=(1,), rho=(1,), rho_bar=(1,))
    with pytest.raises(ValueError, match="n = 2"):
        Order2Controller(one)
    with pytest.raises(ValueError, match="substeps"):
        Order2Controller(EXAMPLE1.controller, substeps=0)
