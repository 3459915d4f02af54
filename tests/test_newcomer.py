# SPDX-License-Identifier: BSD-2-Clause
"""A newcomer's frictions (issue 22): each test failed before its fix.

Oracles: the commands' own exit status and output, the files a fake ``orchestrate build`` leaves,
the SSD written here (no step annotation), the controller FMU's documented warning.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from fmpy.util import read_csv
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, ScenarioError, ScenarioWarning
from orchestrator.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_python_m_orchestrator_is_the_orchestrate_command():
    """Before: 'No module named orchestrator.__main__'."""
    r = subprocess.run([sys.executable, "-m", "orchestrator", "--version"], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("orchestrate ")


def test_the_readme_says_how_to_reach_orchestrate_from_a_new_shell():
    readme = (ROOT / "README.md").read_text()
    assert "source .venv/bin/activate" in readme and "python -m orchestrator" in readme


@pytest.mark.system
def test_an_ssd_without_a_step_annotation_is_not_run_at_1_ms_in_silence(test_fmus, tmp_path, capsys):
    """Before: it ran at the default 1 ms without a word."""
    folder = loop_scenario(tmp_path / "loop", test_fmus, stop=0.01, step=None, pack=False)
    assert "step" not in (folder / "SystemStructure.ssd").read_text().lower()
    with pytest.warns(ScenarioWarning,
                      match=r"no communication step: the SSD has no step annotation \(libcosim"):
        result = orchestrator.run(folder)
    assert result.provenance["step"] == 0.001 and result.count == 11
    with pytest.raises(ScenarioError, match="no communication step"):
        orchestrator.run(folder, RunOptions(strict=True))
    assert len(orchestrator.run(folder, RunOptions(step=0.005)).rows) == 3  # a step given: no warning
    assert main(["validate", str(folder)]) == 0
    assert "warning: " in capsys.readouterr().out


@pytest.mark.system
def test_fmu_warnings_are_shown_without_verbose(built, tmp_path, capsys):
    """Before: the controller's sample-time warning needed --verbose."""
    argv = ["run", str(built / "ssp" / "pendulum.ssp"), "--stop-time", "0.01", "--no-plot",
            "--set", "controller.discretization=1", "--output", str(tmp_path / "p.csv")]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "orchestrate: warning: controller (FixedTimeController): communication step 0.0005 s" in err
    assert err.count("differs from sample_time") == 1
    assert main([*argv, "--quiet"]) == 0  # issue 36: --quiet means quiet, FMU warnings too
    assert "warning" not in capsys.readouterr().err


@pytest.mark.system
def test_a_scenario_folder_finds_its_projects_fmus_from_any_directory(test_fmus, tmp_path, monkeypatch):
    """Before: ssp/NAME looked for build/fmus/ in the working directory only ('no FMU')."""
    project = tmp_path / "project"
    source = loop_scenario(project / "ssp" / "loop", test_fmus, stop=0.05, pack=False)
    (project / "build" / "fmus").mkdir(parents=True)
    for fmu in (source / "resources").glob("*.fmu"):  # as 'orchestrate build' lays them out
        fmu.rename(project / "build" / "fmus" / fmu.name)
    (source / "resources").rmdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["run", str(source), "--quiet", "--no-plot", "--output", "r.csv"]) == 0
    assert len(read_csv("r.csv")) == 6


@pytest.mark.system
def test_crosscheck_says_what_an_archive_misses(test_fmus, tmp_path):
    """Before: 'needs a DefaultExperiment stopTime and a step annotation' whichever was missing."""
    from orchestrator.crosscheck.tools import Scenario

    archive = loop_scenario(tmp_path / "loop", test_fmus, stop=0.01, step=None)
    expected = (r"other tools need a step annotation \(libcosim's osp:FixedStepAlgorithm baseStepSize in "
                r"the DefaultExperiment, or OMSimulator's oms:FixedStepMaster stepSize in the System\); "
                "it has none$")
    with pytest.raises(ValueError, match=expected):
        Scenario.read(archive)


@pytest.mark.system
def test_inspect_into_a_reader_that_left_ends_without_a_traceback(built):
    """Before: 'orchestrate inspect pendulum | head' could end with a BrokenPipeError traceback.
    'true' leaves before orchestrate writes, so every write meets a closed pipe."""
    command = (f"{Path(sys.executable).with_name('orchestrate')} inspect {built / 'ssp' / 'pendulum.ssp'} "
               "| true")
    r = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stderr == "", r.stderr
