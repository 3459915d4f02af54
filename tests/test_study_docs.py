# SPDX-License-Identifier: BSD-2-Clause
"""Issue 37, item 2: the study's and the campaigns' pages copy no number by hand.

The oracle is the generated table ``docs/fixed-time-study/study.md`` (``make study-fixed-time``
writes it from the runs): every number in the findings of ``docs/fixed-time-study/index.md`` is
one of its numbers (a count, a time, a peak, or a count of settled runs it implies), no other page
carries a copy of its table, and ``docs/campaigns.md`` states no count of diverging states. On
main the findings said 85 never-settled pendulum states beside a table's 86, the campaigns page
"333 of 441" and "109 states" where the study gives 298, 77 and 3."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"
STUDY = DOCS / "fixed-time-study" / "study.md"
INDEX = DOCS / "fixed-time-study" / "index.md"
NUMBER = re.compile(r"(?<![\w.^-])-?\d+(?:\.\d+)?(?:e[+-]?\d+)?(?![\w^])")


def _numbers(text: str) -> set[float]:
    return {float(n) for n in NUMBER.findall(text)}


def _study_numbers() -> set[float]:
    """Every number of the generated page, and what its rows imply: settled = runs - diverged -
    never, and the sums over a row's two examples."""
    text = STUDY.read_text(encoding="utf-8")
    numbers = _numbers(text)
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 10 and cells[3].isdigit():
            runs, diverged, never = int(cells[3]), int(cells[4]), int(cells[5])
            numbers |= {float(runs - diverged - never), float(diverged + never)}
    return numbers


def _findings(text: str) -> str:
    """The part of the study page that reports the study's results (up to the fail-fast section,
    which reports benchmarks of its own)."""
    start = text.index("The table, as the target writes it")
    return text[start:text.index("**Fail fast**")]


def test_every_number_of_the_findings_is_the_generated_tables() -> None:
    findings = re.sub(r"`[^`]*`|\([^()]*\.md[^()]*\)|eq\. \(\d+\)|\[-10, 10\]\^2", "", _findings(
        INDEX.read_text(encoding="utf-8")))
    missing = sorted(_numbers(findings) - _study_numbers())
    assert not missing, f"numbers of {INDEX.name}'s findings not in the generated {STUDY.name}: {missing}"


def test_only_the_generated_pages_carry_the_study_table() -> None:
    header = "| example | law | sampling | runs | diverged |"
    generated = {STUDY, DOCS / "fixed-time-study" / "manipulator.md"}
    copies = [p for p in DOCS.rglob("*.md") if p not in generated and header in p.read_text(encoding="utf-8")]
    assert not copies


def test_the_campaigns_page_copies_no_count() -> None:
    text = (DOCS / "campaigns.md").read_text(encoding="utf-8")
    assert not re.findall(r"\d+ (?:of \d+|states) (?:states )?(?:diverge|settle)", text)
    assert "333 of 441" not in text and "109 states" not in text


def test_every_figure_the_study_ships_is_in_the_docs() -> None:
    """Issue 37: the pendulum saturation figure, the only one with the never-settled states, was
    named in the study's code (DOC_FIGURES) but not in docs/: each is committed, linked from the
    generated table page, and the saturation ones from the study page."""
    from orchestrator.experiments.fixed_time_study import DOC_FIGURES

    study, index = STUDY.read_text(encoding="utf-8"), INDEX.read_text(encoding="utf-8")
    for name in DOC_FIGURES:
        assert (STUDY.parent / name).is_file(), name
        assert f"![{name}]({name})" in study, name
    assert all(f"]({name})" in index for name in DOC_FIGURES if "saturation" in name)
