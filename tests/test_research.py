# SPDX-License-Identifier: BSD-2-Clause
"""Issue 37, item 3: the research-question page is generated from the campaigns' tables.

Oracles: hand-computed medians and counts of small tables, the paper's eq. (77)-(84) written out
by hand, a plain run of the scenario (the NN term's switch defaults to the paper's law), and the
committed generated page itself (every number of an answer line is in its own tables: text and
data agree)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from orchestrator import RunOptions, run
from orchestrator.campaign import Design, read_design, read_table, sweep
from orchestrator.experiments import findings
from orchestrator.experiments.campaigns import RESEARCH
from orchestrator.experiments.research import QUESTIONS, answer, run_table

REPO = Path(__file__).resolve().parent.parent
PAGE = REPO / "docs" / "research" / "index.md"


def _rows() -> list[dict]:
    rows = []
    for k1 in (5.0, 10.0):
        for k2 in (5.0, 10.0):
            rows.append({"controller.k1": k1, "controller.k2": k2, "status": "ok",
                         "settling_time": 0.1 / k2, "peak_v": 100.0 * k1, "energy_v": k1 * k2,
                         "effort_v": 1.0, "effort_uf": 1.0, "mae": 0.01})
    return rows


def test_the_answer_is_the_medians_of_the_table() -> None:
    line = answer(_rows(), QUESTIONS[0])
    # k1 5 -> 10: settling median of (0.02, 0.01) both times; peak 500 -> 1000; energy median(25, 50)
    # = 37.5 -> median(50, 100) = 75
    assert ("k1 from 5 to 10: settling 0.015 -> 0.015 s, peak abs(v) 500 -> 1000, int v^2 dt 37.5 -> 75"
            in line)
    assert "k2 from 5 to 10: settling 0.02 -> 0.01 s" in line


def test_the_table_has_one_sorted_row_per_run() -> None:
    lines = run_table(list(reversed(_rows())), QUESTIONS[0]).splitlines()
    assert len(lines) == 2 + 4 and lines[2].startswith("| 5 | 5 | 0.02 | 500 |")


def test_the_committed_page_answers_from_its_own_tables() -> None:
    text = PAGE.read_text(encoding="utf-8")
    sections = text.split("\n## ")[1:]
    assert [s.splitlines()[0] for s in sections[-4:]] == [
        "Recovery after the fault", "The adaptive estimates eta_hat", "The NN term's contribution",
        "Eq. (84), the bound on the tracking error"]
    for section in sections:
        answer_line = next(line for line in section.splitlines() if line.startswith("**Answer.**"))
        table = "\n".join(line for line in section.splitlines() if line.startswith("| "))
        cells = {float(c) for c in re.findall(r"(?<=\| )-?\d+(?:\.\d+)?(?:e[+-]?\d+)?(?= \|)", table)}
        numbers = [float(n) for n in re.findall(r"(?<![\w.^])\d+(?:\.\d+)?(?:e[+-]?\d+)?", answer_line)]
        # every value an answer gives is a median over three runs of the table: one of its cells
        # (medians of three are cells), the gains too
        assert all(n in cells for n in numbers), (section.splitlines()[0], sorted(set(numbers) - cells))



def _fault_row(scenario: str, mode: int, recovery: float, band: float, peak: float) -> dict:
    return {"scenario": scenario, "controller.mode": mode, "status": "ok", "recovery_time": recovery,
            "recovery_band": band, "max_error_after_fault": peak}


def test_recovery_counts_never_apart_from_failed_runs() -> None:
    rows = [_fault_row("example1", 0, t, 1e-3, 2e-3) for t in (1.0, 3.0, 2.0, math.inf)]
    rows.append({"scenario": "example1", "controller.mode": 0, "status": "failed", "recovery_time": None,
                 "recovery_band": None, "max_error_after_fault": None})
    tables, line = findings.recovery(rows)
    # 5 runs, 4 ok, 3 back (median 2, max 3), 1 never (inf is not a failure), band 0.001, peak / band 2
    assert tables[0].splitlines()[2] == "| example1 | fixed-time | 5 | 4 | 3 | 1 | 2 | 3 | 0.001 | 2 |"
    assert line == "example1 fixed-time: 3 of 5 runs back in band (median 2 s, max 3 s), 1 never."


def test_nn_term_pairs_the_runs_of_each_initial_state() -> None:
    def row(x1: float, nn: int, settling: float, energy: float) -> dict:
        return {"scenario": "s", "plant.x1_0": x1, "plant.x2_0": 0.0, "controller.nn_term": nn,
                "status": "ok", "settling_time": settling, "energy_v": energy, "peak_v": 1.0, "mae": 0.1}

    rows = [row(0, 1, 0.5, 10.0), row(0, 0, 0.75, 5.0), row(1, 1, 0.5, 8.0), row(1, 0, 0.25, 8.0),
            row(2, 1, 0.2, 1.0), row(2, 0, math.inf, 1.0)]
    tables, line = findings.nn_term(rows)
    # both settle from x1 = 0, 1: changes +0.25, -0.25 (median 0, largest 0.25), ratios 0.5, 1 (median 0.75)
    assert tables[1].splitlines()[2] == "| s | 3 | 2 | 1 | 0 | 0 | 0.25 | 0.75 | 1 | 1 |"
    assert "of 3 initial states 2 settle with and without the term, 1 only with it, 0 only without" in line


def test_eq84_lower_bound_written_out() -> None:
    """Eq. (77), (79), (84) for Example 1 (a = 5, 2; alpha = 1.5, beta = 0.75; c = a_bar = 1 as the
    study's T_m has it): x_0 >= 12.5 + 2 - 0.5 / sqrt(1.5) + 0.25 * 0.75^0.25 = 14.3244, so
    abs(y - yd) <= 2 (x_0 / (0.5 c))^(1/3) is at least 6.12 at Phi = 0.5, 4.86 for any Phi."""
    known = 12.5 + 2.0 - 0.5 / math.sqrt(1.5) + 0.25 * 0.75**0.25
    assert findings.eq84_known_part(findings.EXAMPLE1.controller) == known
    lines = findings.eq84([])[0][0].splitlines()
    assert lines[2] == (f"| Example 1 | {known:.4g} | 1 | 1 | {2 * (known / 0.5) ** (1 / 3):.3g} | "
                        f"{2 * known ** (1 / 3):.3g} | - |")
    assert "| Example 1 | 14.32 | 1 | 1 | 6.12 | 4.86 |" in PAGE.read_text(encoding="utf-8")


def test_recovery_campaign_runs_the_fault_campaigns_faults() -> None:
    tolerance = read_design(REPO / "ssp" / "campaigns" / "fault_tolerance.toml")
    recovery = read_design(REPO / "ssp" / "campaigns" / "fault_recovery.toml")
    assert recovery.variants() == tolerance.variants() and recovery.stop_time == tolerance.stop_time


def test_a_tiny_research_campaign(built: Path, tmp_path: Path) -> None:
    """Two runs of Example 1 (NN term on and off, fault at 1.5 s, 2.5 s) through the engine's sweep
    with the research metrics: the NN term on is the scenario as it runs without the switch (a plain
    run: the paper's law), its eta_hat columns are those of that run's trajectory, and off differs."""
    scenario = built / "ssp" / "example1.ssp"
    design = Design(source="tiny", columns=("controller.nn_term",), points=((1,), (0,)),
                    fixed={"actuator.t_fault": 1.5}, stop_time=2.5)
    rows = {int(r["controller.nn_term"]): r
            for r in read_table(sweep([scenario], design, tmp_path / "c", metrics=RESEARCH, workers=1,
                                      progress=False).parquet)[0]}
    plain = run(scenario, RunOptions(stop_time=2.5, overrides={"actuator.t_fault": 1.5})).rows
    error = np.abs(plain["plant.y"] - plain["reference.yd"])
    assert rows[1]["mae"] == float(np.mean(error))
    assert rows[1]["eta1_max"] == float(np.max(plain["controller.eta1_hat"]))
    assert rows[1]["eta2_final"] == float(plain["controller.eta2_hat"][-1])
    assert rows[1]["recovery_band"] == float(np.max(error[(plain["time"] >= 0.5) & (plain["time"] < 1.5)]))
    assert rows[0]["status"] == "ok" and rows[0]["mae"] != rows[1]["mae"]
