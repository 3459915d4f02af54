# SPDX-License-Identifier: BSD-2-Clause
"""Smoke test of the report: short horizons into tmp_path, every file written, four metric rows."""

from __future__ import annotations

import subprocess
from importlib.metadata import version
from pathlib import Path

import pytest

from orchestrator.cli import main
from orchestrator.experiments.report import CASES, FIGURES

pytestmark = pytest.mark.system


def test_report_on_a_short_horizon(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "report"
    assert main(["report", "--out", str(out), "--stop-time", "0.5", "--study-horizon", "0.5",
                 "--study-values", "0", "2"]) == 0
    report = out / "report.md"
    assert capsys.readouterr().out.strip() == str(report)
    text = report.read_text()
    head = subprocess.run(["git", "-C", str(Path(__file__).parent), "rev-parse", "HEAD"], capture_output=True,
                          text=True).stdout.strip()
    assert f"; commit `{head[:12]}`" in text and f"fmpy {version('fmpy')}" in text  # issue 12: provenance
    for example in (1, 2):
        for key, *_ in FIGURES:
            figure = out / f"example{example}_{key}.png"
            assert figure.stat().st_size > 5000, figure
            assert f"]({figure.name})" in text
    section = text.split("## Metrics beside the paper's Tables 1-2")[1].split("\n\n")[1]
    rows = [line for line in section.splitlines() if line.startswith("| ") and "---" not in line][1:]
    assert [tuple(r.split(" | ")[:2]) for r in rows] == [(f"| {e}", m) for e, m in CASES]
    assert "| 0.1375 | 0.0027 | 0.0517 | 0.0209 |" in rows[0]
    study = text.split("## The fixed-time claim, measured")[1]
    assert study.count("\n| ") == 1 + 4  # header and the 2 x 2 initial states
    assert "horizon 0.5 s" in study


@pytest.mark.parametrize("values", [(-1.0, 1.0), (2.0,)])
def test_study_section_on_a_grid_without_nearer_states(values: tuple[float, ...]) -> None:
    """Every state of the grid {-1, 1}^2 (or {2}^2) is equally far from the origin: there is nothing
    to compare the farthest states with, and the section says so instead of failing (it raised
    ValueError on an empty selection)."""
    from orchestrator.experiments.report import SettlingRow, _study_section

    rows = [SettlingRow(a, b, 0.05, 0.3) for a in values for b in values]
    text = "\n".join(_study_section(rows, values, 1.0))
    assert f"max(|x1(0)|, |x2(0)|) = {max(abs(v) for v in values):g}" in text
    assert "cannot be judged" in text and "Verdict" not in text
