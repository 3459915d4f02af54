# SPDX-License-Identifier: BSD-2-Clause
"""The research questions a reader of the paper asks next (issue 37), as shipped campaigns.

``python -m orchestrator.experiments.research`` (``make research``) runs the campaign designs of
:data:`QUESTIONS` through ``orchestrate sweep``'s engine (``--report-only``: from the tables an
earlier run left) and writes ``docs/research/index.md``: per design the table of its runs (every
number generated from ``runs.parquet``), a one-line answer computed from them, and its figures.
Remark 6, the gains k_i, q_i, rho_i and a_i, each halved and doubled around the paper's values,
with the control effort (integrals of |v|, v^2, |uf|) beside settling time, peak |v| and tracking
error; then the questions of :data:`FINDINGS` (recovery after the fault, the adaptive estimates,
the NN term's contribution), summarised by :mod:`orchestrator.experiments.findings` from runs with
the metrics of :data:`~orchestrator.experiments.campaigns.RESEARCH`; and the text of :data:`EQ84`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..campaign import Metrics, read_design, read_table, sweep
from ..campaign.report import write_report
from . import findings
from .campaigns import RESEARCH, TRACKING
from .caps import metrics_for, rows_cap_cell, scenario_sampling
from .fixed_time_study import on_grid

__all__ = ["EQ84", "FINDINGS", "QUESTIONS", "Finding", "Question", "answer", "main", "run_table",
           "write_page"]

CAMPAIGNS = Path("ssp") / "campaigns"
DEFAULT_OUT = Path("results") / "campaigns"
DEFAULT_DOCS = Path("docs") / "research"
COLUMNS = (("settling_time", "settling (s)", ".3g"), ("peak_v", "peak abs(v)", ".4g"),
           ("effort_v", "int abs(v) dt", ".4g"), ("energy_v", "int v^2 dt", ".4g"),
           ("effort_uf", "int abs(uf) dt", ".4g"), ("mae", "MAE", ".3g"))


@dataclass(frozen=True)
class Question:
    """A research question: its campaign design, the scenario it runs and the two parameters it
    varies (their names in the table)."""

    title: str
    design: str
    scenario: str
    parameters: tuple[str, str]


QUESTIONS = tuple(
    Question(f"Remark 6: the gains {g}_1, {g}_2", f"gains_{g}", "example1_no_fault",
             (f"controller.{g}1", f"controller.{g}2"))
    for g in ("k", "q", "rho", "a")
)


@dataclass(frozen=True)
class Finding:
    """A research question summarised over its campaign: the design, its scenarios, what the
    page says of its definitions (``note``) and the summary (tables, answer) of its rows."""

    title: str
    design: str
    scenarios: tuple[str, ...]
    note: str
    summary: Callable[[Sequence[Mapping[str, Any]]], findings.Summary]
    figures: bool = True  # False: the design's figures are shown with another question


FINDINGS = (
    Finding("Recovery after the fault", "fault_recovery", ("example1", "pendulum"),
            "The fault-tolerance campaign's 40 faults (`fault_tolerance.toml`'s Latin hypercube) on both "
            "examples and both laws, 12 s. **Recovery time**: the time after t_fault until abs(y - yd) is "
            "back inside its pre-fault band for good; the band is the largest abs(y - yd) over the second "
            "before t_fault (`orchestrator/experiments/metrics.py`, `recovery_time`). A run whose error "
            "is still outside the band at its end is *never back* (within the horizon): an answer, not a "
            "failed run. Zero: the error never left the band.", findings.recovery),
    Finding("The adaptive estimates eta_hat", "estimates", ("example1_smooth", "pendulum_smooth"),
            "The controller FMUs output eta1_hat and eta2_hat (unchanged since issue 35). Over the study's "
            "initial states (the grid above), both laws, "
            "semi-implicit sampling, 4 s: the largest estimate of each run, its final value and its change "
            "over the run's last second (eta_hat(4 s) - eta_hat(3 s)). Runs that diverge are left out "
            "(counted as runs minus ok).", findings.estimates),
    Finding("The NN term's contribution", "nn_term", ("example1_smooth", "pendulum_smooth"),
            "The fixed-time law with its NN term eta_hat_i z_i P_i^T P_i / (2 a_i^2) switched out of every "
            "zeta_i (controller parameter `nn_term` = 0; the estimates still adapt) against the paper's "
            "law (`nn_term` = 1, bit for bit the law of before), semi-implicit sampling (under explicit "
            "sampling most of these states diverge either way), from the study's "
            "initial states (the grid above), 3 s. Settling: "
            "the 0.05 band. Paired table: per initial state, the two runs compared. Scope: the paper's "
            "gains, a and kappa only; the cap column shows how often the semi-implicit cap, not the "
            "law, set zeta_1 and v (where it binds, the NN term inside phi cannot act). Other (a, kappa, "
            "q), both laws, both samplings: the next question.", findings.nn_term),
    Finding("The NN term over (a, kappa, q)", "nn_grid",
            ("example1", "pendulum", "example1_smooth", "pendulum_smooth"),
            "The NN term switched out (`nn_term` = 0) against the paper's law over a grid of its width a, "
            "the adaptation gain kappa and the gain q (`ssp/campaigns/nn_grid.toml` and its points "
            "`nn_grid_points.csv`), both laws, on the paper's explicit sampling (`example1` at 1 ms, "
            "`pendulum` at 0.5 ms) and the semi-implicit one (`example1_smooth`, `pendulum_smooth`), "
            "from each scenario's own initial state, 3 s (before the fault). A point *helps* when the "
            "term cuts the MAE by more than 5 %, *hurts* when it raises it by more (both runs settle); "
            "*destabilised*: only the run without the term settles (the one with it diverges, and the "
            "plants' bounds end it, or runs away within the 3 s).",
            findings.nn_grid, figures=False),
)
EQ84 = Finding(
    "Eq. (84), the bound on the tracking error", "nn_term", ("example1_smooth", "pendulum_smooth"),
    "Eq. (84) reads abs(y - yd) <= 2 (x_0 / ((1 - Phi) c))^(1 / (2 alpha)) with x_0 = b_0 + c_0 (eq. 79). "
    "It cannot be evaluated for the paper's examples: b_0 (eq. 77) sums, per step j, "
    "(o_j + rho_tilde_j) eta_j^2 / (2 kappa_j) with eta_j = norm(W_j*)^2 / b_m (the ideal NN weights, "
    "never given), epsilon_j^2 / 2 (the NN approximation error bound, never given), l_j and sigma_j "
    "(Lemma 6 constants of the unknown bounds psi_j1, psi_j2 of Assumption 5) and b_j(t) (from the ISpS "
    "gains of Assumption 6), plus b_m L_bar^2 / 2 (the bound of the fault's L(t) = L_gain x2 cos^2 x1 + "
    "L_bias, bounded only once x2 is) and d / kappa_0 (d = 0.625 is given, eq. 90 and 104, but kappa_0 "
    "is a constant of the proof the law never uses, so the term may be as small as one likes); c_0 is "
    "\"assumed\" to bound a term on the set abs(z_1) < 0.8814 nu with nu never chosen. Three constants "
    "are given: beta_bar = max(m_r b_r, m_l b_l) = 0.72 of eq. (7) (the dead-zone's 1.2 x 0.6), entering "
    "as b_m beta_bar^2 / 2; d = 0.625; and the pendulum's disturbance bounds d_1* = 0.2, d_2* = 0.3 of "
    "eq. (99) (0.2 sin t, 0.3 cos t; Example 1 has no disturbance), entering as d_j*^2 / 2. Every "
    "other term is non-negative, so what the paper gives is a lower bound of x_0: sum a_j^2 / 2 + "
    "(1 - alpha) alpha^(1 - alpha) + (1 - beta) beta^(1 - beta) + b_m beta_bar^2 / 2 + sum d_j*^2 / 2 "
    "(`orchestrator/experiments/findings.py`, `eq84_terms`), with c of eq. (77) as the study's T_m uses "
    "it (b_m = m_bar = 1) and c <= a_bar for any b_m, m_bar. The bound of eq. (84) is at least the "
    "values below, against the largest final error of the full law's settled runs of the NN term "
    "campaign above.", findings.eq84, figures=False)


def run_table(rows: Sequence[Mapping[str, Any]], question: Question) -> str:
    """The Markdown table of a question's runs, sorted by its two parameters, with the share of
    samples where the semi-implicit cap bound (``-``: explicit sampling, no cap)."""
    a, b = question.parameters
    header = f"| {a} | {b} | " + " | ".join(label for _, label, _ in COLUMNS) + f" | {findings.CAP_COLUMN} |"
    lines = [header, "|" + "---|" * (3 + len(COLUMNS))]
    for r in sorted(rows, key=lambda r: (float(r[a]), float(r[b]))):
        cells = [f"{float(r[a]):g}", f"{float(r[b]):g}"]
        cells += [format(float(r[name]), spec) if r.get(name) is not None else "-"
                  for name, _, spec in COLUMNS]
        cells.append(rows_cap_cell([r]))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def answer(rows: Sequence[Mapping[str, Any]], question: Question) -> str:
    """One line from the data: over each parameter's smallest and largest value (medians over the
    other parameter), how settling time, peak |v| and the effort integral of v^2 change."""
    parts = []
    for p in question.parameters:
        values = sorted({float(r[p]) for r in rows})
        low, high = values[0], values[-1]

        def median(metric: str, at: float, p: str = p) -> float:
            return float(np.median([float(r[metric]) for r in rows if float(r[p]) == at]))

        parts.append(
            f"{p.split('.')[1]} from {low:g} to {high:g}: settling {median('settling_time', low):.3g} -> "
            f"{median('settling_time', high):.3g} s, peak abs(v) {median('peak_v', low):.4g} -> "
            f"{median('peak_v', high):.4g}, int v^2 dt {median('energy_v', low):.4g} -> "
            f"{median('energy_v', high):.4g}"
        )
    return "; ".join(parts) + " (medians over the other gain)."


def _figures(design: str, out: Path, docs: Path) -> list[str]:
    """The design's report figures (one report per scenario) copied into ``docs`` as Markdown images."""
    parts = []
    for figure in sorted((out / design).glob("*/report/*.png")):
        name = f"{design}_{figure.parent.parent.name}_{figure.name}"
        shutil.copyfile(figure, docs / name)
        parts.append(f"![{design}: {figure.stem}]({name})")
    return parts


def write_page(tables: Mapping[Question | Finding, Sequence[Mapping[str, Any]]], out: Path, docs: Path,
               seconds: float | None, states: int = 21) -> str:
    """``docs/index.md`` (the tables, answers and figures) with the figures copied from ``out``."""
    docs.mkdir(parents=True, exist_ok=True)
    parts = ["# Research questions (issue 37)",
             "Generated by `make research` (`python -m orchestrator.experiments.research`) from the runs "
             "of the shipped designs; no number on this page is typed by hand. Control effort: the "
             "integrals of the held signals abs(v), v^2 and abs(uf) (`orchestrator/experiments/metrics.py`). "
             f"Designs over initial states ran on {states} x {states} states of their 21 x 21 grid "
             "(`--states`). Cap column (issue 45): per backstepping step, the share of samples where the "
             "semi-implicit cap abs(z_i) / (b_max h) replaced the paper's feedback (mean over the row's "
             "runs; `orchestrator/experiments/caps.py`); `-`: explicit sampling, no cap."]
    if seconds is not None:
        parts.append(f"Wall time of the campaigns and this page: {seconds:.0f} s.")
    for question, rows in tables.items():
        if isinstance(question, Finding):
            summary_tables, line = question.summary(rows)
            parts += [f"## {question.title}",
                      f"Design `ssp/campaigns/{question.design}.toml`, scenarios "
                      + ", ".join(f"`{s}`" for s in question.scenarios)
                      + f", {len(rows)} runs, {sum(r['status'] == 'ok' for r in rows)} ok. {question.note}",
                      f"**Answer.** {line}", *summary_tables]
        else:
            parts += [f"## {question.title}",
                      f"Design `ssp/campaigns/{question.design}.toml`, scenario `{question.scenario}`, "
                      f"{len(rows)} runs, {sum(r['status'] == 'ok' for r in rows)} ok.",
                      f"**Answer.** {answer(rows, question)}", run_table(rows, question)]
        if not isinstance(question, Finding) or question.figures:
            parts += _figures(question.design, out, docs)
    text = "\n\n".join(parts) + "\n"
    (docs / "index.md").write_text(text, encoding="utf-8")
    return text


def _scenarios_and_metrics(question: Question | Finding) -> tuple[tuple[str, ...], Metrics]:
    """The scenarios a question or finding is swept over, and the metrics its table needs."""
    if isinstance(question, Question):
        return (question.scenario,), TRACKING
    return question.scenarios, RESEARCH


def _campaign(name: str, scenario: str, metrics: Metrics, out: Path, args: argparse.Namespace) -> None:
    """Design ``name`` (on the --states grid where it varies the initial state) swept over
    ``scenario`` into ``out``, with its campaign report."""
    design = read_design(CAMPAIGNS / f"{name}.toml")
    if "plant.x1_0" in design.columns:
        design = on_grid(design, args.states)
    summary = sweep([args.build / "ssp" / f"{scenario}.ssp"], design, out,
                    metrics=metrics_for(metrics, scenario_sampling(scenario)), workers=args.workers,
                    force=True)
    write_report(summary.parquet, out / "report")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the research campaigns (or redraw from their tables) and write the page."""
    parser = argparse.ArgumentParser(prog="python -m orchestrator.experiments.research",
                                     description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"campaign tables ({DEFAULT_OUT})")
    parser.add_argument("--docs", type=Path, default=DEFAULT_DOCS, help=f"the page's folder ({DEFAULT_DOCS})")
    parser.add_argument("--build", type=Path, default=Path("build"), help="built scenarios (default build/)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--report-only", action="store_true", help="from the tables of an earlier run")
    parser.add_argument("--states", type=int, default=21, choices=(3, 6, 11, 21),
                        help="grid points per axis of the designs over initial states: their 21, or a "
                             "subgrid (default 21)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    tables: dict[Question | Finding, list[dict[str, Any]]] = {}
    everything: tuple[Question | Finding, ...] = (*QUESTIONS, *FINDINGS, EQ84)
    for question in everything:
        folder = args.out / question.design
        scenarios, metrics = _scenarios_and_metrics(question)
        if not args.report_only and not any(q.design == question.design for q in tables):
            for s in scenarios:  # one sweep per scenario: its semi-implicit cap (caps.metrics_for)
                _campaign(question.design, s, metrics, folder / s, args)
        tables[question] = [r for s in scenarios for r in read_table(folder / s / "runs.parquet")[0]]
    timing = args.out / "wall_time.json"  # the campaigns' time, for a page redrawn with --report-only
    if not args.report_only:
        timing.write_text(json.dumps({"seconds": time.perf_counter() - started}), encoding="utf-8")
    seconds = json.loads(timing.read_text(encoding="utf-8"))["seconds"] if timing.is_file() else None
    text = write_page(tables, args.out, args.docs, seconds, args.states)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
