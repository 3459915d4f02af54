# SPDX-License-Identifier: BSD-2-Clause
"""Issues 37 and 45: the study's page copies no number by hand, and each number is its own cell.

The oracle is the generated table ``docs/fixed-time-study/study.md`` (``make study-fixed-time`` writes
it from the runs). Every number in the findings of ``docs/fixed-time-study/index.md`` is claimed
below by the phrase that states it and the cell it states: its table, row (example, law, sampling)
and column (and which of a "median / max" pair). The claim must hold, and every number of the
findings must lie inside a claimed phrase, so no number is checked only against "somewhere in the
page" (issue 45: the semi-implicit "0.066" passed because the continuous row held that number;
the semi-implicit cell was 0.0655). No other page carries a copy of the table, and
``docs/campaigns.md`` states no count of diverging states."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent / "docs"
STUDY = DOCS / "fixed-time-study" / "study.md"
INDEX = DOCS / "fixed-time-study" / "index.md"
NUMBER = re.compile(r"(?<![\w.^-])-?\d+(?:\.\d+)?(?:e[+-]?\d+)?(?![\w^])")
# Text of the findings that holds digits but states no measured value: states and their notation,
# equation numbers, the grid's range, the finite-time law's k = 0, t = 0, names (Example 1, Remark 6),
# exponents, the limits' names (u_max = 1e4).
NOT_DATA = re.compile(r"`[^`]*`|\([^()]*\.md[^()]*\)|eq\. \(\d+\)|\[-10, 10\]\^2|x[12]\(0\)|Phi -> 1|"
                      r"k = 0|t = 0|Remark \d|Example \d|\^\(?[\d.]+\)?|u_max = 1e\d")
MAIN, SATURATION = 0, 1
HEADERS = {"runs": 3, "diverged": 4, "never": 5, "settling": 6, "peak": 7, "t_m": 8, "holds": 9, "cap": 10}

# (phrase of the findings, the cell it states): (table, example, law, sampling, column, part); part:
# the index in a "a / b" cell, or "settled" (runs - diverged - never) for the holds column.
Ref = tuple[int, str, str, str, str, int | str | None]
CLAIMS: list[tuple[str, Ref]] = [
    # the continuous law
    ("from every one of the 441 states", (MAIN, "1", "fixed-time", "continuous", "runs", None)),
    ("within 0.098 s (Example 1)", (MAIN, "1", "fixed-time", "continuous", "settling", 1)),
    ("and 0.066 s (pendulum)", (MAIN, "2", "fixed-time", "continuous", "settling", 1)),
    ("(Example 1: 0.052 s median)", (MAIN, "1", "fixed-time", "continuous", "settling", 0)),
    ("(0.921 s median", (MAIN, "1", "finite-time", "continuous", "settling", 0)),
    ("up to 1.57 s)", (MAIN, "1", "finite-time", "continuous", "settling", 1)),
    ("from 224 (Example 1)", (MAIN, "1", "finite-time", "continuous", "diverged", None)),
    ("and 102 (pendulum) of the states", (MAIN, "2", "finite-time", "continuous", "diverged", None)),
    ("85 more pendulum states", (MAIN, "2", "finite-time", "continuous", "never", None)),
    ("at the 2 s horizon", (-1, "", "", "", "horizon", None)),
    ("T_m = 12 s", (-1, "", "", "", "T_m (Phi = 0.5)", None)),
    ("(6 s as Phi -> 1", (-1, "", "", "", "T_m, Phi -> 1", None)),
    ("c = c_hat = 1", (-1, "", "", "", "c", None)),
    # explicit sampling
    ("breaks**: 298 (Example 1)", (MAIN, "1", "fixed-time", "explicit", "diverged", None)),
    ("and 336 (pendulum)", (MAIN, "2", "fixed-time", "explicit", "diverged", None)),
    ("of the 441 states diverge", (MAIN, "1", "fixed-time", "explicit", "runs", None)),
    ("(up to 1.07e7 for Example 1", (MAIN, "1", "fixed-time", "continuous", "peak", 1)),
    ("1.66e8 for the pendulum", (MAIN, "2", "fixed-time", "continuous", "peak", 1)),
    # semi-implicit sampling
    ("(0 diverge", (MAIN, "1", "fixed-time", "semi-implicit", "diverged", None)),
    ("settling within 0.097 s and", (MAIN, "1", "fixed-time", "semi-implicit", "settling", 1)),
    ("0.0655 s; medians", (MAIN, "2", "fixed-time", "semi-implicit", "settling", 1)),
    ("zeta_1 in 0.758", (MAIN, "1", "fixed-time", "semi-implicit", "cap", 0)),
    ("v in 0.869 of the", (MAIN, "1", "fixed-time", "semi-implicit", "cap", 1)),
    ("zeta_1 in 0.376", (MAIN, "2", "fixed-time", "semi-implicit", "cap", 0)),
    ("v in 0.775 on the pendulum", (MAIN, "2", "fixed-time", "semi-implicit", "cap", 1)),
    ("3.45e5 against", (MAIN, "1", "fixed-time", "semi-implicit", "peak", 1)),
    ("against 1.07e7 on Example 1", (MAIN, "1", "fixed-time", "continuous", "peak", 1)),
    ("5.15e6 against", (MAIN, "2", "fixed-time", "semi-implicit", "peak", 1)),
    ("against 1.66e8 on the pendulum", (MAIN, "2", "fixed-time", "continuous", "peak", 1)),
    ("zeta_1 in 0.19", (MAIN, "1", "finite-time", "semi-implicit", "cap", 0)),
    ("v in 0.163", (MAIN, "1", "finite-time", "semi-implicit", "cap", 1)),
    ("(pendulum: 0.0574", (MAIN, "2", "finite-time", "semi-implicit", "cap", 0)),
    ("and 0.0463)", (MAIN, "2", "finite-time", "semi-implicit", "cap", 1)),
    # finite escapes
    ("within the 2 s on both examples", (-1, "", "", "", "horizon", None)),
    ("86 states have not settled", (MAIN, "2", "finite-time", "explicit", "never", None)),
    ("settling time of 2 s means", (-1, "", "", "", "horizon", None)),
    # saturation
    ("unlimited: 298", (MAIN, "1", "fixed-time", "explicit", "diverged", None)),
    ("and 336 of the grid's", (MAIN, "2", "fixed-time", "explicit", "diverged", None)),
    ("grid's 441", (MAIN, "1", "fixed-time", "explicit", "runs", None)),
    ("grows only to 0.102 s (Example 1)",
     (SATURATION, "1", "fixed-time", "explicit, u_max = 10000", "settling", 1)),
    ("to 0.142 s (pendulum)", (SATURATION, "2", "fixed-time", "explicit, u_max = 10000", "settling", 1)),
    ("within 0.268 s", (SATURATION, "1", "fixed-time", "explicit, u_max = 1000", "settling", 1)),
    ("17 pendulum states escape",
     (SATURATION, "2", "fixed-time", "explicit, u_max = 1000", "diverged", None)),
    ("(55 and", (SATURATION, "1", "fixed-time", "explicit, u_max = 100", "diverged", None)),
    ("and 68 states escape", (SATURATION, "2", "fixed-time", "explicit, u_max = 100", "diverged", None)),
    ("settling up to 0.84 s", (SATURATION, "1", "fixed-time", "explicit, u_max = 100", "settling", 1)),
    ("(median 0.062 ->", (SATURATION, "1", "fixed-time", "explicit, u_max = 10000", "settling", 0)),
    ("-> 0.127 ->", (SATURATION, "1", "fixed-time", "explicit, u_max = 1000", "settling", 0)),
    ("-> 0.401 s on Example 1", (SATURATION, "1", "fixed-time", "explicit, u_max = 100", "settling", 0)),
    ("active in 0.00722,", (SATURATION, "1", "fixed-time", "explicit, u_max = 10000", "cap", "limit")),
    ("0.0402 and", (SATURATION, "1", "fixed-time", "explicit, u_max = 1000", "cap", "limit")),
    ("and 0.543 of the samples", (SATURATION, "1", "fixed-time", "explicit, u_max = 100", "cap", "limit")),
    ("(pendulum: 0.0221,", (SATURATION, "2", "fixed-time", "explicit, u_max = 10000", "cap", "limit")),
    (" 0.269,", (SATURATION, "2", "fixed-time", "explicit, u_max = 1000", "cap", "limit")),
    (" 0.837)", (SATURATION, "2", "fixed-time", "explicit, u_max = 100", "cap", "limit")),
]


def _tables() -> list[dict[tuple[str, str, str], list[str]]]:
    """The study table and the saturation table of study.md: (example, law, sampling) -> cells."""
    tables: list[dict[tuple[str, str, str], list[str]]] = []
    current: dict[tuple[str, str, str], list[str]] | None = None
    for line in STUDY.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| example | law | sampling |"):
            current = {}
            tables.append(current)
        elif current is not None and line.startswith("| ") and len(cells) == len(HEADERS) + 3:
            current[(cells[0], cells[1], cells[2])] = cells
        elif not line.startswith("|"):
            current = None
    return tables


def _bounds() -> dict[str, str]:
    """The T_m table of study.md: constant -> value (the unit dropped)."""
    text = STUDY.read_text(encoding="utf-8")
    rows = re.findall(r"^\| (T_m[^|]*|c|c_hat) \| ([^|]+) \|", text, re.MULTILINE)
    return {name.strip(): value.strip().removesuffix(" s") for name, value in rows}


def cell(ref: Ref) -> str:
    """The text of the cell a claim names."""
    table, example, law, sampling, column, part = ref
    if table == -1:  # the T_m table and the header's horizon
        return _bounds()[column] if column != "horizon" else re.search(
            r"Horizon (\S+) s", STUDY.read_text(encoding="utf-8"))[1]  # type: ignore[index]
    cells = _tables()[table][(example, law, sampling)]
    text = cells[HEADERS[column]]
    if part == "limit":
        return text.split(": ")[-1]
    if part == "settled":
        runs, diverged, never = (int(cells[HEADERS[c]]) for c in ("runs", "diverged", "never"))
        return str(runs - diverged - never)
    if isinstance(part, int):
        return text.split(" / ")[part].split(" (")[0]
    return text


def _findings(text: str) -> str:
    """The part of the study page that reports the study's results (up to the fail-fast section,
    which reports benchmarks of its own)."""
    start = text.index("The table, as the target writes it")
    return re.sub(r"\s+", " ", text[start:text.index("**Fail fast**")])


def test_each_claim_states_its_own_cell() -> None:
    findings = _findings(INDEX.read_text(encoding="utf-8"))
    wrong = []
    for phrase, ref in CLAIMS:
        assert phrase in findings, phrase
        numbers = NUMBER.findall(NOT_DATA.sub("", phrase))
        assert len(numbers) == 1, (phrase, numbers)
        if float(numbers[0]) != float(cell(ref)):
            wrong.append((phrase, ref, cell(ref)))
    assert not wrong


def test_every_number_of_the_findings_is_claimed() -> None:
    findings = _findings(INDEX.read_text(encoding="utf-8"))
    covered = [False] * len(findings)
    for phrase, _ in CLAIMS:
        for m in re.finditer(re.escape(phrase), findings):
            covered[m.start():m.end()] = [True] * (m.end() - m.start())
    masked = "".join(c if not covered[i] else " " for i, c in enumerate(findings))
    unclaimed = NUMBER.findall(NOT_DATA.sub("", masked))
    assert not unclaimed, f"numbers of {INDEX.name}'s findings that no claim checks: {unclaimed}"


def test_a_claim_checks_its_own_row_and_column() -> None:
    """Issue 45's example: the semi-implicit pendulum's largest settling time (0.0655 s) is not the
    continuous law's (0.066 s), and the claim of the one is not satisfied by the other's cell."""
    phrase, ref = next(c for c in CLAIMS if c[0] == "0.0655 s; medians")
    assert float(cell(ref)) == 0.0655
    other = (ref[0], ref[1], ref[2], "continuous", ref[4], ref[5])
    assert float(cell(other)) != float(NUMBER.findall(phrase)[0])


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
