# SPDX-License-Identifier: BSD-2-Clause
"""The law's compiled step (controller/_law.c, controller.native.CompiledLaw) against the Python
reference (controller.law, controller.stepping.rk4_step through controller.native.ReferenceLaw), a
second implementation of the same arithmetic: the same bits of every result and the same exception
and message, on random gains of every order 1..4 (both laws, both discretizations, any number of
RBF neurons), random states and inputs from tiny to overflowing."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator
from types import ModuleType

import pytest
from fmu_helpers import compiled_extension
from hypothesis import given, settings
from hypothesis import strategies as st

from controller import native
from controller.law import InputError
from controller.params import (
    DEFAULT_CENTERS,
    EXPLICIT,
    FINITE_TIME,
    FIXED_TIME,
    SEMI_IMPLICIT,
    ControllerParameters,
)
from controller.stepping import AdaptiveController
from fmu_src.models.examples import EXAMPLE1


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """_law.c compiled as the FMU build compiles it, loaded as the one controller.native uses."""
    module = compiled_extension("controller._law", tmp_path_factory.mktemp("law"))
    saved = native._law, native.COMPILED
    native._law, native.COMPILED = module, True
    yield module
    native._law, native.COMPILED = saved


def bits(values: object) -> object:
    """Floats as their IEEE bytes (-0.0 differs from 0.0), every nan as "nan": IEEE 754 leaves the
    sign and payload of a nan produced by an operation open, and compilers may swap the operands of
    a commutative operation; anything else as it is."""
    if isinstance(values, tuple) and all(isinstance(v, float) for v in values):
        return tuple("nan" if math.isnan(v) else struct.pack("<d", v) for v in values)
    return values


def outcome(call: Callable[..., tuple[float, ...]], *args: object) -> object:
    """The result's bits, or the exception's type and message."""
    try:
        return bits(call(*args))
    except (ArithmeticError, ValueError, TypeError) as error:
        return type(error).__name__, str(error)


gain = st.floats(0.1, 30.0)
small = st.floats(-3.0, 3.0, allow_nan=False)
# from the loops' values to ones whose powers overflow (|z|^(2 alpha - 1), |x1|^4) and subnormal ones
wide = st.one_of(small, st.floats(-1e4, 1e4), st.floats(-1e80, 1e80), st.floats(-1e200, 1e200),
                 st.sampled_from([0.0, -0.0, 1e-310, -1e-200, math.inf, -math.inf, math.nan]))


@st.composite
def parameters(draw: st.DrawFn, n: int | None = None) -> ControllerParameters:
    """Valid gains of either law and either discretization (sample times from 0.1 to 10 ms: both
    sides of the semi-implicit boundary layer), plant order 1..4, seven or 1-9 RBF neurons, the NN
    term on or off (issue 37)."""
    order = draw(st.integers(1, 4)) if n is None else n
    per_step = st.tuples(*[gain] * order)
    centers = draw(st.one_of(st.just(DEFAULT_CENTERS), st.lists(small, min_size=1, max_size=9)))
    return ControllerParameters(
        k=draw(per_step), q=draw(per_step), a=draw(per_step), kappa=draw(per_step), rho=draw(per_step),
        rho_bar=draw(per_step), alpha=draw(st.floats(1.05, 3.0)), beta=draw(st.floats(0.55, 0.95)),
        mode=draw(st.sampled_from([FIXED_TIME, FINITE_TIME])), r0=draw(st.floats(0.0, 2.0)),
        eta0=draw(st.tuples(*[st.floats(0.0, 2.0)] * order)), centers=tuple(centers),
        width=draw(st.floats(0.5, 4.0)), gamma_power=draw(st.sampled_from([4.0, 2.0, 0.0, 2.5])),
        discretization=draw(st.sampled_from([EXPLICIT, SEMI_IMPLICIT])),
        sample_time=draw(st.floats(1e-4, 1e-2)), b_max=draw(st.floats(0.2, 50.0)),
        nn_term=draw(st.booleans()),
    )


@st.composite
def law_arguments(draw: st.DrawFn, values: st.SearchStrategy[float]
                  ) -> tuple[ControllerParameters, tuple[float, ...], tuple[float, ...]]:
    """Gains, the state r, eta_hat_1..n (non-negative, as the law keeps them) and the inputs x1..xn,
    yd..yd^(n)."""
    params = draw(parameters())
    n = params.n
    state = tuple(abs(draw(values)) for _ in range(n + 1))
    return params, state, tuple(draw(values) for _ in range(2 * n + 1))


@settings(max_examples=600, deadline=None)
@given(case=law_arguments(wide), substeps=st.integers(1, 3), h=st.sampled_from([1e-3, 5e-4, 1e-2]))
def test_compiled_law_gives_the_references_bits_and_errors(compiled, case, substeps, h) -> None:
    params, state, inputs = case
    fast, reference = native.CompiledLaw(params, substeps), native.ReferenceLaw(params, substeps)
    terms = outcome(fast.evaluate, state, inputs)
    assert terms == outcome(reference.evaluate, state, inputs)
    assert outcome(fast.advance, h, None, state, inputs) == outcome(reference.advance, h, None, state, inputs)
    if isinstance(terms[0], bytes):  # the law evaluated: reused as the first stage
        first = fast.evaluate(state, inputs)
        assert outcome(fast.advance, h, first, state, inputs) == outcome(reference.advance, h, first, state,
                                                                         inputs)


@settings(max_examples=60, deadline=None)
@given(params=parameters(), seed=st.integers(0, 2**32 - 1), substeps=st.integers(1, 2))
def test_many_steps_equal_the_library_controller(compiled, params, seed, substeps) -> None:
    """300 steps of 1 ms with inputs that jump every step (a sampled loop's), the output's law reused
    as the first stage (as the FMU does): the states of AdaptiveController, bit for bit. Where the
    law's cascade of powers overflows (order 4, alpha 3, k_1 = 2: z_4 ~ z_1^125, with the NN term or
    without), the compiled law raises the library's error at the same step."""
    import random

    rng = random.Random(seed)
    n = params.n
    law = native.CompiledLaw(params, substeps)
    library = AdaptiveController(params, substeps)
    state = tuple(library.state)
    for _ in range(300):
        x = [rng.uniform(-2, 2) for _ in range(n)]
        yd = [rng.uniform(-1, 1) for _ in range(n + 1)]
        try:
            terms = library.output(x, yd)
        except OverflowError as error:
            assert outcome(law.evaluate, state, (*x, *yd)) == (type(error).__name__, str(error))
            return
        stage = law.evaluate(state, (*x, *yd))
        assert bits(stage) == bits((terms.v, *terms.z, *terms.zeta, *terms.ptp, *terms.derivative))
        try:
            library.advance(x, yd, 1e-3)
        except OverflowError as error:
            assert outcome(law.advance, 1e-3, stage, state, (*x, *yd)) == (type(error).__name__, str(error))
            return
        state = law.advance(1e-3, stage, state, (*x, *yd))
        assert bits(state) == bits(tuple(library.state))
    assert all(math.isfinite(v) for v in state)


def test_inputs_that_do_not_fit_the_order_are_refused(compiled) -> None:
    """One line each, the same from both forms; the library's controller names what it needs."""
    params = EXAMPLE1.controller
    for law in (native.CompiledLaw(params), native.ReferenceLaw(params)):
        error = outcome(law.evaluate, (0.0, 0.0, 0.0), (0.5, 0.5, 0.0, 0.5))  # yd'' missing
        assert error == ("TypeError", "the law of order n = 2 takes inputs (x1..xn, yd..yd^(n)): 5 values "
                                      "(got 4)")
        error = outcome(law.advance, 1e-3, None, [0.0, 0.0, 0.0], (0.5, 0.5, 0.0, 0.5, 0.0))
        assert error == ("TypeError", "the law of order n = 2 takes state (r, eta_hat_1..eta_hat_n) as a "
                                      "tuple")
    library = AdaptiveController(params)
    with pytest.raises(InputError, match=r"^x must have n = 2 entries x1\.\.x2 \(got 3\)") as error:
        library.output([0.5, 0.5, 0.1], [0.0, 0.5, 0.0])
    assert "\n" not in str(error.value)
    with pytest.raises(InputError, match=r"^yd must have n \+ 1 = 3 entries.*\(got 2\)$"):
        library.advance([0.5, 0.5], [0.0, 0.5], 1e-3)


def test_orders_outside_one_to_four_run_on_the_reference(compiled) -> None:
    five = ControllerParameters(k=(1,) * 5, q=(1,) * 5, a=(1,) * 5, kappa=(1,) * 5, rho=(1,) * 5,
                                rho_bar=(1,) * 5)
    with pytest.raises(ValueError, match=r"plant orders n = 1\.\.4 \(got n = 5\)"):
        native.CompiledLaw(five)
    assert isinstance(native.law_for(five), native.ReferenceLaw)
    assert isinstance(native.law_for(EXAMPLE1.controller), native.CompiledLaw)


def test_source_tree_runs_the_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the compiled module (the source tree) law_for gives the Python reference."""
    monkeypatch.setattr(native, "_law", None)
    monkeypatch.setattr(native, "COMPILED", False)
    assert isinstance(native.law_for(EXAMPLE1.controller), native.ReferenceLaw)
    with pytest.raises(RuntimeError, match="not built"):
        native.CompiledLaw(EXAMPLE1.controller)
