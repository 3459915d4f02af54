# SPDX-License-Identifier: BSD-2-Clause
"""The fixed-time claim, measured (issue 24): settling maps over [-10, 10]^2 beside the paper's bound.

``python -m orchestrator.experiments.fixed_time_study`` (``make study-fixed-time``) runs, for both
examples and from every initial state x1(0), x2(0) of a grid over [-10, 10]^2:

* the shipped campaigns ``ssp/campaigns/fixed_time_study.toml`` (both laws, explicit and
  semi-implicit sampling at the shipped step) and ``fixed_time_saturation.toml`` (the fixed-time
  law, explicit, behind an actuator limit u_max) through ``orchestrate sweep``'s engine;
* the continuous law (the paper's own behaviour): the monolithic reference
  (:mod:`~orchestrator.experiments.closed_loop`'s right-hand side) with ``solve_ivp``, on every
  other state of the grid (11 x 11), in processes;

and writes the study table (diverged, never settled, settling median / max, peak |v| per
configuration, T_m of eq. (83) beside the worst settling time) and the figures: settling and
peak |v| maps with one colour scale per figure, settling-time distributions, the saturation maps
and the region where the semi-implicit cap binds at t = 0. It prints its wall time.

``--map NAME`` draws the same map for another shipped scenario instead (:data:`MAPS`: the
manipulator of issue 35, a plant of order 3), from its own campaign design: both laws, explicit and
semi-implicit sampling, T_m of eq. (83) for its order beside the worst settling time.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from controller.law import evaluate
from controller.params import FINITE_TIME, FIXED_TIME, SEMI_IMPLICIT, ControllerParameters
from fmu_src.models.examples import EXAMPLES, MANIPULATOR, Example
from fmu_src.models.plants import STATE_LIMIT, Y_LIMIT
from fmu_src.models.reference import reference_signal

from ..campaign import Design, read_design, read_table, sweep
from ..campaign.report import colour_norm
from .campaigns import BAND, TRACKING
from .caps import CAP_NAMES, LIMIT_NAME, cap_cell, metrics_for, scenario_sampling
from .fixed_time_bound import FixedTimeBound, fixed_time_bound
from .metrics import settling_time

__all__ = [
    "MAPS",
    "Cell",
    "MapSpec",
    "cap_binds",
    "cells_from_rows",
    "holds_cell",
    "continuous_cell",
    "draw_maps",
    "main",
    "panel_norm",
    "study_bounds",
    "study_table",
    "summarize",
]

CAMPAIGNS = Path("ssp") / "campaigns"
STUDY_DESIGN = CAMPAIGNS / "fixed_time_study.toml"
SATURATION_DESIGN = CAMPAIGNS / "fixed_time_saturation.toml"
SCENARIOS = {1: "example1_smooth", 2: "pendulum_smooth"}
HORIZON = 2.0
GRID = 1e-3  # the continuous law's sample grid (settling time, peak |v|)
CONTINUOUS_RTOL = 1e-6  # settling times within 1 ms of rtol 1e-8 on the states checked (README)
LAWS = {FIXED_TIME: "fixed-time", FINITE_TIME: "finite-time"}
SAMPLINGS = ("explicit", "semi-implicit", "continuous")
DEFAULT_OUT = Path("results") / "study-fixed-time"
# the figures committed under docs/ beside the table (the README shows them)
DOC_FIGURES = ("example1_settling.png", "pendulum_settling.png", "example1_saturation.png",
               "pendulum_saturation.png")


@dataclass(frozen=True)
class Cell:
    """One run of the study: initial state, outcome (``settled``, ``never`` settled within the
    horizon, ``diverged``), settling time (inf unless settled), peak |v| and the time reached."""

    x1_0: float
    x2_0: float
    outcome: str
    settling: float
    peak_v: float
    time_reached: float
    caps: tuple[float, ...] = ()  # per step i, the share of samples with the semi-implicit cap binding
    limit: float = math.nan  # the share of samples with |v| > u_max (behind an actuator limit)


def _outcome(status: str, settling: float) -> str:
    if status != "ok":
        return "diverged"
    return "settled" if math.isfinite(settling) else "never"


def cells_from_rows(rows: Sequence[Mapping[str, Any]]) -> list[Cell]:
    """Study cells from campaign rows (a failed run is a diverged state: the plant's fail-fast
    bound or a non-finite state ended it)."""
    out = []
    for r in rows:
        settling = r.get("settling_time")
        s = math.inf if settling is None or r["status"] != "ok" else float(settling)
        peak = r.get("peak_v")
        reached = r.get("time_reached")
        out.append(
            Cell(
                float(r["plant.x1_0"]),
                float(r["plant.x2_0"]),
                _outcome(str(r["status"]), s),
                s,
                math.nan if peak is None else float(peak),
                math.nan if reached is None else float(reached),
                tuple(_float(r.get(name)) for name in CAP_NAMES),
                _float(r.get(LIMIT_NAME)),
            )
        )
    return out


def _float(value: object) -> float:
    return math.nan if value is None else float(cast("float | str", value))


def _example_without_fault(example: Example) -> Example:
    return replace(example, actuator=replace(example.actuator, t_fault=math.inf))


def continuous_cell(args: tuple[int, int, float, float]) -> Cell:
    """The continuous law (monolithic reference) from one initial state over :data:`HORIZON`; a
    state beyond the plants' ``state_limit`` or ``y_limit`` (the FMUs' fail-fast bounds) counts as
    diverged."""
    from scipy.integrate import solve_ivp

    from .closed_loop import _continuous_rhs, _outputs

    number, mode, x1_0, x2_0 = args
    example = _example_without_fault(EXAMPLES[number])
    params = example.controller.with_changes(mode=mode)
    assert params.eta0 is not None
    y0 = np.array([x1_0, x2_0, 0.0, params.r0, *params.eta0])

    def escape(t: float, y: np.ndarray, *_: object) -> float:
        return min(STATE_LIMIT - max(abs(y[0]), abs(y[1]), abs(y[2])), Y_LIMIT - abs(y[0]))

    escape.terminal = True  # type: ignore[attr-defined]
    grid = np.arange(round(HORIZON / GRID) + 1) * GRID
    sol = solve_ivp(
        _continuous_rhs, (0.0, HORIZON), y0, method="DOP853", t_eval=grid, rtol=CONTINUOUS_RTOL,
        atol=CONTINUOUS_RTOL * 1e-2, args=(example, params), events=escape,
    )
    v = [abs(_outputs(t, sol.y[:, j].tolist(), example, params)[0]) for j, t in enumerate(sol.t)]
    peak = max(v) if v else math.nan
    reached = float(sol.t[-1]) if sol.t.size else 0.0
    if sol.status != 0:  # escaped (event) or the solver gave up
        return Cell(x1_0, x2_0, "diverged", math.inf, peak, reached)
    yd = np.array([reference_signal(t, example.reference)[0] for t in sol.t])
    s = settling_time(sol.t, sol.y[0] - yd, BAND)
    return Cell(x1_0, x2_0, "settled" if math.isfinite(s) else "never", s, peak, reached)


def cap_binds(example: Example, mode: int, x1_0: float, x2_0: float) -> bool:
    """Whether the semi-implicit law's cap |z_i| / (b_max h) replaces the paper's feedback in some
    backstepping step at t = 0 from this initial state (``semi_implicit_feedback`` takes the cap
    exactly when it is the smaller of the two); ``mode``: the law (0 fixed-time, 1 finite-time)."""
    params = example.controller.with_changes(
        mode=mode, discretization=SEMI_IMPLICIT, sample_time=_step(example)
    )
    assert params.eta0 is not None
    yd = reference_signal(0.0, example.reference)
    terms = evaluate([params.r0, *params.eta0], [x1_0, x2_0], yd, params)
    bh = params.b_max * params.sample_time
    return any(z != 0.0 and abs(zeta) == abs(z) / bh for z, zeta in zip(terms.z, terms.zeta, strict=True))


def _step(example: Example) -> float:
    """The shipped communication step of the example's scenarios (1 ms; 0.5 ms for the pendulum)."""
    return 1e-3 if example.number == 1 else 5e-4


def study_bounds(controller: ControllerParameters) -> FixedTimeBound:
    """T_m of eq. (83) for the study's runs: no fault, so K(t) m(t) = 1 before t_fault (m_bar = 1);
    b_m = 1 for both examples (2 + sin x1, 2 + cos(x1 x2) >= 1; the pendulum's gains are 1)."""
    return fixed_time_bound(controller, b_m=1.0, m_bar=1.0, phi=0.5)


@dataclass(frozen=True)
class Summary:
    """One configuration's line of the study table."""

    runs: int
    diverged: int
    never: int
    settling_median: float
    settling_max: float
    peak_v_median: float
    peak_v_max: float


def summarize(cells: Sequence[Cell]) -> Summary:
    """Counts, settling median / max over the settled states, peak |v| median / max over every
    state with a peak (diverged ones included: they keep their peak so far)."""
    settled = [c.settling for c in cells if c.outcome == "settled"]
    peaks = [c.peak_v for c in cells if math.isfinite(c.peak_v)]
    return Summary(
        runs=len(cells),
        diverged=sum(c.outcome == "diverged" for c in cells),
        never=sum(c.outcome == "never" for c in cells),
        settling_median=float(np.median(settled)) if settled else math.nan,
        settling_max=max(settled) if settled else math.nan,
        peak_v_median=float(np.median(peaks)) if peaks else math.nan,
        peak_v_max=max(peaks) if peaks else math.nan,
    )


def _g(value: float, digits: int = 3) -> str:
    if math.isnan(value):
        return "-"
    return f"{value:.{digits}g}"


HOLDS_HEADER = "max settling <= T_m (settled runs only)"
CAP_HEADER = "cap active, share of samples (step 1 / 2 / ...)"


def caps_cell(cells: Sequence[Cell]) -> str:
    """The row's cap column: per step i the mean over its runs of the share of samples with the
    semi-implicit cap binding (:func:`~orchestrator.experiments.caps.cap_cell`); behind an actuator
    limit, the mean share of samples with abs(v) > u_max; ``-`` where neither exists."""
    limits = [c.limit for c in cells if math.isfinite(c.limit)]
    if limits:
        return f"limit abs(v) > u_max: {float(np.mean(limits)):.3g}"
    steps = max((len(c.caps) for c in cells), default=0)
    fractions = [[c.caps[i] for c in cells if i < len(c.caps)] for i in range(steps)]
    while fractions and not any(math.isfinite(f) for f in fractions[-1]):
        fractions.pop()  # the steps beyond the plant's order
    return cap_cell(fractions)


def holds_cell(s: Summary, bound: FixedTimeBound | None) -> str:
    """Whether the worst settling time is within T_m, saying over how many runs: the bound is a
    claim about runs that settle, so a row where most runs diverge says how few it covers."""
    if bound is None or math.isnan(s.settling_max):
        return "-"
    settled = s.runs - s.diverged - s.never
    verdict = "yes" if s.settling_max <= bound.t_m else f"**no**: {s.settling_max:.3g} s"
    return f"{verdict}, {settled} of {s.runs} settled"


def study_table(
    configurations: Mapping[tuple[int, str, str], Sequence[Cell]], bounds: Mapping[int, FixedTimeBound]
) -> str:
    """The Markdown table: per (example, law, sampling) the counts, settling median / max, peak |v|
    median / max, for the fixed-time law T_m of eq. (83) (Phi = 0.5) beside the worst time, and how
    often the semi-implicit cap (or an actuator limit) replaced the law (:func:`caps_cell`)."""
    lines = [
        "| example | law | sampling | runs | diverged | never settled | settling median / max (s) "
        f"| peak abs(v) median / max | T_m (83), Phi = 0.5 (s) | {HOLDS_HEADER} | {CAP_HEADER} |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (number, law, sampling), cells in configurations.items():
        s = summarize(cells)
        bound = bounds[number] if law == "fixed-time" else None
        t_m = f"{bound.t_m:.3g}" if bound else "none (k = 0)"
        holds = holds_cell(s, bound)
        lines.append(
            f"| {number} | {law} | {sampling} | {s.runs} | {s.diverged} | {s.never} | "
            f"{_g(s.settling_median)} / {_g(s.settling_max)} | {_g(s.peak_v_median)} / {_g(s.peak_v_max)} | "
            f"{t_m} | {holds} | {caps_cell(cells)} |"
        )
    return "\n".join(lines)


def bound_table(bound: FixedTimeBound) -> str:
    """The constants of T_m with their sources (Markdown)."""
    lines = ["| constant | value | source |", "|---|---|---|"]
    lines += [f"| {c.name} | {c.value:.4g} | {c.source} |" for c in bound.constants]
    lines.append(f"| T_m (Phi = {bound.phi:g}) | {bound.t_m:.4g} s | eq. (83) |")
    lines.append(f"| T_m, Phi -> 1 | {bound.infimum:.4g} s | eq. (83), the smallest the proof gives |")
    return "\n".join(lines)


# -- figures ---------------------------------------------------------------------------------------
DIVERGED_COLOUR = "#d62728"
NEVER_COLOUR = "#bbbbbb"


def _grid(cells: Sequence[Cell], value: str) -> tuple[list[float], list[float], np.ndarray]:
    xs = sorted({c.x1_0 for c in cells})
    ys = sorted({c.x2_0 for c in cells})
    grid = np.full((len(ys), len(xs)), np.nan)
    for c in cells:
        v = getattr(c, value)
        if c.outcome == "settled" or (value == "peak_v" and math.isfinite(v)):
            grid[ys.index(c.x2_0), xs.index(c.x1_0)] = v
    return xs, ys, grid


def panel_norm(grid: np.ndarray, log: bool):  # -> matplotlib Normalize
    """One panel's colour scale over its own finite values: logarithmic (``log``, peaks), else linear
    from its smallest to its largest value, so a panel whose values lie within 0.04-0.1 s spans the
    whole colour map (a panel with no value: :func:`colour_norm`'s default)."""
    from matplotlib.colors import Normalize

    values = [float(v) for v in grid.ravel() if math.isfinite(v)]
    if log or not values:
        return colour_norm(values, log)
    low, high = min(values), max(values)
    if high > low:
        return Normalize(low, high)
    pad = 0.5 * abs(low or 1.0)
    return Normalize(low - pad, high + pad)


def _draw_map_panel(ax, cells: Sequence[Cell], value: str, log: bool, caps: Sequence[tuple[float, float]],
                    counts: dict[str, int]):  # -> matplotlib QuadMesh
    """One panel of :func:`draw_maps` with its own colour scale: the heat map, the diverged and
    never-settled states marked, the cap states outlined (each counted into ``counts``); the mesh,
    for the colour bar."""
    from matplotlib.patches import Rectangle

    xs, ys, grid = _grid(cells, value)
    norm = panel_norm(grid, log)
    dx = (xs[1] - xs[0]) if len(xs) > 1 else 1.0
    dy = (ys[1] - ys[0]) if len(ys) > 1 else 1.0
    mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(grid), shading="nearest", cmap="viridis", norm=norm)
    for c in cells:
        fill = {"diverged": DIVERGED_COLOUR, "never": NEVER_COLOUR}.get(c.outcome)
        if fill and value != "peak_v":
            ax.add_patch(Rectangle((c.x1_0 - dx / 2, c.x2_0 - dy / 2), dx, dy, color=fill, lw=0))
        if c.outcome == "diverged":
            ax.plot(c.x1_0, c.x2_0, "x", color="black", markersize=3.5, mew=0.8)
            counts["diverged"] += 1
        elif c.outcome == "never":
            ax.plot(c.x1_0, c.x2_0, "o", mfc="none", color="black", markersize=3.5, mew=0.8)
            counts["never"] += 1
    for x, y in caps:
        ax.add_patch(Rectangle((x - dx / 2, y - dy / 2), dx, dy, fill=False, ec="white", lw=0.9))
        counts["cap"] += 1
    ax.set_xlim(xs[0] - dx / 2, xs[-1] + dx / 2)
    ax.set_ylim(ys[0] - dy / 2, ys[-1] + dy / 2)
    return mesh


def _map_legend(counts: Mapping[str, int], value: str) -> list:
    """The legend's entries of :func:`draw_maps`: only what some panel shows (for peak |v| the
    failed states are markers, not fills)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = []
    if counts["diverged"]:
        handles.append(
            Patch(color=DIVERGED_COLOUR, label="diverged (x)") if value != "peak_v"
            else Line2D([], [], ls="", marker="x", color="black", label="diverged: peak before failing (x)")
        )
    if counts["never"]:
        handles.append(
            Patch(color=NEVER_COLOUR, label=f"never settled within {HORIZON:g} s (o)") if value != "peak_v"
            else Line2D([], [], ls="", marker="o", mfc="none", color="black", label="never settled (o)")
        )
    if counts["cap"]:
        handles.append(Patch(fill=False, ec="black", label="semi-implicit cap binds at t = 0 (outlined)"))
    return handles


def draw_maps(
    panels: Sequence[tuple[str, Sequence[Cell]]],
    value: str,
    label: str,
    target: Path,
    *,
    log: bool = False,
    title: str = "",
    caps: Mapping[str, Sequence[tuple[float, float]]] | None = None,
) -> None:
    """Heat maps of ``value`` over the initial states, one panel per configuration, each with its own
    colour scale and colour bar (issue 37: one shared scale rendered every fixed-time panel, 0.04-0.1 s
    beside the finite-time law's 2 s, in one colour); diverged states in red with an x,
    never-settled states grey with an o, the cap region (``caps[title]``: states) outlined; the
    legend below the panels, outside the data."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(3, len(panels))
    rows = math.ceil(len(panels) / columns)
    fig, axes = plt.subplots(
        rows, columns, figsize=(4.3 * columns + 1.2, 3.7 * rows + 0.9), squeeze=False, layout="constrained"
    )
    counts = {"diverged": 0, "never": 0, "cap": 0}
    for ax, (name, cells) in zip(axes.flat, panels, strict=False):
        mesh = _draw_map_panel(ax, cells, value, log, (caps or {}).get(name, ()), counts)
        ax.set_title(name, fontsize="small")
        ax.set_xlabel("x1(0)")
        ax.set_ylabel("x2(0)")
        fig.colorbar(mesh, ax=ax, label=label, shrink=0.9, extend="neither")
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    handles = _map_legend(counts, value)
    if handles:
        fig.legend(
            handles=handles, loc="outside lower center", ncol=len(handles), fontsize="small", frameon=False
        )
    if title:
        fig.suptitle(title, fontsize="medium")
    fig.savefig(target, dpi=90, bbox_inches="tight")
    plt.close(fig)


def draw_distributions(panels: Sequence[tuple[str, Sequence[Cell]]], target: Path, title: str = "") -> None:
    """Settling-time distributions as empirical CDFs over all states of each configuration (lines:
    none hides another); the curve ends below 1 by the share that never settles or diverges."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for index, (name, cells) in enumerate(panels):
        style = ("-", "--", ":")[index % 3]  # equal curves (one law, two samplings) stay visible
        times = sorted(c.settling for c in cells if c.outcome == "settled")
        if not times:
            ax.plot([], [], style, label=f"{name}: none settles")
            continue
        share = np.arange(1, len(times) + 1) / len(cells)
        ax.step(times, share, style, where="post", lw=1.6, label=f"{name} ({len(times)}/{len(cells)} settle)")
    ax.set_xscale("log")
    ax.set_xlabel("settling time (s), band 0.05")
    ax.set_ylabel("share of initial states settled")
    ax.set_ylim(0.0, 1.02)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if title:
        ax.set_title(title, fontsize="medium")
    fig.savefig(target, dpi=90, bbox_inches="tight")
    plt.close(fig)


# -- the study -------------------------------------------------------------------------------------
def on_grid(design: Design, states: int) -> Design:
    """The design's points whose initial state lies on the ``states`` x ``states`` grid over
    [-10, 10]^2 (every other state of the 21 x 21 grid for 11): the same runs, fewer of them."""
    grid = {round(v, 9) for v in np.linspace(-10.0, 10.0, states).tolist()}
    i, j = design.columns.index("plant.x1_0"), design.columns.index("plant.x2_0")
    points = tuple(p for p in design.points if round(p[i], 9) in grid and round(p[j], 9) in grid)
    return replace(design, points=points)


def _campaign(
    designs: Sequence[Path], build: Path, out: Path, workers: int, states: int
) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    for path in designs:
        design = on_grid(read_design(path), states)
        for name in SCENARIOS.values():  # one sweep per scenario: its cap b_max h (caps.metrics_for)
            summary = sweep([build / "ssp" / f"{name}.ssp"], design, out / path.stem / name,
                            metrics=metrics_for(TRACKING, scenario_sampling(name)), workers=workers,
                            force=True)
            rows += read_table(summary.parquet)[0]
    return rows


def _configurations(
    rows: Sequence[Mapping[str, Any]], continuous: Mapping[tuple[int, str], Sequence[Cell]]
) -> tuple[dict[tuple[int, str, str], list[Cell]], dict[tuple[int, float], list[Cell]]]:
    by_scenario = {name: number for number, name in SCENARIOS.items()}
    sampled: dict[tuple[int, str, str], list[Cell]] = {}
    saturated: dict[tuple[int, float], list[Cell]] = {}
    for r in rows:
        number = by_scenario[str(r["scenario"])]
        cell = cells_from_rows([r])[0]
        if r.get("actuator.u_max") is not None:
            saturated.setdefault((number, float(r["actuator.u_max"])), []).append(cell)
        else:
            law = LAWS[FINITE_TIME if int(r["controller.mode"]) else FIXED_TIME]
            sampling = SAMPLINGS[int(r["controller.discretization"])]
            sampled.setdefault((number, law, sampling), []).append(cell)
    configurations: dict[tuple[int, str, str], list[Cell]] = {}
    for number in SCENARIOS:
        for law in LAWS.values():
            for sampling in SAMPLINGS:
                key = (number, law, sampling)
                configurations[key] = list(continuous.get((number, law), ())) if sampling == "continuous" \
                    else sampled.get(key, [])
    return configurations, saturated


CONTINUOUS_NAME = "continuous.csv"
TIMING_NAME = "wall_time.json"


Job = tuple[int, int, float, float]  # example, mode, x1(0), x2(0)


def _write_continuous(path: Path, jobs: Sequence[Job], cells: Sequence[Cell]) -> None:
    lines = ["example,mode,x1_0,x2_0,outcome,settling,peak_v,time_reached"]
    lines += [
        f"{n},{m},{c.x1_0!r},{c.x2_0!r},{c.outcome},{c.settling!r},{c.peak_v!r},{c.time_reached!r}"
        for (n, m, _, _), c in zip(jobs, cells, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _read_continuous(path: Path) -> dict[tuple[int, str], list[Cell]]:
    continuous: dict[tuple[int, str], list[Cell]] = {}
    for line in path.read_text(encoding="utf-8").splitlines()[1:]:
        n, m, a, b, outcome, settling, peak, reached = line.split(",")
        law = LAWS[FIXED_TIME if int(m) == 0 else FINITE_TIME]
        cell = Cell(float(a), float(b), outcome, float(settling), float(peak), float(reached))
        continuous.setdefault((int(n), law), []).append(cell)
    return continuous


def _continuous_jobs(states: int) -> list[tuple[int, int, float, float]]:
    """The continuous law's runs: (example, mode, x1(0), x2(0)) over a ``states`` x ``states`` grid."""
    values = np.linspace(-10.0, 10.0, states).tolist()
    return [(n, int(m), a, b) for n in SCENARIOS for m in LAWS for a in values for b in values]


def run_study(
    out: Path,
    docs: Path | None,
    build: Path,
    workers: int,
    continuous_states: int,
    report_only: bool = False,
    states: int = 21,
) -> str:
    """Run the whole study (or, with ``report_only``, read the tables an earlier run left in ``out``);
    write ``out/study.md`` and the figures (and copies of the table and the figures into ``docs``);
    return the Markdown."""
    started = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    designs = [STUDY_DESIGN, SATURATION_DESIGN]
    if report_only:
        rows = [r for d in designs for name in SCENARIOS.values()
                for r in read_table(out / d.stem / name / "runs.parquet")[0]]
    else:
        rows = _campaign(designs, build, out, workers, states)
    sampled_time = time.perf_counter() - started
    jobs = _continuous_jobs(continuous_states)
    if not report_only:
        with ProcessPoolExecutor(workers) as pool:
            results = list(pool.map(continuous_cell, jobs, chunksize=4))
        _write_continuous(out / CONTINUOUS_NAME, jobs, results)
    continuous = _read_continuous(out / CONTINUOUS_NAME)
    configurations, saturated = _configurations(rows, continuous)
    bounds = {n: study_bounds(EXAMPLES[n].controller) for n in SCENARIOS}
    figures: list[str] = []
    for number in SCENARIOS:
        figures += _study_figures(number, configurations, saturated, out, continuous_states)
    timing_path = out / TIMING_NAME
    if not report_only:  # the figures' time counts with the continuous law's
        timing = {"wall": time.perf_counter() - started, "sampled": sampled_time, "runs": len(rows),
                  "continuous_runs": len(jobs), "workers": workers}
        timing_path.write_text(json.dumps(timing), encoding="utf-8")
    timing = json.loads(timing_path.read_text(encoding="utf-8"))
    text = _study_text(timing, states, continuous_states, configurations, saturated, bounds)
    (out / "study.md").write_text(text + "\n".join(f"![{f}]({f})" for f in figures) + "\n", encoding="utf-8")
    if docs is not None:
        _copy_to_docs(docs, out, text, figures)
    return text


def _study_text(timing: Mapping[str, Any], states: int, continuous_states: int,
                configurations: Mapping[tuple[int, str, str], list[Cell]],
                saturated: Mapping[tuple[int, float], list[Cell]],
                bounds: Mapping[int, FixedTimeBound]) -> str:
    """The study's Markdown before its figures: how long it took, the table of each law and
    sampling, the saturation table, T_m of eq. (83)."""
    sat_configs = {
        (n, "fixed-time", f"explicit, u_max = {u:g}"): cells for (n, u), cells in sorted(saturated.items())
    }  # on the saturation design's grid (11 x 11)
    return "\n\n".join([
        "# The fixed-time claim, measured",
        f"Wall time {timing['wall']:.0f} s ({timing['sampled']:.0f} s for the {timing['runs']} co-simulation "
        f"runs, {timing['wall'] - timing['sampled']:.0f} s for the {timing['continuous_runs']} runs of the "
        f"continuous law and the figures), {timing['workers']} worker processes. Horizon {HORIZON:g} s, "
        f"band {BAND:g}; initial states on a {states} x {states} grid over [-10, 10]^2 (saturation: "
        f"{min(states, 11)} x {min(states, 11)}, the continuous law: {continuous_states} x "
        f"{continuous_states}).",
        study_table(configurations, bounds),
        "Saturation (beyond the paper; peak abs(v) is the controller's command, before the limit):",
        study_table(sat_configs, bounds),
        "T_m of eq. (83) (Example 1; the pendulum's gains give the same c and c_hat):",
        bound_table(bounds[1]),
    ]) + "\n\n"


def _cap_states(
    example: Example, number: int, configurations: Mapping[tuple[int, str, str], list[Cell]]
) -> dict[str, list[tuple[float, float]]]:
    """Per semi-implicit panel of example ``number``, the initial states where the cap binds at t = 0."""
    return {
        f"{law}, semi-implicit": [
            (c.x1_0, c.x2_0) for c in configurations[(number, law, "semi-implicit")]
            if cap_binds(example, int(mode), c.x1_0, c.x2_0)
        ]
        for mode, law in LAWS.items()
    }


def _study_figures(number: int, configurations: Mapping[tuple[int, str, str], list[Cell]],
                   saturated: Mapping[tuple[int, float], list[Cell]], out: Path,
                   continuous_states: int) -> list[str]:
    """Example ``number``'s four figures in ``out`` (settling and peak maps per law and sampling,
    the settling-time distribution, the saturation maps); their file names."""
    example = EXAMPLES[number]
    tag = f"example{number}" if number == 1 else "pendulum"
    panels = [
        (f"{law}, {sampling}", configurations[(number, law, sampling)])
        for law in LAWS.values() for sampling in SAMPLINGS
    ]
    caps = _cap_states(example, number, configurations)
    names = [f"{tag}_settling.png", f"{tag}_peak_v.png", f"{tag}_distribution.png", f"{tag}_saturation.png"]
    draw_maps(panels, "settling", "settling time (s), band 0.05", out / names[0], caps=caps,
              title=f"{example.name}: settling time from x(0) (continuous law: "
                    f"{continuous_states} x {continuous_states} grid)")
    draw_maps(panels, "peak_v", "peak abs(v)", out / names[1], log=True, title=f"{example.name}: peak abs(v)")
    draw_distributions(panels, out / names[2], title=f"{example.name}: settling-time distribution")
    limits = sorted({u for n, u in saturated if n == number})
    sat_panels = [(f"u_max = {u:g}", saturated[(number, u)]) for u in limits]
    sat_states = {(c.x1_0, c.x2_0) for _, cells in sat_panels for c in cells}  # its grid
    unlimited = configurations[(number, "fixed-time", "explicit")]
    sat_panels.append(("no limit", [c for c in unlimited if (c.x1_0, c.x2_0) in sat_states]))
    draw_maps(sat_panels, "settling", "settling time (s), band 0.05", out / names[3],
              title=f"{example.name}: fixed-time law, explicit sampling, actuator limit u_max")
    return names


def _copy_to_docs(docs: Path, out: Path, text: str, figures: Sequence[str]) -> None:
    """The study's table and the README's figures into ``docs``; the other figures named, not copied."""
    docs.mkdir(parents=True, exist_ok=True)
    links = [f"![{f}]({f})" for f in DOC_FIGURES] + [
        f"`{(out / f).as_posix()}`" for f in figures if f not in DOC_FIGURES
    ]
    (docs / "study.md").write_text(text + "\n".join(links) + "\n", encoding="utf-8")
    for f in DOC_FIGURES:
        (docs / f).write_bytes((out / f).read_bytes())


@dataclass(frozen=True)
class MapSpec:
    """A scenario whose map :func:`run_map` draws: its campaign design, its example (gains, number)
    and the bounds of eq. (83) for its plant (b_m: the least input gain; m_bar: K m without fault)."""

    design: Path
    example: Example
    b_m: float
    m_bar: float = 1.0


# Scenario -> its map (issue 35: the manipulator; its input gains 1, 1/M = 15.6, 1/L = 40: b_m = 1).
MAPS = {"manipulator": MapSpec(CAMPAIGNS / "manipulator_map.toml", MANIPULATOR, b_m=1.0)}


def run_map(name: str, out: Path, docs: Path | None, build: Path, workers: int, states: int = 21,
            report_only: bool = False) -> str:
    """The map of scenario ``name`` (:data:`MAPS`): its campaign over the ``states`` x ``states`` grid
    (``report_only``: the table an earlier run left in ``out/<name>/``), the table with T_m of eq.
    (83) beside the worst settling time, the settling and peak |v| maps (``out/<name>_settling.png``,
    ``<name>_peak_v.png``); ``out/<name>.md`` and, with ``docs``, a copy of the table and the settling
    map there. Returns the Markdown."""
    started = time.perf_counter()
    spec = MAPS[name]
    out.mkdir(parents=True, exist_ok=True)
    timing_path = out / name / TIMING_NAME
    if report_only:
        rows = read_table(out / name / "runs.parquet")[0]
    else:
        design = on_grid(read_design(spec.design), states)
        summary = sweep([build / "ssp" / f"{name}.ssp"], design, out / name,
                        metrics=metrics_for(TRACKING, scenario_sampling(name)), workers=workers, force=True)
        rows = read_table(summary.parquet)[0]
        timing_path.write_text(json.dumps({"wall": time.perf_counter() - started, "workers": workers}),
                               encoding="utf-8")
    timing = json.loads(timing_path.read_text(encoding="utf-8"))
    number, example = spec.example.number, spec.example
    configurations: dict[tuple[int, str, str], list[Cell]] = {
        (number, law, sampling): [] for law in LAWS.values() for sampling in SAMPLINGS[:2]}
    for r in rows:
        law = LAWS[FINITE_TIME if int(r["controller.mode"]) else FIXED_TIME]
        configurations[(number, law, SAMPLINGS[int(r["controller.discretization"])])] += cells_from_rows([r])
    bound = fixed_time_bound(example.controller, b_m=spec.b_m, m_bar=spec.m_bar, phi=0.5)
    panels = [(f"{law}, {sampling}", cells) for (_, law, sampling), cells in configurations.items()]
    figures = [f"{name}_settling.png", f"{name}_peak_v.png"]
    draw_maps(panels, "settling", "settling time (s), band 0.05", out / figures[0],
              title=f"{example.name}: settling time from x(0) (x3(0) = 0), {states} x {states} grid; "
                    f"T_m of eq. (83) = {bound.t_m:.3g} s (Phi = 0.5)")
    draw_maps(panels, "peak_v", "peak abs(v)", out / figures[1], log=True,
              title=f"{example.name}: peak abs(v)")
    text = "\n\n".join([
        f"# The fixed-time claim, measured: {example.name}",
        f"Wall time {timing['wall']:.0f} s for {len(rows)} co-simulation runs, {timing['workers']} worker "
        f"processes. Horizon "
        f"{HORIZON:g} s, band {BAND:g}; initial states on a {states} x {states} grid over [-10, 10]^2, "
        f"sampled at {example.controller.sample_time * 1e3:g} ms as the scenario ships; T_m with b_m = "
        f"{spec.b_m:g}, m_bar = {spec.m_bar:g} (no fault within the horizon).",
        study_table(configurations, {number: bound}),
        f"T_m of eq. (83) for n = {example.controller.n}:",
        bound_table(bound),
    ]) + "\n\n"
    links = "\n".join(f"![{f}]({f})" for f in figures)
    (out / f"{name}.md").write_text(text + links + "\n", encoding="utf-8")
    if docs is not None:
        docs.mkdir(parents=True, exist_ok=True)
        (docs / f"{name}.md").write_text(text + f"![{figures[0]}]({figures[0]})\n", encoding="utf-8")
        (docs / figures[0]).write_bytes((out / figures[0]).read_bytes())
    return text


def main(argv: Sequence[str] | None = None) -> int:
    """Run the study and print its table and wall time."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.fixed_time_study",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder ({DEFAULT_OUT})")
    parser.add_argument("--docs", type=Path, default=None, help="also copy the table and figures here")
    parser.add_argument("--build", type=Path, default=Path("build"), help="built scenarios (default build/)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--continuous-states", type=int, default=11,
                        help="grid points per axis for the continuous law (default 11)")
    parser.add_argument("--states", type=int, default=21, choices=(3, 6, 11, 21),
                        help="grid points per axis of the sampled runs: the designs' 21, or a subgrid "
                             "of it (default 21)")
    parser.add_argument("--report-only", action="store_true",
                        help="redraw the table and figures from the tables of an earlier run in --out")
    parser.add_argument("--map", choices=sorted(MAPS), default=None,
                        help="instead, the map of this scenario (its own campaign design and T_m)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    if args.map is not None:
        print(run_map(args.map, args.out, args.docs, args.build, args.workers, args.states, args.report_only))
        print(f"study-fixed-time --map {args.map}: wall time {time.perf_counter() - started:.0f} s")
        return 0
    text = run_study(args.out, args.docs, args.build, args.workers, args.continuous_states, args.report_only,
                     args.states)
    print(text)
    elapsed = time.perf_counter() - started
    if args.report_only:
        print(f"study-fixed-time: table and figures redrawn in {elapsed:.0f} s (the study's own time above)")
    else:
        print(f"study-fixed-time: wall time {elapsed:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
