# SPDX-License-Identifier: BSD-2-Clause
"""False divergence of the plants' fail-fast bounds, measured (issue 37).

The plant FMUs end a step with fmi2Discard when their state leaves its range of validity
(``y_limit``, ``state_limit``, the rate bound ``rate_horizon``, the step budget ``max_steps``): a
campaign counts such a run as diverged. A bound that ends a run the continuous closed loop settles
is a *false divergence*. This module checks the bounds over a grid of initial states:

* :func:`sampled_outcome`: the sampled loop a co-simulation computes, in one process: the
  controller (:class:`~controller.stepping.AdaptiveController`, the law's discretization), the
  actuator (:func:`~fmu_src.models.actuator.actuator_output`) and the plant advanced by the plant
  FMUs' own step (:func:`~fmu_src.models.plants.dopri_hold_step`, or the compiled one) with its
  fail-fast bounds, zero-order hold at the scenario's step;
* :func:`reference_outcome`: the continuous closed loop (the paper's law, ``solve_ivp`` DOP853 of
  :mod:`~orchestrator.experiments.closed_loop`'s right-hand side) with no bound but an escape
  event at :data:`ESCAPED` (far beyond every bound), the independent oracle.

A state is a false divergence when the sampled loop ends on a bound and the oracle settles: the
continuous reference (``--reference``; the test's oracle) or, cheaper, the same sampled loop with
no bound at all (the explicit law's sampled divergence is a true one although the continuous law
settles).
``python -m orchestrator.experiments.escape_check`` (``make check-fail-fast``) runs the grid of
the issue (|x1(0)| <= 20, |x2(0)| <= 1e4, 21 x 21, both examples) and prints the counts (run it
in a checkout of an older commit for the bounds before).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
import zipfile
from collections import Counter
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from controller.params import FIXED_TIME, SEMI_IMPLICIT, Discretization, Mode
from controller.stepping import AdaptiveController
from fmu_src.models.actuator import actuator_output
from fmu_src.models.examples import EXAMPLES, Example
from fmu_src.models.native import EXAMPLE1, NativePlant, native_hold_step, pendulum_native
from fmu_src.models.plants import (
    MAX_STEPS,
    RATE_HORIZON,
    STATE_LIMIT,
    Y_LIMIT,
    PendulumParameters,
    State,
    dopri_hold_step,
    example1_rhs,
    pendulum_rhs_for,
)
from fmu_src.models.reference import reference_derivatives, reference_signal

from .campaigns import BAND
from .metrics import settling_time

__all__ = [
    "ESCAPED",
    "SHIPPED_BOUNDS",
    "Bounds",
    "Outcome",
    "grid",
    "main",
    "reference_outcome",
    "sampled_outcome",
]

ESCAPED = 1e8  # the reference's escape event: |state| beyond it is a finite escape, not a transient
STEPS = {1: 1e-3, 2: 5e-4}  # the smooth scenarios' communication steps (example1_smooth, pendulum_smooth)
RTOL, ATOL = 1e-10, 1e-12  # the plant FMUs' defaults


@dataclass(frozen=True)
class Bounds:
    """The plant's fail-fast parameters: ``state_limit``, ``y_limit``, ``rate_horizon``, ``max_steps``."""

    state_limit: float = STATE_LIMIT
    y_limit: float = Y_LIMIT
    rate_horizon: float = RATE_HORIZON
    max_steps: int = MAX_STEPS


SHIPPED_BOUNDS = Bounds()


@dataclass(frozen=True)
class Outcome:
    """One run: ``settled`` / ``never`` (outside the band at the horizon) / ``diverged``, the
    settling time (inf unless settled), the time reached, why it ended early, the largest |x1|,
    |x2|, |z| and the CPU time (s)."""

    outcome: str
    settling: float
    reached: float
    reason: str
    peaks: tuple[float, float, float]
    cpu: float


def _no_fault(example: Example) -> Example:
    return replace(example, actuator=replace(example.actuator, t_fault=math.inf))


HoldStep = Callable[..., Any]


def _plant_step(example: Example, compiled: Any | None) -> tuple[HoldStep, Any]:
    """The plant FMU's step for ``example``: the compiled one (``compiled``: a loaded ``_dopri``
    module) or the Python reference, and its plant argument."""
    if compiled is not None:
        from fmu_src.models import native

        native._dopri = compiled  # the module the FMU build compiles, loaded by the caller
        plant: NativePlant = EXAMPLE1 if example.number == 1 else pendulum_native(PendulumParameters())
        return native_hold_step, plant
    rhs = example1_rhs if example.number == 1 else pendulum_rhs_for(PendulumParameters())
    return dopri_hold_step, rhs


def sampled_outcome(
    number: int,
    x0: tuple[float, float],
    mode: Mode = FIXED_TIME,
    discretization: Discretization = SEMI_IMPLICIT,
    horizon: float = 0.3,
    bounds: Bounds = SHIPPED_BOUNDS,
    compiled: Any | None = None,
) -> Outcome:
    """Example ``number`` from (x1(0), x2(0), z(0) = 0) without fault, sampled at its smooth
    scenario's step with the law's ``discretization``, the plant stepped with ``bounds`` (a bound
    that ends a step ends the run: ``diverged``, with the plant's message as ``reason``)."""
    started = time.process_time()
    example = _no_fault(EXAMPLES[number])
    h = STEPS[number]
    params = example.controller.with_changes(mode=mode, discretization=discretization, sample_time=h)
    controller = AdaptiveController(params)
    step, plant = _plant_step(example, compiled)
    state: State = (x0[0], x0[1], 0.0)
    peaks = [abs(x0[0]), abs(x0[1]), 0.0]
    times, errors = [0.0], [x0[0] - reference_signal(0.0, example.reference)[0]]
    guess, reason = 0.0, ""
    for k in range(round(horizon / h)):
        t = k * h
        x = list(state[:2])
        yd = reference_derivatives(t, example.reference)[:3]
        v = controller.output(x, yd).v
        uf, _ = actuator_output(t, v, state[0], state[1], example.actuator)
        try:
            new = step(plant, t, state, uf, h, RTOL, ATOL, guess, bounds.state_limit, bounds.max_steps,
                       bounds.y_limit, bounds.rate_horizon)
        except (ValueError, OverflowError) as error:
            reason = str(error)
            break
        controller.advance(x, yd, h)
        state, guess = new.state, new.next_step
        x1_bound = min(bounds.y_limit, bounds.state_limit)
        if not (abs(state[0]) <= x1_bound and abs(state[1]) <= bounds.state_limit
                and abs(state[2]) <= bounds.state_limit):
            reason = f"state {state} beyond a bound"  # what plant_core.step_plant rejects
            break
        peaks = [max(p, abs(s)) for p, s in zip(peaks, state, strict=False)]
        times.append(t + h)
        errors.append(state[0] - reference_signal(t + h, example.reference)[0])
    cpu = time.process_time() - started
    reached = times[-1]
    if reason:
        return Outcome("diverged", math.inf, reached, reason, (peaks[0], peaks[1], peaks[2]), cpu)
    s = settling_time(np.array(times), np.array(errors), BAND)
    outcome = "settled" if math.isfinite(s) else "never"
    return Outcome(outcome, s, reached, "", (peaks[0], peaks[1], peaks[2]), cpu)


def reference_outcome(number: int, x0: tuple[float, float], mode: Mode = FIXED_TIME,
                      horizon: float = 0.3, rtol: float = 1e-6) -> Outcome:
    """The continuous closed loop (the paper's law) from (x1(0), x2(0), 0) without fault and
    without any bound: ``diverged`` only if a state passes :data:`ESCAPED` or the solver gives up."""
    from scipy.integrate import solve_ivp

    from .closed_loop import _continuous_rhs

    started = time.process_time()
    example = _no_fault(EXAMPLES[number])
    params = example.controller.with_changes(mode=mode)
    assert params.eta0 is not None
    y0 = np.array([x0[0], x0[1], 0.0, params.r0, *params.eta0])

    def escape(t: float, y: np.ndarray, *_: object) -> float:
        return ESCAPED - max(abs(y[0]), abs(y[1]), abs(y[2]))

    escape.terminal = True  # type: ignore[attr-defined]
    samples = np.arange(round(horizon / 1e-3) + 1) * 1e-3
    sol = solve_ivp(_continuous_rhs, (0.0, horizon), y0, method="DOP853", t_eval=samples, rtol=rtol,
                    atol=rtol * 1e-2, args=(example, params), events=escape)
    cpu = time.process_time() - started
    peaks = tuple(float(np.max(np.abs(sol.y[i]))) if sol.t.size else 0.0 for i in range(3))
    reached = float(sol.t[-1]) if sol.t.size else 0.0
    if sol.status != 0:
        return Outcome("diverged", math.inf, reached, sol.message, peaks, cpu)  # type: ignore[arg-type]
    yd = np.array([reference_signal(t, example.reference)[0] for t in sol.t])
    s = settling_time(sol.t, sol.y[0] - yd, BAND)
    return Outcome("settled" if math.isfinite(s) else "never", s, reached, "", peaks, cpu)  # type: ignore[arg-type]


def grid(states: int = 21, x1_max: float = 20.0, x2_max: float = 1e4) -> list[tuple[float, float]]:
    """The ``states`` x ``states`` initial states over [-x1_max, x1_max] x [-x2_max, x2_max]."""
    return [(a, b) for a in np.linspace(-x1_max, x1_max, states).tolist()
            for b in np.linspace(-x2_max, x2_max, states).tolist()]


UNBOUNDED = Bounds(state_limit=math.inf, y_limit=math.inf, rate_horizon=0.0, max_steps=10**9)


def _job(args: tuple[int, tuple[float, float], int, int, float, bool]) -> tuple[Outcome, Outcome | None]:
    """One state: the loop with the plants' bounds and, if it ended on one, the oracle: the
    continuous loop (``reference``) or the same sampled loop without any bound."""
    number, x0, mode, discretization, horizon, reference = args
    sampled = sampled_outcome(number, x0, Mode(mode), Discretization(discretization), horizon,
                              SHIPPED_BOUNDS, _COMPILED)
    if sampled.outcome != "diverged":
        return sampled, None
    if reference:
        return sampled, reference_outcome(number, x0, Mode(mode), horizon)
    return sampled, sampled_outcome(number, x0, Mode(mode), Discretization(discretization), horizon,
                                    UNBOUNDED, _COMPILED)


_COMPILED: Any | None = None


def _extract_compiled(fmu: Path, where: Path) -> str:
    """The plant FMU's compiled step (``_dopri.abi3.so``), unpacked into ``where``."""
    with zipfile.ZipFile(fmu) as archive:
        name = next(n for n in archive.namelist() if n.endswith("/_dopri.abi3.so"))
        target = where / "_dopri.abi3.so"
        target.write_bytes(archive.read(name))
    return str(target)


def _load_compiled(path: str | None) -> None:
    global _COMPILED
    if path:
        import importlib.util

        spec = importlib.util.spec_from_file_location("_dopri", path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _COMPILED = module


def main(argv: Sequence[str] | None = None) -> int:
    """Print the false divergences of the plants' bounds over the issue's grid."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.escape_check",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--states", type=int, default=21)
    parser.add_argument("--horizon", type=float, default=0.3)
    parser.add_argument("--mode", type=int, choices=(0, 1), default=0, help="0 fixed-time, 1 finite-time")
    parser.add_argument("--discretization", type=int, choices=(0, 1), default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--reference", action="store_true",
                        help="the oracle of a run ended on a bound: the continuous law without bounds "
                             "(default: the same sampled loop without bounds, cheaper)")
    parser.add_argument("--build", type=Path, default=Path("build"),
                        help="the build whose plant FMU's compiled step to use (default build/)")
    args = parser.parse_args(argv)
    workdir = tempfile.TemporaryDirectory()
    compiled = _extract_compiled(args.build / "fmus" / "PendulumPlant.fmu", Path(workdir.name))
    jobs = [(n, x0, args.mode, args.discretization, args.horizon, args.reference)
            for n in (1, 2) for x0 in grid(args.states)]
    with ProcessPoolExecutor(args.workers, initializer=_load_compiled, initargs=(compiled,)) as pool:
        results = list(pool.map(_job, jobs, chunksize=4))
    for n in (1, 2):
        _print_example(n, [(job, r) for job, r in zip(jobs, results, strict=True) if job[0] == n])
    workdir.cleanup()
    return 0


def _costs(mine: Sequence[tuple[tuple, tuple]]) -> str:
    """The CPU time of a diverging run (median, largest) and the largest |x1|, |x2|, |z| of the rest."""
    diverging = [s.cpu for _, (s, ref) in mine if s.outcome == "diverged"]
    settled_peaks = [s.peaks for _, (s, _) in mine if s.outcome != "diverged"]
    return (f"CPU per diverging run median {np.median(diverging) * 1e3 if diverging else math.nan:.1f} ms, "
            f"max {max(diverging, default=math.nan) * 1e3:.1f} ms; largest |x1|, |x2|, |z| of the others "
            f"{[max(p[i] for p in settled_peaks) for i in range(3)] if settled_peaks else '-'}")


def _print_example(n: int, mine: Sequence[tuple[tuple, tuple]]) -> None:
    """Example ``n``'s line (outcomes, false divergences, CPU of a diverging run, the peaks of the
    others) and its first false divergences; ``mine``: its (job, (sampled run, reference run))."""
    counts = Counter(s.outcome for _, (s, _) in mine)
    false = [(job[1], s.reason) for job, (s, ref) in mine if ref is not None and ref.outcome == "settled"]
    print(f"Example {n}: {dict(counts)}; false divergences {len(false)}; {_costs(mine)}")
    for x0, reason in false[:10]:
        print(f"  false: {x0}: {reason[:160]}")


if __name__ == "__main__":
    raise SystemExit(main())
