"""Tool neutrality (issue 8): every built scenario runs unchanged (same archive, its own step, stop
time and parameter sets) in both of our masters and in every installed SSP tool -- libcosim, Ecos
(ecospy and its ``ecos`` program), OMSimulator (program and Python package) -- through the matrix
code of ``orchestrate crosscheck``, and no cell of the matrix is red.

The independent oracle of each tool is our master of the same semantics (``jacobi`` for the delayed
tools, ``gauss-seidel`` for the delay-free ones), and the parameter values of the archive's
``.ssv`` files, read back from each tool. Every (tool, scenario) runs once per session (xdist: in
one worker); ``CROSSCHECK_OUTPUT=DIR`` also writes the matrix there (``make test`` uses
results/crosscheck/).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from orchestrator.crosscheck import TOOLS, Scenario, select_tools
from orchestrator.crosscheck.matrix import Cell, run_matrix, write_csv, write_markdown

pytestmark = [pytest.mark.system, pytest.mark.xdist_group("crosscheck")]

REPO = Path(__file__).resolve().parent.parent
SCENARIOS = sorted(p.parent.name for p in (REPO / "ssp").glob("*/SystemStructure.ssd"))
TOOL_KEYS = ["orchestrate-gauss-seidel", "orchestrate-jacobi", *TOOLS]


@pytest.fixture(scope="session")
def matrix(built: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], Cell]:
    """The whole matrix, each run once; written to $CROSSCHECK_OUTPUT (if set) or a temporary folder."""
    scenarios = [Scenario.read(built / "ssp" / f"{name}.ssp") for name in SCENARIOS]
    tools = select_tools()
    cells = run_matrix(scenarios, tools)
    out = Path(os.environ.get("CROSSCHECK_OUTPUT") or tmp_path_factory.mktemp("crosscheck"))
    write_markdown(cells, out / "matrix.md", tools)
    write_csv(cells, out / "matrix.csv")
    return {(c.tool, c.scenario): c for c in cells}


@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("tool", TOOL_KEYS)
def test_scenario_runs_unchanged_in_every_tool(matrix: dict[tuple[str, str], Cell], tool: str,
                                               scenario: str) -> None:
    cell = matrix[(tool, scenario)]
    if cell.missing:
        pytest.skip(f"{tool}: {cell.missing}")
    failures = [f"{c.name}: {c.detail}" for c in cell.checks if not c.ok]
    assert not failures, f"{scenario} in {cell.title}: " + "; ".join(failures)


def test_every_tool_is_checked_on_every_scenario(matrix: dict[tuple[str, str], Cell]) -> None:
    """The matrix is complete and each cell that ran has all five checks."""
    assert set(matrix) == {(t, s) for t in TOOL_KEYS for s in SCENARIOS}
    for cell in matrix.values():
        if not cell.missing and cell.checks[0].ok:
            assert len(cell.checks) == 5, (cell.tool, cell.scenario, cell.checks)
