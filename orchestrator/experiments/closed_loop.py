# SPDX-License-Identifier: BSD-2-Clause
"""Monolithic closed-loop reference simulation of the paper's examples (and of the manipulator,
:data:`~fmu_src.models.examples.MANIPULATOR`, the order-3 loop of issue 35).

Plant + unmodeled dynamics + actuator fault + dead-zone + controller in one ODE, solved with
``solve_ivp`` at tight tolerances. It is the oracle the co-simulation is compared with. The plant,
actuator and reference math are the very functions the FMUs wrap (``fmu_src.models``, pure math,
no FMI); the control law is ``controller``'s.

Two forms:

* ``sample_time=None``: the continuous controller of the paper (v evaluated at every instant);
* ``sample_time=h``: the sampled system a co-simulation computes: at ``t_k = k h`` the controller
  output v and the actuator output uf are evaluated from the states at ``t_k`` and held over
  ``[t_k, t_k + h]`` while ``solve_ivp`` integrates the plant and the controller's states.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
from scipy.integrate import solve_ivp

from controller.law import evaluate
from controller.params import FINITE_TIME, FIXED_TIME, ControllerParameters, Mode
from fmu_src.models.actuator import actuator_output
from fmu_src.models.examples import EXAMPLES, Example
from fmu_src.models.reference import reference_derivatives

__all__ = ["ReferenceRun", "SolverError", "simulate"]

RTOL = 1e-10
ATOL = 1e-12
# The fields of a run of the examples (n = 2), in the order of the result columns.
FIELDS = ("time", "x1", "x2", "z", "y", "yd", "v", "uf", "u_dz", "r", "eta1_hat", "eta2_hat", "z1", "z2")


def fields_of(ex: Example, n: int) -> tuple[str, ...]:
    """The result columns of a run of ``ex`` with a controller of order n (:data:`FIELDS` for the
    examples): time, the plant's three states, y, yd, v, uf, u_dz, r, eta_hat_i and z_i."""
    return ("time", *ex.states, "y", "yd", "v", "uf", "u_dz", "r", *(f"eta{i}_hat" for i in range(1, n + 1)),
            *(f"z{i}" for i in range(1, n + 1)))


@dataclass
class ReferenceRun:
    """Samples of a reference run on a uniform grid, as a NumPy structured array."""

    example: Example
    controller: ControllerParameters
    sample_time: float | None
    data: np.ndarray = field(repr=False)


def _controller_inputs(t: float, y: np.ndarray | list[float], ex: Example, n: int
                       ) -> tuple[list[float], tuple[float, ...]]:
    """The controller's inputs: the first n plant states, yd and its n derivatives."""
    return [y[i] for i in range(n)], reference_derivatives(t, ex.reference)[: n + 1]


def _seq(values: np.ndarray | list[float]) -> Sequence[float]:
    """An array (or list) where the law and the plant models take a ``Sequence[float]``: they only
    index it, so it serves as it is (their annotations name no arrays)."""
    return cast(Sequence[float], values)


def _outputs(t: float, y: np.ndarray | list[float], ex: Example, params: ControllerParameters) -> tuple:
    """(v, uf, u_dz, terms) for the full state y = [x1, x2, x3 or z, r, eta_1..eta_n] at time t."""
    x, yd = _controller_inputs(t, y, ex, params.n)
    terms = evaluate(_seq(y[3:]), x, yd, params)
    uf, u_dz = actuator_output(t, terms.v, y[0], y[1], ex.actuator)
    return terms.v, uf, u_dz, terms


def _continuous_rhs(t: float, y: np.ndarray, ex: Example, params: ControllerParameters) -> list[float]:
    # Python floats: the models' scalar arithmetic on NumPy scalars costs about twice as much.
    values = y.tolist()
    _, uf, _, terms = _outputs(t, values, ex, params)
    return [*ex.plant_rhs(t, values[:3], uf), *terms.derivative]


def _held_rhs(t: float, y: np.ndarray, ex: Example, params: ControllerParameters, x, yd, uf) -> list[float]:
    """Plant driven by the held uf; controller states driven by the held inputs x, yd."""
    values = y.tolist()  # Python floats, as in _continuous_rhs
    return [*ex.plant_rhs(t, values[:3], uf), *evaluate(values[3:], x, yd, params).derivative]


def _record(t: float, y: np.ndarray, ex: Example, params: ControllerParameters) -> tuple:
    v, uf, u_dz, terms = _outputs(t, y, ex, params)
    yd = reference_derivatives(t, ex.reference)[0]
    return (t, y[0], y[1], y[2], y[0], yd, v, uf, u_dz, *(y[3 + i] for i in range(params.n + 1)), *terms.z)


def simulate(
    example: Example,
    controller: ControllerParameters | None = None,
    stop_time: float | None = None,
    sample_time: float | None = None,
    grid: float = 1e-3,
) -> ReferenceRun:
    """Run the closed loop from t = 0 and sample it every ``grid`` seconds.

    With ``sample_time`` the controller and actuator are sampled with a zero-order hold (the
    co-simulation's semantics); ``grid`` must then equal ``sample_time``.
    """
    params = controller or example.controller
    if params.n != example.controller.n:
        raise ValueError(f"{example.name} is a plant of order {example.controller.n}; controller has "
                         f"n = {params.n}")
    stop = example.stop_time if stop_time is None else stop_time
    steps = round(stop / grid)
    if not math.isclose(steps * grid, stop, rel_tol=1e-12):
        raise ValueError(f"stop time {stop} is not a whole number of grid steps {grid}")
    times = [k * grid for k in range(steps + 1)]
    assert params.eta0 is not None  # ControllerParameters.__post_init__ always fills it
    y0 = np.array([*example.x0, params.r0, *params.eta0])
    rows = []
    if sample_time is None:
        rows = _simulate_continuous(example, params, times, y0)
    else:
        if not math.isclose(sample_time, grid, rel_tol=1e-12):
            raise ValueError(f"sampled runs are recorded at the sample time ({sample_time}), not {grid}")
        rows = _simulate_sampled(example, params, times, y0)
    data = np.array(rows, dtype=[(name, float) for name in fields_of(example, params.n)])
    return ReferenceRun(example=example, controller=params, sample_time=sample_time, data=data)


class SolverError(RuntimeError):
    """SciPy's solver gave up on a span of the monolithic reference: ``reason`` is its message."""

    def __init__(self, example: str, start: float, end: float, reason: str) -> None:
        super().__init__(f"{example}: solve_ivp failed on [{start}, {end}]: {reason}")
        self.example, self.span, self.reason = example, (start, end), reason


def _simulate_continuous(ex: Example, params: ControllerParameters, times: list[float], y0) -> list[tuple]:
    """Integrate piecewise so the fault switch at t_fault is a segment boundary, not a kink inside."""
    t_end = times[-1]
    bounds = [0.0] + [b for b in (ex.actuator.t_fault,) if 0.0 < b < t_end] + [t_end]
    rows: list[tuple] = []
    y = y0
    for start, end in zip(bounds[:-1], bounds[1:], strict=True):
        t_eval = [t for t in times if start <= t <= end and (not rows or t > rows[-1][0])]
        sol = solve_ivp(
            _continuous_rhs, (start, end), y, method="DOP853", t_eval=t_eval,
            rtol=RTOL, atol=ATOL, args=(ex, params),
        )
        if not sol.success:
            raise SolverError(ex.name, start, end, sol.message)
        rows.extend(_record(t, sol.y[:, j], ex, params) for j, t in enumerate(sol.t))
        y = sol.y[:, -1]
    return rows


def _simulate_sampled(ex: Example, params: ControllerParameters, times: list[float], y0) -> list[tuple]:
    rows: list[tuple] = []
    y = y0
    for k, t in enumerate(times):
        rows.append(_record(t, y, ex, params))
        if k == len(times) - 1:
            break
        x, yd = _controller_inputs(t, y, ex, params.n)
        _, uf, _, _ = _outputs(t, y, ex, params)
        sol = solve_ivp(
            _held_rhs, (t, times[k + 1]), y, method="DOP853", rtol=RTOL, atol=ATOL,
            args=(ex, params, x, yd, uf),
        )
        if not sol.success:
            raise SolverError(ex.name, t, times[k + 1], sol.message)
        y = sol.y[:, -1]
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Print the metrics of one example and mode (or the table of all four)."""
    parser = argparse.ArgumentParser(
        prog="python -m orchestrator.experiments.closed_loop",
        description="Monolithic reference simulation of the paper's examples (no FMI).",
    )
    parser.add_argument("--example", type=int, choices=sorted(EXAMPLES), default=1)
    parser.add_argument("--mode", type=Mode.parse, choices=list(Mode), default=FIXED_TIME)
    parser.add_argument("--sample-time", type=float, default=None,
                        help="zero-order-hold sample time in s (default: continuous controller)")
    parser.add_argument("--stop-time", type=float, default=None)
    parser.add_argument("--table", action="store_true", help="all examples and both modes")
    args = parser.parse_args(argv)
    from .metrics import format_table, tracking_metrics

    cases = [(e, m) for e in sorted(EXAMPLES) for m in (FIXED_TIME, FINITE_TIME)] if args.table else [
        (args.example, args.mode)
    ]
    rows = []
    for number, mode in cases:
        ex = EXAMPLES[number]
        grid = args.sample_time or 1e-3
        run = simulate(ex, ex.controller.with_changes(mode=mode), args.stop_time, args.sample_time, grid)
        d = run.data
        rows.append((f"{ex.name}, {mode}", tracking_metrics(d["time"], d["y"], d["yd"], d["v"], d["uf"])))
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
