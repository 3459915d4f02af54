# SPDX-License-Identifier: BSD-2-Clause
"""Gains, cap and step for a user's own plant of order 1-4 (issue 45), by a documented procedure.

The procedure (``docs/controller-fmu.md``, "Tuning for your own plant") starts from what a user
knows of the plant, its input gains g_1..g_n of the paper's system (1) and the time scale of the
reference (its amplitude A and angular frequency omega), the wanted accuracy e and the
communication step h, and gives a first guess (:func:`first_guess`):

* ``b_max = 1.25 max g_i``: a bound of every input gain with a margin, for a delay-free master (a
  master that delays every connection needs more, the manipulator's 1.75 g_3; the campaign does
  not check that case);
* ``beta = 0.95``: the q term q |z|^(2 beta - 1) is nearly linear, so the cap |z| / (b_max h) binds
  only where |z| < (q b_max h)^(1 / (2 - 2 beta)), a tiny layer, instead of near every small error;
  ``alpha = 1.5`` (the project's default) and k_i = 1 leave the fast term to large errors;
* step rates lambda_i = lambda_1 s^(i - 1), each inner loop s times faster than the one it serves
  (the law has no derivative of the virtual control, so backstepping needs that time-scale
  separation), with lambda_1 = A omega / e (a first step that lags the reference's slope A omega by
  e) and ``q_i = lambda_i / g_i``; s = 3, lowered (not below 1.5) until every q_i is at most half
  the cap's slope 1 / (b_max h), so that the law, not the cap, acts in every step
  (:func:`separation`).

A campaign (:data:`DESIGN`, ``ssp/campaigns/tuning_flexible_joint.toml``: lambda_1, s and the b_max
factor around the guess) then simulates the sampled loop with the library's law (the controller
FMUs' law, the same bits) and the plant's model, and :func:`choose` takes, of the bounded runs whose
largest error over the second half is within e and where the cap binds in less than half the
samples of every step, the one with the least control after the first 0.1 s. The
shipped plant is the flexible joint of Spong (1987) with input gains 1, 10, 1, 2
(:data:`FLEXIBLE_JOINT`), which with b_max 10-100 and Example 1's gains diverged at 1 ms.

``python -m orchestrator.experiments.tuning`` runs the campaign and writes its table into the
controller guide (between the markers :data:`BEGIN` and :data:`END`).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from controller.fmath import cos, sin
from controller.params import SEMI_IMPLICIT, ControllerParameters
from controller.stepping import AdaptiveController

from ..campaign import read_design
from .caps import RELATIVE

__all__ = ["BEGIN", "DESIGN", "END", "FLEXIBLE_JOINT", "Outcome", "Plant", "Tuning", "choose", "first_guess",
           "flexible_joint_rhs", "main", "procedure", "run_campaign", "separation", "simulate", "table"]

DESIGN = Path("ssp") / "campaigns" / "tuning_flexible_joint.toml"
GUIDE = Path("docs") / "controller-fmu.md"
BEGIN, END = "<!-- tuning campaign: begin (generated) -->", "<!-- tuning campaign: end -->"
SEPARATION = 3.0
B_MAX_FACTOR = 1.25
BETA = 0.95
BAND = 0.05
SUBSTEPS = 4  # RK4 sub-steps of the plant per communication step
DIVERGED = 1e4  # a state beyond this ends the run as diverged

RightHandSide = Callable[[Sequence[float], float], tuple[float, ...]]


@dataclass(frozen=True)
class Plant:
    """A user's plant in the paper's strict-feedback form: its input gains (bounds of g_i), its
    right-hand side x' = f(x, u) (a module-level function: the campaign's processes import it), the
    initial state, and the reference yd = amplitude sin(omega t) it shall track to ``accuracy``."""

    name: str
    gains: tuple[float, ...]
    rhs: RightHandSide
    x0: tuple[float, ...]
    amplitude: float = 0.5
    omega: float = 1.0
    accuracy: float = 0.05


# Spong's flexible joint: link inertia I = 1, motor inertia J = 0.5, joint stiffness K = 10, gravity
# M g L = 5: I q1'' + M g L sin q1 + K (q1 - q2) = 0, J q2'' - K (q1 - q2) = u; x = (q1, q1', q2, q2').
FJ_I, FJ_J, FJ_K, FJ_MGL = 1.0, 0.5, 10.0, 5.0


def flexible_joint_rhs(x: Sequence[float], u: float) -> tuple[float, ...]:
    """Spong's flexible joint in the paper's form: x1' = x2, x2' = (K/I) x3 - (M g L / I) sin x1 -
    (K/I) x1, x3' = x4, x4' = u / J - (K/J)(x3 - x1): input gains 1, K/I = 10, 1, 1/J = 2."""
    return (x[1], (FJ_K * x[2] - FJ_MGL * sin(x[0]) - FJ_K * x[0]) / FJ_I, x[3],
            (u - FJ_K * (x[2] - x[0])) / FJ_J)


FLEXIBLE_JOINT = Plant("flexible joint (Spong 1987)", (1.0, FJ_K / FJ_I, 1.0, 1.0 / FJ_J), flexible_joint_rhs,
                       (0.0, 0.0, 0.0, 0.0))


@dataclass(frozen=True)
class Tuning:
    """One point of the procedure: the first step's rate, the separation and the b_max factor."""

    lambda1: float
    separation: float
    b_max_factor: float = B_MAX_FACTOR


def separation(gains: Sequence[float], h: float, lambda1: float, b_max_factor: float = B_MAX_FACTOR) -> float:
    """The procedure's s: :data:`SEPARATION`, lowered in steps of 0.5 (not below 1.5) until every
    q_i = lambda_1 s^(i-1) / g_i is at most half the cap's slope 1 / (b_max h)."""
    slope = 1.0 / (b_max_factor * max(gains) * h)
    s = SEPARATION
    while s > 1.5 and max(lambda1 * s**i / g for i, g in enumerate(gains)) > 0.5 * slope:
        s -= 0.5
    return s


def procedure(plant: Plant, h: float) -> Tuning:
    """The procedure's first guess for ``plant`` at step ``h``: lambda_1 = A omega / e, s by
    :func:`separation`, b_max = 1.25 max g_i."""
    lambda1 = plant.amplitude * plant.omega / plant.accuracy
    return Tuning(lambda1, separation(plant.gains, h, lambda1), B_MAX_FACTOR)


def first_guess(gains: Sequence[float], h: float, tuning: Tuning) -> ControllerParameters:
    """The controller parameters of the procedure for input gains ``gains`` at step ``h``:
    q_i = lambda_1 s^(i-1) / g_i, k_i = 1, beta = 0.95, b_max = factor x max g_i, semi-implicit at h;
    a, kappa, rho, rho_bar as the paper's Example 1 (steps beyond 2 repeat step 2's)."""
    n = len(gains)
    q = tuple(tuning.lambda1 * tuning.separation ** i / g for i, g in enumerate(gains))
    def paper(first: float, then: float) -> tuple[float, ...]:
        return (first, *(then,) * (n - 1))

    return ControllerParameters(k=(1.0,) * n, q=q, a=paper(5.0, 2.0), kappa=paper(2.0, 2.0),
                                rho=paper(2.0, 2.0), rho_bar=paper(1.0, 1.0), alpha=1.5, beta=BETA,
                                discretization=SEMI_IMPLICIT, sample_time=h,
                                b_max=tuning.b_max_factor * max(gains))


@dataclass(frozen=True)
class Outcome:
    """A simulated run: ``status`` (ok or diverged, with the time reached), the settling time in the
    0.05 band, the MAE and the largest |y - yd| over the second half, the peak |v| (and after the
    first 0.1 s), and per step the share of samples with the cap binding."""

    status: str
    time_reached: float
    settling: float
    mae_late: float
    max_late: float
    peak_v: float
    peak_v_late: float
    caps: tuple[float, ...]


def _reference(t: float, plant: Plant, n: int) -> list[float]:
    """yd = A sin(omega t) and its derivatives up to order n."""
    a, w = plant.amplitude, plant.omega
    return [a * w ** j * (sin(w * t) if j % 4 == 0 else cos(w * t) if j % 4 == 1 else
                          -sin(w * t) if j % 4 == 2 else -cos(w * t)) for j in range(n + 1)]


def simulate(plant: Plant, params: ControllerParameters, h: float, stop: float,
             record: list[tuple[float, float, float]] | None = None) -> Outcome:
    """The sampled loop: the law's output at each step held over [t, t + h] (zero-order hold), the
    plant by RK4 with :data:`SUBSTEPS` sub-steps, the controller's states by its own RK4 step, in
    the order the controller FMU is called (set inputs, read v, step the plant, step the
    controller). ``record``, if given, receives (t, y, v) at every sample."""
    n = params.n
    controller = AdaptiveController(params)
    x = list(plant.x0)
    bh = params.b_max * params.sample_time
    capped, counted = [0] * n, [0] * n
    times: list[float] = []
    errors: list[float] = []
    peak = peak_late = 0.0
    steps = round(stop / h)
    dt = h / SUBSTEPS
    for k in range(steps + 1):
        t = k * h
        yd = _reference(t, plant, n)
        terms = controller.output(x, yd)
        v = terms.v
        peak = max(peak, abs(v))
        if t >= 0.1:
            peak_late = max(peak_late, abs(v))
        _count_caps(terms.z, terms.zeta, bh, capped, counted)
        times.append(t)
        errors.append(abs(x[0] - yd[0]))
        if record is not None:
            record.append((t, x[0], v))
        if k == steps:
            break
        if not all(math.isfinite(s) and abs(s) < DIVERGED for s in (*x, v)):
            return Outcome("diverged", t, math.inf, math.nan, math.nan, peak, peak_late,
                           tuple(c / max(m, 1) for c, m in zip(capped, counted, strict=True)))
        controller.advance(x, yd, h)
        for _ in range(SUBSTEPS):
            x = _rk4_step(plant, x, v, dt)
    late = errors[len(errors) // 2:]
    return Outcome("ok", times[-1], _settling(times, errors, h), sum(late) / len(late), max(late), peak,
                   peak_late, tuple(c / max(m, 1) for c, m in zip(capped, counted, strict=True)))


def _count_caps(z: Sequence[float], zeta: Sequence[float], bh: float, capped: list[int],
                counted: list[int]) -> None:
    """Count, per step, the samples with z_i != 0 (``counted``) and those where |zeta_i| is the
    semi-implicit cap |z_i| / (b_max h) to within :data:`RELATIVE` (``capped``)."""
    for i, (z_i, zeta_i) in enumerate(zip(z, zeta, strict=True)):
        if z_i != 0.0:
            counted[i] += 1
            capped[i] += abs(abs(zeta_i) - abs(z_i) / bh) <= RELATIVE * abs(z_i) / bh


def _rk4_step(plant: Plant, x: list[float], v: float, dt: float) -> list[float]:
    """The plant's state after one classical Runge-Kutta step of ``dt``, the input ``v`` held."""
    k1 = plant.rhs(x, v)
    k2 = plant.rhs([a + dt / 2 * b for a, b in zip(x, k1, strict=True)], v)
    k3 = plant.rhs([a + dt / 2 * b for a, b in zip(x, k2, strict=True)], v)
    k4 = plant.rhs([a + dt * b for a, b in zip(x, k3, strict=True)], v)
    return [a + dt / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4, strict=True)]


def _settling(times: Sequence[float], errors: Sequence[float], h: float) -> float:
    """The sample after the last one outside the band (0: never outside; inf: outside at the end)."""
    outside = [t for t, e in zip(times, errors, strict=True) if e > BAND]
    return 0.0 if not outside else (math.inf if outside[-1] == times[-1] else outside[-1] + h)


def _run(args: tuple[Plant, Tuning, float, float]) -> Outcome:
    plant, tuning, h, stop = args
    return simulate(plant, first_guess(plant.gains, h, tuning), h, stop)


def run_campaign(plant: Plant, design: Path, workers: int) -> list[tuple[Tuning, Outcome]]:
    """Every point of ``design`` (columns ``tuning.lambda1``, ``tuning.separation``,
    ``tuning.b_max_factor``; ``step`` and ``stop_time``) simulated in ``workers`` processes."""
    d = read_design(design)
    h = d.step if d.step is not None else 1e-3
    stop = d.stop_time if d.stop_time is not None else 10.0
    tunings = [Tuning(**{name.split(".", 1)[1]: value for name, value in point.items()})
               for point in d.variants()]
    with ProcessPoolExecutor(workers) as pool:
        outcomes = list(pool.map(_run, [(plant, t, h, stop) for t in tunings]))
    return list(zip(tunings, outcomes, strict=True))


def choose(results: Sequence[tuple[Tuning, Outcome]], accuracy: float) -> tuple[Tuning, Outcome] | None:
    """Of the bounded runs whose largest error over the second half is within ``accuracy``, those
    where the paper's law acts in most samples of every step (each cap share below one half) if any,
    and of them the one with the least peak |v| after 0.1 s (the least control once the transient is
    over); if none is that accurate, the bounded run with the smallest error (None: none bounded)."""
    ok = [r for r in results if r[1].status == "ok"]
    accurate = [r for r in ok if r[1].max_late <= accuracy]
    acting = [r for r in accurate if max(r[1].caps) < 0.5]
    if acting or accurate:
        return min(acting or accurate, key=lambda r: r[1].peak_v_late)
    return min(ok, key=lambda r: r[1].max_late) if ok else None


def _g(x: float, spec: str = ".3g") -> str:
    return "never" if math.isinf(x) else "-" if math.isnan(x) else format(x, spec)


def table(plant: Plant, results: Sequence[tuple[Tuning, Outcome]], h: float) -> str:
    """The campaign's Markdown table, the chosen run in bold."""
    best = choose(results, plant.accuracy)
    lines = ["| lambda_1 | s | b_max | q_1..q_n | status | settling (s) | MAE, 2nd half | max abs(y - yd), "
             "2nd half | peak abs(v) | peak abs(v) after 0.1 s "
             "| cap active, share of samples (step 1 / ... / n) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for tuning, outcome in results:
        params = first_guess(plant.gains, h, tuning)
        cells = [f"{tuning.lambda1:g}", f"{tuning.separation:g}", f"{params.b_max:g}",
                 ", ".join(f"{q:.3g}" for q in params.q),
                 outcome.status if outcome.status == "ok" else f"diverged at {outcome.time_reached:.3g} s",
                 _g(outcome.settling), _g(outcome.mae_late), _g(outcome.max_late), _g(outcome.peak_v),
                 _g(outcome.peak_v_late), " / ".join(f"{c:.3g}" for c in outcome.caps)]
        if best is not None and (tuning, outcome) == best:
            cells = [f"**{c}**" for c in cells]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_guide(guide: Path, text: str) -> None:
    """Replace what lies between :data:`BEGIN` and :data:`END` in ``guide`` with ``text``."""
    page = guide.read_text(encoding="utf-8")
    start, end = page.index(BEGIN) + len(BEGIN), page.index(END)
    guide.write_text(page[:start] + "\n\n" + text + "\n\n" + page[end:], encoding="utf-8")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the shipped tuning campaign for the flexible joint and write its table into the guide."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.tuning",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--design", type=Path, default=DESIGN, help=f"campaign design ({DESIGN})")
    parser.add_argument("--guide", type=Path, default=None, help=f"write the table into this page ({GUIDE})")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    design = read_design(args.design)
    h = design.step if design.step is not None else 1e-3
    results = run_campaign(FLEXIBLE_JOINT, args.design, args.workers)
    best = choose(results, FLEXIBLE_JOINT.accuracy)
    guess = procedure(FLEXIBLE_JOINT, h)
    chosen = "no run stayed bounded" if best is None else (
        f"chosen: lambda_1 = {best[0].lambda1:g}, s = {best[0].separation:g}, b_max factor "
        f"{best[0].b_max_factor:g}")
    text = (f"Design `{args.design.as_posix()}`, {len(results)} runs of the {FLEXIBLE_JOINT.name} "
            f"(input gains {', '.join(f'{g:g}' for g in FLEXIBLE_JOINT.gains)}) at h = {h * 1e3:g} ms, "
            f"{design.stop_time:g} s, yd = {FLEXIBLE_JOINT.amplitude:g} sin({FLEXIBLE_JOINT.omega:g} t), "
            f"x(0) = 0; wall time {time.perf_counter() - started:.0f} s. The procedure's first guess: "
            f"lambda_1 = {guess.lambda1:g}, s = {guess.separation:g}, b_max factor {guess.b_max_factor:g}; "
            f"the campaign's {chosen} (bold).\n\n"
            + table(FLEXIBLE_JOINT, results, h))
    if args.guide is not None:
        write_guide(args.guide, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
