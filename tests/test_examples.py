# SPDX-License-Identifier: BSD-2-Clause
"""Every example in examples/ runs as a user would run it, and shows what it promises.

The oracles are independent of the code under test: the controller's tracking promise on a plant
that is not the paper's, the closed form of forward Euler for the Reference FMUs' Dahlquist, the
campaign's own design (every run in the table), and the notebook executed by a real Jupyter
kernel (nbclient), every cell without an error.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"
REFERENCE_FMUS = REPO.parent / "shared" / "tools" / "reference-fmus" / "2.0"

pytestmark = pytest.mark.system


@pytest.fixture
def workspace(built: Path, tmp_path: Path) -> Path:
    """A user's folder: the examples beside a ``build/`` (the session's build) and nothing else."""
    (tmp_path / "build").symlink_to(built, target_is_directory=True)
    shutil.copytree(EXAMPLES, tmp_path / "examples")
    return tmp_path


def _example(*args: str, cwd: Path) -> str:
    proc = subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    return proc.stdout


def test_own_plant_tracks_the_reference(workspace: Path) -> None:
    out = _example("examples/own_plant_fmpy.py", "build/fmus/FixedTimeController.fmu", cwd=workspace)
    error = float(re.search(r"max \|y - yd\| after 1 s = (\S+),", out).group(1))
    assert error < 0.05, out  # tracks sin(t) on a mass-spring-damper it was not designed for


@pytest.mark.skipif(not (REFERENCE_FMUS / "Dahlquist.fmu").is_file(),
                    reason=f"no Reference FMUs in {REFERENCE_FMUS}")
def test_own_ssp_from_the_reference_fmus(workspace: Path) -> None:
    out = _example("examples/reference_fmus/run.py", str(REFERENCE_FMUS), "out", cwd=workspace)
    assert "41 rows" in out, out  # the script's own exit status checks the closed form to 1e-12


def test_campaign_example(workspace: Path) -> None:
    design = EXAMPLES / "campaign" / "gains.toml"
    command = next(line for line in design.read_text().splitlines() if "orchestrate sweep" in line)
    args = command.split("orchestrate", 1)[1].split()  # the command the design's comment gives, verbatim
    proc = subprocess.run([sys.executable, "-m", "orchestrator", *args, "--quiet"], cwd=workspace,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    import pyarrow.parquet as pq

    out = workspace / "results" / "examples" / "gains"
    table = pq.read_table(out / "runs.parquet").to_pydict()
    assert sorted(zip(table["controller.k1"], table["actuator.K_inf"], strict=True)) == [
        (k, kinf) for k in (5.0, 10.0, 20.0) for kinf in (0.2, 0.8)]
    assert set(table["status"]) == {"ok"}
    assert (out / "report" / "summary.md").is_file()


def test_notebook_runs(workspace: Path) -> None:
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.read(workspace / "examples" / "python_api.ipynb", as_version=4)
    NotebookClient(notebook, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(workspace / "examples")}}).execute()
    outputs = "".join(o.get("text", "") for c in notebook.cells if c.cell_type == "code" for o in c.outputs)
    assert "max |y - yd| after 0.5 s" in outputs
    first = float(re.search(r"part at t = (\S+) s", outputs).group(1))
    assert first == pytest.approx(0.5, abs=1e-9)  # the earlier fault shows from t_fault on, not before
