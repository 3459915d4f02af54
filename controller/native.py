# SPDX-License-Identifier: BSD-2-Clause
"""The law's step compiled (``_law.c`` beside this module): the same arithmetic as the Python
reference (:func:`controller.law.evaluate`, :func:`controller.law.derivative`,
:func:`controller.stepping.rk4_step`), giving the same bits, the same exceptions and messages.

Both forms offer one flat interface, :class:`Law` (what a controller FMU calls per communication
step, with no object built per call but the result tuple):

* ``evaluate(state, inputs)`` -> ``(v, z_1..z_n, zeta_1..zeta_n, ptp_1..ptp_n, r', eta_1'..eta_n')``
  for the tuples ``state = (r, eta_1..eta_n)`` and ``inputs = (x_1..x_n, yd, yd', ..., yd^(n))``;
* ``advance(h, first, state, inputs)`` -> ``(r, eta_1..eta_n)`` after one communication step of
  length h with the inputs held; ``first`` is None or ``evaluate``'s result at this state and these
  inputs (its derivative is the first RK4 stage).

:func:`law_for` gives the compiled one (:class:`CompiledLaw`) where it is built and the plant order
is 1..4, else the Python reference (:class:`ReferenceLaw`). The FMU build (:mod:`fmu_src.toolchain.build`)
compiles ``_law.c`` into every controller FMU, so an FMU always steps with it (an FMU that cannot
load it fails to instantiate rather than step slower); in the source tree, where nothing is
compiled, :data:`COMPILED` is False. ``tests/test_controller_native.py`` compares the two.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable
from functools import partial
from typing import Protocol

from .law import _law as _reference_law
from .params import SEMI_IMPLICIT, ControllerParameters
from .stepping import rk4_step

try:
    from . import _law  # type: ignore[attr-defined]  # compiled by the FMU build
except ImportError:
    if __name__.startswith("_ftc_"):  # bundled in an FMU (fmu_src/toolchain/build.py names the package so)
        raise  # a built controller FMU carries it: without it the build is broken, not slower
    _law = None  # the source tree: the Python reference steps

__all__ = ["COMPILED", "MAX_ORDER", "CompiledLaw", "Law", "ReferenceLaw", "law_constants", "law_for",
           "slave_functions"]

COMPILED = _law is not None
MAX_ORDER = 4  # the plant orders the compiled law (and the controller FMUs) support: 1..4


class Law(Protocol):
    """The flat interface of both forms (module docstring)."""

    @property
    def n(self) -> int:
        """The plant order."""

    @property
    def evaluate(self) -> Callable[..., tuple[float, ...]]:
        """``evaluate(state, inputs)``."""

    @property
    def advance(self) -> Callable[..., tuple[float, ...]]:
        """``advance(h, first, state, inputs)``."""


def law_constants(p: ControllerParameters) -> bytes:
    """The constants of ``p`` packed for ``_law.c`` (doubles: n, semi-implicit, neurons, 2 alpha - 1,
    2 beta - 1, a_bar, gamma_gain, gamma_power, d_r, -2 / tau^2, b_max h, NN term on; then k_eff, q, 2 a^2,
    kappa, rho + rho_bar per step; 2 mu_j; (dim_i mu_j) mu_j per step), each computed by the
    expression the Python law uses, so with the same value. ValueError for an order outside 1..4."""
    n = p.n
    if not 1 <= n <= MAX_ORDER:
        raise ValueError(f"the compiled law is built for plant orders n = 1..{MAX_ORDER} (got n = {n})")
    values = [float(n), 1.0 if p.discretization == SEMI_IMPLICIT else 0.0, float(len(p.centers)),
              2.0 * p.alpha - 1.0, 2.0 * p.beta - 1.0, p.a_bar, p.gamma_gain, p.gamma_power, p.d_r,
              -2.0 / (p.width * p.width), p.b_max * p.sample_time, 1.0 if p.nn_term else 0.0]
    values += [*p.k_effective, *p.q, *(2.0 * a * a for a in p.a), *p.kappa]
    values += [rho + bar for rho, bar in zip(p.rho, p.rho_bar, strict=True)]
    values += [2.0 * mu for mu in p.centers]
    values += [(4 + 3 * i) * mu * mu for i in range(n) for mu in p.centers]  # rbf_energy's dim * mu * mu
    return array("d", values).tobytes()


class CompiledLaw:
    """:class:`Law` on ``_law.c`` (requires :data:`COMPILED`; plant orders 1..4)."""

    __slots__ = ("advance", "constants", "evaluate", "n", "substeps")

    def __init__(self, params: ControllerParameters, substeps: int = 1) -> None:
        if _law is None:
            raise RuntimeError("the compiled law _law is not built (it is built into the controller FMUs)")
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1 (got {substeps})")
        constants = law_constants(params)
        self.n = params.n
        # what the controller FMU's compiled step reads (_law.step_slave, fmu_src/controller_core.py)
        self.constants, self.substeps = constants, substeps
        # partial: no Python frame per call
        self.evaluate: partial[tuple[float, ...]] = partial(_law.evaluate, constants)
        self.advance: partial[tuple[float, ...]] = partial(_law.advance, constants, substeps)


class ReferenceLaw:
    """:class:`Law` on the Python reference (any plant order)."""

    __slots__ = ("advance", "evaluate", "n")

    def __init__(self, params: ControllerParameters, substeps: int = 1) -> None:
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1 (got {substeps})")
        n = self.n = params.n

        def parts(state: tuple[float, ...], inputs: tuple[float, ...]
                  ) -> tuple[tuple[float, ...], tuple[float, ...]]:
            for values, count, what in ((state, n + 1, "state (r, eta_hat_1..eta_hat_n)"),
                                        (inputs, 2 * n + 1, "inputs (x1..xn, yd..yd^(n))")):
                if not isinstance(values, tuple):
                    raise TypeError(f"the law of order n = {n} takes {what} as a tuple")
                if len(values) != count:
                    raise TypeError(f"the law of order n = {n} takes {what}: {count} values "
                                    f"(got {len(values)})")
            return inputs[:n], inputs[n:]

        def evaluate_law(state: tuple[float, ...], inputs: tuple[float, ...]) -> tuple[float, ...]:
            x, yd = parts(state, inputs)
            z, zeta, ptp, rates = _reference_law(state, x, yd, params, True)
            return (zeta[-1], *z, *zeta, *ptp, *rates)

        def advance_law(h: float, first: tuple[float, ...] | None, state: tuple[float, ...],
                        inputs: tuple[float, ...]) -> tuple[float, ...]:
            x, yd = parts(state, inputs)
            start = None if first is None else first[3 * n + 1 :]
            return tuple(rk4_step(state, x, yd, params, h, substeps, start))

        self.evaluate = evaluate_law
        self.advance = advance_law


def slave_functions() -> tuple[Callable[..., object], Callable[..., object], object] | None:
    """``_law.step_slave`` and ``_law.refresh_slave``, a controller FMU's step and output refresh on its
    slave's dict (see ``fmu_src/controller_core.py``), and ``_law.direct_calls``, the capsule of their
    C entries for the FMU's shim (``controller/direct_calls.h``); None where the law is not compiled."""
    return None if _law is None else (_law.step_slave, _law.refresh_slave, _law.direct_calls)


def law_for(params: ControllerParameters, substeps: int = 1) -> Law:
    """The compiled law where it is built and ``params.n`` is 1..4, else the Python reference."""
    if COMPILED and 1 <= params.n <= MAX_ORDER:
        return CompiledLaw(params, substeps)
    return ReferenceLaw(params, substeps)
