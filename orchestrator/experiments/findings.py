# SPDX-License-Identifier: BSD-2-Clause
"""Summary tables and one-line answers of issue 37's research questions on runs of the engine.

Each function takes the rows of a campaign table (``read_table``'s dicts: parameters, ``status``
and the metric columns of :data:`~orchestrator.experiments.campaigns.RESEARCH`) and returns
Markdown tables and an answer whose every number is a cell of those tables (the page's
text-versus-data test checks it): :func:`recovery` (time back inside the pre-fault band, per
scenario and law), :func:`estimates` (eta_hat bounded? converging?), :func:`nn_term` (the law
without its NN term against the full law, per initial state), :func:`eq84` (the paper's bound on
the tracking error, as far as the paper gives its constants).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from controller.params import ControllerParameters
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2, Example
from fmu_src.models.plants import PendulumParameters

from .caps import rows_cap_cell
from .fixed_time_study import study_bounds

__all__ = ["EXAMPLES", "Summary", "eq84", "eq84_known_part", "eq84_terms", "estimates",
           "nn_grid", "nn_term", "recovery"]

Row = Mapping[str, Any]
# the share of samples with the semi-implicit cap binding, per step (orchestrator/experiments/caps.py)
CAP_COLUMN = "cap active, share of samples (step 1 / 2)"
# (tables, answer)
Summary = tuple[list[str], str]


def value(row: Row, name: str) -> float:
    """A column as a float; NaN where the run left it empty (None)."""
    cell = row.get(name)
    return math.nan if cell is None else float(cell)


def _law(row: Row) -> str:
    return "fixed-time" if int(value(row, "controller.mode")) == 0 else "finite-time"


def _cell(x: float, spec: str = ".3g") -> str:
    """A table cell: "never" for inf, "-" for NaN (nothing to report)."""
    if math.isinf(x):
        return "never"
    return "-" if math.isnan(x) else format(x, spec)


def _table(header: Sequence[str], lines: Sequence[Sequence[str]]) -> str:
    return "\n".join(["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
                     + ["| " + " | ".join(cells) + " |" for cells in lines])


def _groups(rows: Sequence[Row], key: Callable[[Row], tuple[str, ...]]) -> dict[tuple[str, ...], list[Row]]:
    out: dict[tuple[str, ...], list[Row]] = {}
    for r in sorted(rows, key=lambda r: (str(r["scenario"]), key(r))):
        out.setdefault(key(r), []).append(r)
    return out


def _stat(values: Sequence[float] | np.ndarray, how: Callable[[np.ndarray], Any]) -> float:
    return float(how(np.asarray(values))) if len(values) else math.nan


def recovery(rows: Sequence[Row]) -> Summary:
    """Per scenario and law: runs, runs ok, runs back inside the pre-fault band (finite
    ``recovery_time``), runs that never return within the horizon, median and largest recovery time,
    the median pre-fault band ``recovery_band`` and the median of the largest error after the fault
    over it (how far the fault pushes the error out of its band)."""
    header = ("scenario", "law", "runs", "ok", "back in band", "never back", "median recovery (s)",
              "max recovery (s)", "median band", "median peak after fault / band", CAP_COLUMN)
    lines, parts = [], []
    groups = _groups(rows, lambda r: (str(r["scenario"]), _law(r)))
    for (scenario, law), runs in groups.items():
        ok = [r for r in runs if r["status"] == "ok"]
        times = [value(r, "recovery_time") for r in ok]
        back = [t for t in times if math.isfinite(t)]
        never = sum(math.isinf(t) for t in times)
        median, largest = _stat(back, np.median), _stat(back, np.max)
        band = _stat([value(r, "recovery_band") for r in ok], np.median)
        peak = _stat([value(r, "max_error_after_fault") / value(r, "recovery_band") for r in ok], np.median)
        lines.append((scenario, law, str(len(runs)), str(len(ok)), str(len(back)), str(never), _cell(median),
                      _cell(largest), _cell(band), _cell(peak), rows_cap_cell(runs)))
        parts.append(f"{scenario} {law}: {len(back)} of {len(runs)} runs back in band "
                     f"(median {_cell(median)} s, max {_cell(largest)} s), {never} never")
    return [_table(header, lines)], "; ".join(parts) + "."


def estimates(rows: Sequence[Row]) -> Summary:
    """Per scenario and law, over the runs that end ok: the largest eta_hat_i, the median final
    value and the largest |change over the last window| (``eta<i>_change``), and the runs that
    failed (their estimates are reported only as far as they ran)."""
    header = ("scenario", "law", "runs", "ok", "max eta_hat_1", "max eta_hat_2", "median final eta_hat_1",
              "median final eta_hat_2", "max abs change eta_hat_1", "max abs change eta_hat_2", CAP_COLUMN)
    lines, parts = [], []
    for (scenario, law), runs in _groups(rows, lambda r: (str(r["scenario"]), _law(r))).items():
        ok = [r for r in runs if r["status"] == "ok"]
        cells = [_stat([value(r, f"eta{i}_max") for r in ok], np.max) for i in (1, 2)]
        cells += [_stat([value(r, f"eta{i}_final") for r in ok], np.median) for i in (1, 2)]
        cells += [_stat([abs(value(r, f"eta{i}_change")) for r in ok], np.max) for i in (1, 2)]
        lines.append((scenario, law, str(len(runs)), str(len(ok)), *(_cell(c) for c in cells),
                      rows_cap_cell(runs)))
        parts.append(f"{scenario} {law} ({len(ok)} runs ok): eta_hat_1 <= {_cell(cells[0])}, eta_hat_2 <= "
                     f"{_cell(cells[1])}, change over the last second <= {_cell(cells[4])} and "
                     f"{_cell(cells[5])}")
    return [_table(header, lines)], "; ".join(parts) + "."


def _settled(r: Row | None) -> bool:
    return r is not None and r["status"] == "ok" and math.isfinite(value(r, "settling_time"))


def nn_term(rows: Sequence[Row]) -> Summary:
    """The law without its NN term (``controller.nn_term`` 0) against the full law (1): per scenario
    and switch, runs ok (not diverged), runs settled, median and largest settling time, medians of
    peak |v|, of the integral of v^2 and of the MAE; then per scenario, paired by initial state, how
    many settle with both, only with or only without the term, the median and the largest
    |change| of the settling time (off minus on) where both settle, and the median ratio of the
    integral of v^2 and the median and largest ratio of the MAE (off over on)."""
    header = ("scenario", "NN term", "runs", "ok", "settled", "median settling (s)", "max settling (s)",
              "median peak abs(v)", "median int v^2 dt", "median MAE", CAP_COLUMN)

    def switch(r: Row) -> tuple[str, str]:
        return str(r["scenario"]), "on" if value(r, "controller.nn_term") else "off"

    lines = [_nn_switch_line(scenario, on, runs) for (scenario, on), runs in _groups(rows, switch).items()]
    paired_header = ("scenario", "initial states", "settle with both", "only with the term", "only without",
                     "median settling change (s)", "max abs settling change (s)", "median ratio int v^2 dt",
                     "median ratio MAE", "max ratio MAE")
    paired, parts = [], []
    for scenario in sorted({str(r["scenario"]) for r in rows}):
        line, part = _nn_paired(scenario, [r for r in rows if r["scenario"] == scenario])
        paired.append(line)
        parts.append(part)
    return [_table(header, lines), _table(paired_header, paired)], "; ".join(parts) + "."


def _nn_switch_line(scenario: str, on: str, runs: Sequence[Row]) -> tuple[str, ...]:
    """The row of :func:`nn_term`'s first table for one scenario and switch."""
    settled = [r for r in runs if _settled(r)]
    times = [value(r, "settling_time") for r in settled]
    ok = sum(r["status"] == "ok" for r in runs)
    return (scenario, on, str(len(runs)), str(ok), str(len(settled)),
            _cell(_stat(times, np.median)), _cell(_stat(times, np.max)),
            *(_cell(_stat([value(r, m) for r in settled], np.median), ".4g")
              for m in ("peak_v", "energy_v", "mae")), rows_cap_cell(runs))


def _by_state(rows: Sequence[Row]) -> dict[tuple[float, float], dict[bool, Row]]:
    """The runs by initial state (x1(0), x2(0)), then by the NN term's switch."""
    states: dict[tuple[float, float], dict[bool, Row]] = {}
    for r in rows:
        states.setdefault((value(r, "plant.x1_0"), value(r, "plant.x2_0")), {})[
            bool(value(r, "controller.nn_term"))] = r
    return states


def _nn_paired(scenario: str, rows: Sequence[Row]) -> tuple[tuple[str, ...], str]:
    """:func:`nn_term`'s paired row of one scenario's ``rows`` (the runs with and without the term
    from each initial state side by side), and its sentence."""
    states = _by_state(rows)
    both = [s for s in states.values() if _settled(s.get(True)) and _settled(s.get(False))]
    only_on = sum(_settled(s.get(True)) and not _settled(s.get(False)) for s in states.values())
    only_off = sum(_settled(s.get(False)) and not _settled(s.get(True)) for s in states.values())
    change = [value(s[False], "settling_time") - value(s[True], "settling_time") for s in both]
    ratio = [value(s[False], "energy_v") / value(s[True], "energy_v") for s in both]
    mae = [value(s[False], "mae") / value(s[True], "mae") for s in both]
    median, largest = _stat(change, np.median), _stat(np.abs(change), np.max)
    energy, mae_median, mae_max = _stat(ratio, np.median), _stat(mae, np.median), _stat(mae, np.max)
    line = (scenario, str(len(states)), str(len(both)), str(only_on), str(only_off),
            _cell(median, ".3g"), _cell(largest, ".3g"), _cell(energy, ".4g"),
            _cell(mae_median, ".4g"), _cell(mae_max, ".4g"))
    part = (f"{scenario}: of {len(states)} initial states {len(both)} settle with and without the "
            f"term, {only_on} only with it, {only_off} only without; settling changes by "
            f"{_cell(largest)} s at most (median {_cell(median)} s), int v^2 dt by a median factor "
            f"{_cell(energy, '.4g')}, the MAE by a median factor {_cell(mae_median, '.4g')} "
            f"(at most {_cell(mae_max, '.4g')})")
    return line, part


# The scenario of each example in the study's campaigns, and its controller's gains.
EXAMPLES = {"example1_smooth": ("Example 1", EXAMPLE1),
            "pendulum_smooth": ("Example 2, the pendulum", EXAMPLE2)}


def eq84_known_part(params: ControllerParameters) -> float:
    """The part of x_0 = b_0 + c_0 (eq. 79, 77) fixed by the design constants alone: sum a_j^2 / 2 +
    (1 - alpha) alpha^(1 - alpha) + (1 - beta) beta^(1 - beta). Every other term of b_0 and c_0 is
    a square, a bound of a non-negative quantity or a constant of Lemma 6 times a positive design
    constant (eq. 30-33, 62-63, 77), so x_0 is at least this (:func:`eq84_terms` adds the plant's)."""
    alpha, beta = params.alpha, params.beta
    return (sum(a * a / 2.0 for a in params.a) + (1.0 - alpha) * alpha ** (1.0 - alpha)
            + (1.0 - beta) * beta ** (1.0 - beta))


def eq84_terms(example: Example) -> tuple[float, float, float]:
    """(design part, b_m beta_bar^2 / 2, sum d_j*^2 / 2) of x_0 that the paper gives numbers for:
    :func:`eq84_known_part`; beta_bar = max(m_r b_r, m_l b_l) of eq. (7) (0.72 for the examples'
    dead-zone) with b_m = 1 as the study's T_m; the disturbance bounds d_j* of Assumption 4 from the
    plant's own disturbances (eq. 99: 0.2 sin t and 0.3 cos t give d_1* >= 0.2, d_2* >= 0.3; Example
    1, eq. 85, has none, so d_j* may be any positive number: 0 in the bound)."""
    act = example.actuator
    beta_bar = max(act.m_r * act.b_r, act.m_l * act.b_l)
    plant = example.plant
    disturbances = (plant.d1, plant.d2) if isinstance(plant, PendulumParameters) else ()
    return (eq84_known_part(example.controller), 1.0 * beta_bar * beta_bar / 2.0,
            sum(d * d / 2.0 for d in disturbances))


def eq84(rows: Sequence[Row]) -> Summary:
    """Eq. (84), |y - yd| <= 2 (x_0 / ((1 - Phi) c))^(1 / (2 alpha)), from what the paper gives: per
    example, the known terms of x_0 (:func:`eq84_terms`) and their sum, c of eq. (77) as the study
    computes it (:func:`~orchestrator.experiments.fixed_time_study.study_bounds`: b_m = m_bar = 1,
    Phi = 0.5), the lower bound of the right-hand side at Phi = 0.5 and for any Phi (1 - Phi < 1,
    c <= a_bar), and the largest final |y - yd| of the full law's settled runs in ``rows`` (the NN
    term campaign)."""
    header = ("example", "a_j^2 / 2 + alpha, beta terms", "b_m beta_bar^2 / 2 (eq. 7)",
              "sum d_j*^2 / 2 (eq. 99)", "known part of x_0", "c (eq. 77)", "a_bar",
              "bound at least, Phi = 0.5",
              "bound at least, any Phi", "largest final abs(y - yd), settled runs")
    lines, parts = [], []
    for scenario, (name, example) in EXAMPLES.items():
        params = example.controller
        design, fault, disturbance = eq84_terms(example)
        known, c = design + fault + disturbance, study_bounds(params).constant("c")
        at_half = 2.0 * (known / (0.5 * c)) ** (1.0 / (2.0 * params.alpha))
        any_phi = 2.0 * (known / params.a_bar) ** (1.0 / (2.0 * params.alpha))
        final = _stat([value(r, "final_error") for r in rows if r["scenario"] == scenario
                       and value(r, "controller.nn_term") and _settled(r)], np.max)
        lines.append((name, _cell(design, ".4g"), _cell(fault, ".4g"), _cell(disturbance, ".4g"),
                      _cell(known, ".4g"), _cell(c, ".4g"), _cell(params.a_bar, ".4g"),
                      _cell(at_half, ".3g"), _cell(any_phi, ".3g"), _cell(final, ".3g")))
        parts.append(f"{scenario}: the bound is at least {_cell(any_phi)} for any Phi ({_cell(at_half)} at "
                     f"the study's Phi), the runs end within {_cell(final)}")
    return [_table(header, lines)], ("Not evaluable: x_0 needs constants the paper never gives; its known "
                                     "part alone makes the bound vacuous. " + "; ".join(parts) + ".")


NN_GRID = ("controller.a1", "controller.kappa1", "controller.q1")
EFFECT = 0.05  # a relative change of the MAE below this is no measurable effect


def _sampling(scenario: str) -> str:
    return "semi-implicit" if scenario.endswith("_smooth") else "explicit"


def nn_grid(rows: Sequence[Row]) -> Summary:
    """The NN term over a grid of (a, kappa, q) (``ssp/campaigns/nn_grid.toml``): per scenario and
    law, the grid points paired by (a, kappa, q), the term on against off. A point where both runs
    settle (end ok, inside the band at the end) is *helped* when the term cuts the MAE by more than
    :data:`EFFECT` (MAE on < (1 - EFFECT) MAE off), *hurt* when it raises it by more, else *no
    effect*; *destabilised* when only the run without the term settles (the one with it diverges or
    runs away inside the horizon), *stabilised* when only the run with it does. Beside the counts:
    the point with the largest cut of the MAE (its ratio on / off and its settling times off -> on)
    and the share of samples the semi-implicit cap bound with the term on."""
    header = ("scenario", "sampling", "law", "points", "term helps", "no effect", "term hurts",
              "destabilised by the term", "stabilised by the term", "neither settles",
              "largest MAE cut: MAE on / off at (a, kappa, q)", "settling off -> on there (s)", CAP_COLUMN)
    lines, parts = [], []
    totals = dict.fromkeys(("points", "helps", "none", "hurts", "destabilised", "stabilised", "fail"), 0)
    for (scenario, law), runs in _groups(rows, lambda r: (str(r["scenario"]), _law(r))).items():
        points: dict[tuple[float, ...], dict[bool, Row]] = {}
        for r in runs:
            key = tuple(value(r, p) for p in NN_GRID)
            points.setdefault(key, {})[bool(value(r, "controller.nn_term"))] = r
        counts, best = _nn_effects(points)
        where, settling = "-", "-"
        if best is not None:
            ratio, key = best
            on, off = points[key][True], points[key][False]
            where = f"{ratio:.3g} at ({key[0]:g}, {key[1]:g}, {key[2]:g})"
            settling = f"{_cell(value(off, 'settling_time'))} -> {_cell(value(on, 'settling_time'))}"
        lines.append((scenario, _sampling(scenario), law, str(counts["points"]), str(counts["helps"]),
                      str(counts["none"]), str(counts["hurts"]), str(counts["destabilised"]),
                      str(counts["stabilised"]), str(counts["fail"]), where, settling,
                      rows_cap_cell([r for r in runs if value(r, "controller.nn_term")])))
        for name in totals:
            totals[name] += counts[name]
    a, kappa, q = ({value(r, p) for r in rows} for p in NN_GRID)
    grid = (f"a in {_values(a)}, kappa in {_values(kappa)}, q in {_values(q)} (the same for both steps; "
            "k and rho as the scenario ships them)")
    parts.append(f"Scope: {grid}, both laws, from each scenario's initial state, 3 s, no fault; "
                 f"of {totals['points']} (scenario, law, a, kappa, q) points the term cuts the MAE by "
                 f"more than {EFFECT:.0%} at {totals['helps']}, has no effect at {totals['none']}, "
                 f"raises it at {totals['hurts']}, destabilises the sampled loop at "
                 f"{totals['destabilised']} (only the run without it settles), stabilises it at "
                 f"{totals['stabilised']}, and neither run settles at {totals['fail']}")
    return [_table(header, lines)], "; ".join(parts) + "."


def _nn_effects(
    points: Mapping[tuple[float, ...], Mapping[bool, Row]]
) -> tuple[dict[str, int], tuple[float, tuple[float, ...]] | None]:
    """:func:`nn_grid`'s counts over the grid points (each the runs with, True, and without the
    term): paired points, helped, no effect, hurt, destabilised, stabilised, neither settles; and
    the point with the smallest MAE ratio on / off where both settle (ratio, point), if any."""
    counts = dict.fromkeys(("points", "helps", "none", "hurts", "destabilised", "stabilised", "fail"), 0)
    best: tuple[float, tuple[float, ...]] | None = None
    for key, pair in points.items():
        on, off = pair.get(True), pair.get(False)
        if on is None or off is None:
            continue
        counts["points"] += 1
        effect, ratio = _nn_effect(on, off)
        counts[effect] += 1
        if ratio is not None and (best is None or ratio < best[0]):
            best = (ratio, key)
    return counts, best


def _nn_effect(on: Row, off: Row) -> tuple[str, float | None]:
    """What the term does at one grid point (its runs with and without it): fail (neither settles),
    destabilised, stabilised, or, where both settle, helps, none or hurts, with the MAE ratio on / off
    (None where not both settle)."""
    ok_on, ok_off = _settled(on), _settled(off)
    if not ok_on:
        return ("destabilised" if ok_off else "fail"), None
    if not ok_off:
        return "stabilised", None
    ratio = value(on, "mae") / value(off, "mae")
    return ("helps" if ratio < 1 - EFFECT else "hurts" if ratio > 1 + EFFECT else "none"), ratio


def _values(values: set[float]) -> str:
    return "{" + ", ".join(f"{v:g}" for v in sorted(values)) + "}"
