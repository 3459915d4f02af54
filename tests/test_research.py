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
import pytest

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


def _tables(section: str) -> list[list[dict[str, str]]]:
    """The section's Markdown tables as rows of {header: cell}."""
    tables, current, header = [], [], None
    for line in [*section.splitlines(), ""]:
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if header is None:
                header = cells
            elif not set(line) <= set("|-"):
                current.append(dict(zip(header, cells, strict=True)))
        elif header is not None:
            tables.append(current)
            current, header = [], None
    return tables


def _sections() -> dict[str, str]:
    text = PAGE.read_text(encoding="utf-8")
    return {s.splitlines()[0]: s for s in text.split("\n## ")[1:]}


def _answer(section: str) -> str:
    return next(line for line in section.splitlines() if line.startswith("**Answer.**"))


def _row(table: list[dict[str, str]], **key: str) -> dict[str, str]:
    rows = [r for r in table if all(r[k] == v for k, v in key.items())]
    assert len(rows) == 1, key
    return rows[0]


def _checked(answer_line: str, pattern: str, check) -> str:
    """Every match of ``pattern`` in the answer checked by ``check(match)``; the line without them."""
    matches = list(re.finditer(pattern, answer_line))
    assert matches, pattern
    for m in matches:
        check(m)
    return re.sub(pattern, "", answer_line)


def _no_number_left(rest: str) -> None:
    assert not re.findall(r"(?<![\w.^])\d+(?:\.\d+)?(?:e[+-]?\d+)?", rest.replace("**Answer.**", "")), rest


def test_each_number_of_the_gain_answers_is_the_median_of_its_own_column() -> None:
    """Remark 6: "k1 from 5 to 20: settling a -> b s, ..." -- a is the median of the settling column
    over the table's rows with k1 = 5, b over those with k1 = 20, and so on for every number."""
    sections = _sections()
    for question in QUESTIONS:
        section = sections[question.title]
        (table,) = _tables(section)

        def check(m: re.Match, table=table, title=question.title) -> None:
            column = f"controller.{m['p']}"
            for at, which in ((m["low"], 0), (m["high"], 1)):
                rows = [r for r in table if float(r[column]) == float(at)]
                assert rows
                for label, group in (("settling (s)", "s"), ("peak abs(v)", "v"), ("int v^2 dt", "e")):
                    expected = float(np.median([float(r[label]) for r in rows]))
                    assert float(m[f"{group}{which}"]) == expected, (title, label, at)
            values = sorted({float(r[column]) for r in table})
            assert (float(m["low"]), float(m["high"])) == (values[0], values[-1])

        rest = _checked(_answer(section), r"(?P<p>\w+) from (?P<low>\S+) to (?P<high>\S+): settling "
                        r"(?P<s0>\S+) -> (?P<s1>\S+) s, peak abs\(v\) (?P<v0>\S+) -> (?P<v1>\S+), "
                        r"int v\^2 dt (?P<e0>\S+) -> (?P<e1>[^\s;]+)", check)
        _no_number_left(rest)


def test_each_number_of_the_finding_answers_is_its_own_cell() -> None:
    """Recovery, estimates, the NN term, the NN term's grid and eq. (84): every number of an answer
    line is the cell of its own row (scenario, law) and column, and the line has no other number."""
    sections = _sections()
    tables = {title: _tables(section) for title, section in sections.items()}

    def cells(row: dict[str, str], m: re.Match, pairs: dict[str, str]) -> None:
        for group, column in pairs.items():
            assert m[group] == row[column], (group, column, m[group], row[column])

    recovery = tables["Recovery after the fault"][0]
    rest = _checked(_answer(sections["Recovery after the fault"]),
                    r"(?P<s>\w+) (?P<law>f\w+-time): (?P<back>\d+) of (?P<runs>\d+) runs back in band "
                    r"\(median "
                    r"(?P<med>\S+) s, max (?P<max>\S+) s\), (?P<never>\d+) never",
                    lambda m: cells(_row(recovery, scenario=m["s"], law=m["law"]), m,
                                    {"back": "back in band", "runs": "runs", "med": "median recovery (s)",
                                     "max": "max recovery (s)", "never": "never back"}))
    _no_number_left(rest)

    estimates = tables["The adaptive estimates eta_hat"][0]
    rest = _checked(_answer(sections["The adaptive estimates eta_hat"]),
                    r"(?P<s>\w+) (?P<law>f\w+-time) \((?P<ok>\d+) runs ok\): eta_hat_1 <= (?P<e1>\S+), "
                    r"eta_hat_2 <= (?P<e2>\S+), change over the last second <= (?P<c1>\S+) and "
                    r"(?P<c2>[0-9][0-9.e+-]*[0-9])",
                    lambda m: cells(_row(estimates, scenario=m["s"], law=m["law"]), m,
                                    {"ok": "ok", "e1": "max eta_hat_1", "e2": "max eta_hat_2",
                                     "c1": "max abs change eta_hat_1", "c2": "max abs change eta_hat_2"}))
    _no_number_left(rest)

    paired = tables["The NN term's contribution"][1]
    rest = _checked(_answer(sections["The NN term's contribution"]),
                    r"(?P<s>\w+): of (?P<n>\d+) initial states (?P<both>\d+) settle with and without the "
                    r"term, "
                    r"(?P<on>\d+) only with it, (?P<off>\d+) only without; settling changes by "
                    r"(?P<max>\S+) s at "
                    r"most \(median (?P<med>\S+) s\), int v\^2 dt by a median factor (?P<e>\S+), the MAE "
                    r"by a "
                    r"median factor (?P<m>\S+) \(at most (?P<mm>[^)]+)\)",
                    lambda m: cells(_row(paired, scenario=m["s"]), m,
                                    {"n": "initial states", "both": "settle with both", "on": "only with "
                                                                                              "the term",
                                     "off": "only without", "max": "max abs settling change (s)",
                                     "med": "median settling change (s)", "e": "median ratio int v^2 dt",
                                     "m": "median ratio MAE", "mm": "max ratio MAE"}))
    _no_number_left(rest)

    grid = tables["The NN term over (a, kappa, q)"][0]
    columns = {"points": "points", "helps": "term helps", "none": "no effect", "hurts": "term hurts",
               "de": "destabilised by the term", "st": "stabilised by the term", "fail": "neither settles"}

    def totals(m: re.Match) -> None:
        for group, column in columns.items():
            assert int(m[group]) == sum(int(r[column]) for r in grid), column
        design = read_design(REPO / "ssp" / "campaigns" / "nn_grid.toml")
        for name, column in (("a", "controller.a1"), ("kappa", "controller.kappa1"), ("q", "controller.q1")):
            values = sorted({float(v[column]) for v in design.variants()})
            assert [float(v) for v in m[name].split(", ")] == values

    rest = _checked(_answer(sections["The NN term over (a, kappa, q)"]),
                    r"a in \{(?P<a>[^}]*)\}, kappa in \{(?P<kappa>[^}]*)\}, q in \{(?P<q>[^}]*)\}.*?, 3 "
                    r"s, no fault; "
                    r"of (?P<points>\d+) \(scenario, law, a, kappa, q\) points the term cuts the MAE by "
                    r"more than "
                    r"5% at (?P<helps>\d+), has no effect at (?P<none>\d+), raises it at (?P<hurts>\d+), "
                    r"destabilises the sampled loop at (?P<de>\d+) \(only the run without it settles\), "
                    r"stabilises it at "
                    r"(?P<st>\d+), and neither run settles at (?P<fail>\d+)", totals)
    _no_number_left(rest)

    eq84 = tables["Eq. (84), the bound on the tracking error"][0]
    names = {"example1_smooth": "Example 1", "pendulum_smooth": "Example 2, the pendulum"}
    rest = _checked(_answer(sections["Eq. (84), the bound on the tracking error"]),
                    r"(?P<s>\w+): the bound is at least (?P<any>\S+) for any Phi \((?P<half>\S+) at the "
                    r"study's "
                    r"Phi\), the runs end within (?P<final>[^\s;]+?)(?=;|\.$)",
                    lambda m: cells(_row(eq84, example=names[m["s"]]), m,
                                    {"any": "bound at least, any Phi", "half": "bound at least, Phi = 0.5",
                                     "final": "largest final abs(y - yd), settled runs"}))
    _no_number_left(rest)


def _fault_row(scenario: str, mode: int, recovery: float, band: float, peak: float) -> dict:
    return {"scenario": scenario, "controller.mode": mode, "status": "ok", "recovery_time": recovery,
            "recovery_band": band, "max_error_after_fault": peak}


def test_recovery_counts_never_apart_from_failed_runs() -> None:
    rows = [_fault_row("example1", 0, t, 1e-3, 2e-3) for t in (1.0, 3.0, 2.0, math.inf)]
    rows.append({"scenario": "example1", "controller.mode": 0, "status": "failed", "recovery_time": None,
                 "recovery_band": None, "max_error_after_fault": None})
    tables, line = findings.recovery(rows)
    # 5 runs, 4 ok, 3 back (median 2, max 3), 1 never (inf is not a failure), band 0.001, peak / band 2
    # explicit runs (no cap columns): the cap cell is "-"
    assert tables[0].splitlines()[2] == "| example1 | fixed-time | 5 | 4 | 3 | 1 | 2 | 3 | 0.001 | 2 | - |"
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


def test_nn_grid_classifies_each_point_by_the_pair_of_runs() -> None:
    """Five (a, kappa, q) points of one scenario and law: the term cuts the MAE by 50 % (helps), by
    2 % (no effect), raises it by 10 % (hurts), only the run without the term settles (destabilised),
    neither settles; with the term on the cap bound in a quarter and a half of the samples (steps 1, 2)."""
    def row(a: float, nn: int, status: str, mae: float) -> dict:
        return {"scenario": "example1_smooth", "controller.mode": 0, "controller.a1": a,
                "controller.kappa1": 2.0, "controller.q1": 8.0, "controller.nn_term": nn, "status": status,
                "mae": mae,
                "settling_time": 0.1 * mae, "cap1_active": 0.25, "cap2_active": 0.5, "cap3_active": None,
                "cap4_active": None}

    rows = [row(0.2, 1, "ok", 0.01), row(0.2, 0, "ok", 0.02), row(0.5, 1, "ok", 0.0098),
            row(0.5, 0, "ok", 0.01), row(1.0, 1, "ok", 0.011), row(1.0, 0, "ok", 0.01),
            row(2.0, 1, "failed", math.nan), row(2.0, 0, "ok", 0.01), row(5.0, 1, "failed", math.nan),
            row(5.0, 0, "failed", math.nan)]
    tables, line = findings.nn_grid(rows)
    assert tables[0].splitlines()[2] == ("| example1_smooth | semi-implicit | fixed-time | 5 | 1 | 1 | 1 "
                                         "| 1 | 0 | 1 "
                                         "| 0.5 at (0.2, 2, 8) | 0.002 -> 0.001 | 0.25 / 0.5 |")
    assert line.startswith("Scope: a in {0.2, 0.5, 1, 2, 5}, kappa in {2}, q in {8} (the same for both steps")
    assert line.endswith("of 5 (scenario, law, a, kappa, q) points the term cuts the MAE by more than 5% "
                         "at 1, has "
                         "no effect at 1, raises it at 1, destabilises the sampled loop at 1 (only the "
                         "run without it settles), stabilises it at 0, and neither run settles at 1.")


def test_eq84_lower_bound_written_out() -> None:
    """Eq. (77), (79), (84) for Example 1 (a = 5, 2; alpha = 1.5, beta = 0.75; c = a_bar = 1 as the
    study's T_m has it): x_0 >= 12.5 + 2 - 0.5 / sqrt(1.5) + 0.25 * 0.75^0.25 = 14.3244 from the design
    constants, plus b_m beta_bar^2 / 2 with beta_bar = max(m_r b_r, m_l b_l) = max(1 x 0.5, 1.2 x 0.6)
    = 0.72 (eq. 7) and b_m = 1: 0.2592; the pendulum adds d_1*^2 / 2 + d_2*^2 / 2 = (0.04 + 0.09) / 2
    = 0.065 from the disturbances 0.2 sin t, 0.3 cos t of eq. (99). Then abs(y - yd) <=
    2 (x_0 / (0.5 c))^(1/3) at Phi = 0.5, 2 x_0^(1/3) for any Phi."""
    design = 12.5 + 2.0 - 0.5 / math.sqrt(1.5) + 0.25 * 0.75**0.25
    assert findings.eq84_known_part(findings.EXAMPLE1.controller) == design
    assert findings.eq84_terms(findings.EXAMPLE1) == pytest.approx((design, 0.2592, 0.0), rel=1e-15)
    assert findings.eq84_terms(findings.EXAMPLE2) == pytest.approx((design, 0.2592, 0.065), rel=1e-15)
    lines = findings.eq84([])[0][0].splitlines()
    for line, disturbance in ((lines[2], 0.0), (lines[3], 0.065)):
        known = design + 0.2592 + disturbance
        assert line.endswith(f"| {known:.4g} | 1 | 1 | {2 * (known / 0.5) ** (1 / 3):.3g} | "
                             f"{2 * known ** (1 / 3):.3g} | - |")
    page = PAGE.read_text(encoding="utf-8")
    assert "| Example 1 | 14.32 | 0.2592 | 0 | 14.58 | 1 | 1 | 6.16 | 4.89 |" in page
    assert "| Example 2, the pendulum | 14.32 | 0.2592 | 0.065 | 14.65 | 1 | 1 | 6.17 | 4.89 |" in page


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
