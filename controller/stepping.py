# SPDX-License-Identifier: BSD-2-Clause
"""A stepping interface for a sampled controller: the shape an FMU wraps.

At a communication point the caller reads ``output(x, yd)``; then ``advance(x, yd, h)``
integrates the controller's own states (r and eta_hat) over [t, t + h] with those inputs held
(zero-order hold), by classical Runge-Kutta 4 with ``substeps`` equal sub-steps. The local error
is O((h/substeps)^5): with h = 1 ms the states agree with ``solve_ivp`` at rtol 1e-12 to about
1e-12 relative (tests/test_controller_stepping.py measures it).

``output`` and the first RK4 stage of ``advance`` evaluate the law at the same state and inputs;
``advance`` reuses the evaluation of ``output`` when state and inputs are equal in value.
"""

from __future__ import annotations

from collections.abc import Sequence

from .law import ControlTerms, check_inputs, derivative, evaluate
from .params import ControllerParameters

__all__ = ["AdaptiveController", "rk4_step"]


class AdaptiveController:
    """The adaptive fixed-time (or finite-time) controller with its states r and eta_hat."""

    def __init__(self, params: ControllerParameters, substeps: int = 1) -> None:
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1 (got {substeps})")
        self.params = params
        self.substeps = substeps
        self.state: list[float] = []
        self.last: ControlTerms | None = None
        self._last_arguments: tuple[tuple[float, ...], ...] = ()
        self.reset()

    def reset(self) -> None:
        """Back to the initial values r0 and eta0."""
        eta0 = self.params.eta0
        assert eta0 is not None  # ControllerParameters.__post_init__ always fills it
        self.state = [self.params.r0, *eta0]
        self.last = None
        self._last_arguments = ()

    @property
    def r(self) -> float:
        """The dynamic signal r (eq. 20)."""
        return self.state[0]

    @property
    def eta_hat(self) -> tuple[float, ...]:
        """The adaptive estimates eta_hat_1..eta_hat_n."""
        return tuple(self.state[1:])

    def output(self, x: Sequence[float], yd: Sequence[float]) -> ControlTerms:
        """The control v and its intermediate terms for the current state and these inputs."""
        self.last = evaluate(self.state, x, yd, self.params)
        self._last_arguments = (tuple(self.state), tuple(x), tuple(yd))
        return self.last

    def advance(self, x: Sequence[float], yd: Sequence[float], h: float) -> None:
        """Integrate r and eta_hat over a step of length h with x and yd held (RK4)."""
        # The law at this state and these inputs, if output() has just evaluated it.
        y = self.state
        terms = self.last if self._last_arguments == (tuple(y), tuple(x), tuple(yd)) else None
        first = None if terms is None else terms.derivative
        self.state = rk4_step(y, x, yd, self.params, h, self.substeps, first)


def rk4_step(
    state: Sequence[float],
    x: Sequence[float],
    yd: Sequence[float],
    p: ControllerParameters,
    h: float,
    substeps: int = 1,
    first: Sequence[float] | None = None,
) -> list[float]:
    """``[r, eta_hat_1..eta_hat_n]`` after a step of length h with x and yd held: ``substeps`` classical
    RK4 steps; ``first``, if given, is the state derivative at ``state`` (the first stage)."""
    check_inputs(x, yd, p.n)
    dt = h / substeps
    y = list(state)
    m = len(y)
    for _ in range(substeps):
        k1 = first if first is not None else derivative(y, x, yd, p)
        first = None
        k2 = derivative([y[j] + 0.5 * dt * k1[j] for j in range(m)], x, yd, p)
        k3 = derivative([y[j] + 0.5 * dt * k2[j] for j in range(m)], x, yd, p)
        k4 = derivative([y[j] + dt * k3[j] for j in range(m)], x, yd, p)
        y = [y[j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]) for j in range(m)]
    return y
