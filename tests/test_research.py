# SPDX-License-Identifier: BSD-2-Clause
"""Issue 37, item 3: the research-question page is generated from the campaigns' tables.

Oracles: hand-computed medians of a small table, and the committed generated page itself (every
number of an answer line is in its own table: text and data agree)."""

from __future__ import annotations

import re
from pathlib import Path

from orchestrator.experiments.research import QUESTIONS, answer, run_table

PAGE = Path(__file__).resolve().parent.parent / "docs" / "research" / "index.md"


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
    for section in text.split("\n## ")[1:]:
        answer_line = next(line for line in section.splitlines() if line.startswith("**Answer.**"))
        table = "\n".join(line for line in section.splitlines() if line.startswith("| "))
        cells = {float(c) for c in re.findall(r"(?<=\| )-?\d+(?:\.\d+)?(?:e[+-]?\d+)?(?= \|)", table)}
        numbers = [float(n) for n in re.findall(r"(?<![\w.^])\d+(?:\.\d+)?(?:e[+-]?\d+)?", answer_line)]
        # every value an answer gives is a median over three runs of the table: one of its cells
        # (medians of three are cells), the gains too
        assert all(n in cells for n in numbers), (section.splitlines()[0], sorted(set(numbers) - cells))
