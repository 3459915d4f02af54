# SPDX-License-Identifier: BSD-2-Clause
"""A scenario of a user's own, with no file of the paper: two Modelica Reference FMUs (VanDerPol
into Feedthrough through a linear transformation), and the loop of tests/orch_helpers.py.

Oracles: the FMUs' own modelDescription.xml read here with the standard library (names, start
values), the values the test writes into the SSV and ``--set``, the transformation
y = 2 x0 + 0.5 applied to VanDerPol's output (Feedthrough copies its input), and the SSD written here.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, ScenarioWarning
from orchestrator.cli import main
from orchestrator.inspection import inspect_scenario
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

pytestmark = pytest.mark.system

REFERENCE_FMUS = Path(__file__).resolve().parents[2] / "shared" / "tools" / "reference-fmus" / "2.0"
needs_reference_fmus = pytest.mark.skipif(not (REFERENCE_FMUS / "VanDerPol.fmu").is_file(),
                                          reason=f"no Modelica Reference FMUs in {REFERENCE_FMUS}")


def own_scenario(folder: Path, step: float | None = 0.01) -> Path:
    outputs = [("x0", "output", "Real"), ("x1", "output", "Real")]
    comps = (component("vdp", "VanDerPol.fmu", outputs, {"mu": 1.5}),
             component("through", "Feedthrough.fmu", [("Float64_continuous_input", "input", "Real"),
                                                     ("Float64_continuous_output", "output", "Real")]))
    conns = (Connection.between("vdp.x0", "through.Float64_continuous_input", 2.0, 0.5),)
    write_ssd(folder, SystemStructure("vdp", comps, conns, Experiment(0.0, 2.0, step)))
    return pack_ssp(folder, {n: REFERENCE_FMUS / n for n in ("VanDerPol.fmu", "Feedthrough.fmu")},
                    folder.parent / f"{folder.name}.ssp")


def _starts(fmu: Path) -> dict[str, str | None]:
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    return {v.get("name"): next((c.get("start") for c in v), None) for v in root.iter("ScalarVariable")}


@needs_reference_fmus
def test_inspect_lists_variables_values_origins_and_connections(tmp_path, capsys):
    archive = own_scenario(tmp_path / "vdp")
    report = inspect_scenario(archive, overrides={"through.Float64_tunable_parameter": 3.0})
    assert report.problems == [] and report.name == "vdp"
    assert [row[:2] for row in report.timing] == [("start", "0 s"), ("stop", "2 s"), ("step", "0.01 s"),
                                                  ("master", "gauss-seidel")]  # written for both tools
    (vdp, about, variables), (through, _, through_vars) = report.components
    assert vdp == "vdp" and through == "through"
    assert "FMI 2.0" in about and "FMU VanDerPol.fmu" in about
    starts = _starts(REFERENCE_FMUS / "VanDerPol.fmu")
    by_name = {v.name: v for v in variables}
    assert set(by_name) == {n for n in starts if n in ("x0", "x1", "mu")}
    assert by_name["mu"].start == starts["mu"] and by_name["mu"].value == 1.5
    assert by_name["mu"].origin == "SSD (vdp.ssv)" and by_name["x0"].connection == \
        "-> through.Float64_continuous_input"
    by_name = {v.name: v for v in through_vars}
    tunable = by_name["Float64_tunable_parameter"]
    assert tunable.value == 3.0 and tunable.origin == "--set"
    assert by_name["Float64_fixed_parameter"].origin == "FMU"
    assert by_name["Float64_continuous_input"].connection == "<- vdp.x0 (x 2 + 0.5)"
    assert report.connections == ["vdp.x0 -> through.Float64_continuous_input (x 2 + 0.5)"]
    assert main(["inspect", str(archive), "--set", "vdp.mu=2"]) == 0
    out = capsys.readouterr().out
    assert "component vdp: FMU VanDerPol.fmu, FMI 2.0" in out
    mu = [line.split() for line in out.splitlines() if line.split()[:2] == ["mu", "parameter"]]
    assert mu == [["mu", "parameter", "Real", "-", "1", "2.0", "--set"]]
    assert main(["inspect", str(archive), "--set", "vdp.nothere=2"]) == 1
    assert "problems (1):" in capsys.readouterr().out


@needs_reference_fmus
def test_a_users_scenario_runs_plots_and_applies_the_transformation(tmp_path):
    archive = own_scenario(tmp_path / "vdp")
    with pytest.warns(ScenarioWarning, match=r"inputs are not connected .* Int32_input \(0\)"):
        result = orchestrator.run(archive, RunOptions(output=tmp_path / "vdp.csv"))
    rows = result.rows
    np.testing.assert_array_equal(rows["through.Float64_continuous_output"], 2.0 * rows["vdp.x0"] + 0.5)
    assert result.provenance["start_values"]["vdp.mu"] == 1.5
    assert main(["run", str(archive), "--quiet", "--output", str(tmp_path / "r.csv")]) == 0
    assert (tmp_path / "r.png").stat().st_size > 5000


def test_inspect_of_a_scenario_with_a_parameter_set_names_the_file(test_fmus, tmp_path):
    from orchestrator.ssp import ParameterSet, write_ssv

    loop = loop_scenario(tmp_path / "loop", test_fmus, gain=-2.0)
    ssv = write_ssv(tmp_path / "mine.ssv", ParameterSet.of("mine.ssv", {"integrator.x0": 4.0}))
    report = inspect_scenario(loop, parameter_sets=[ssv])
    variables = {v.name: v for _, _, vs in report.components for v in vs}
    assert variables["x0"].value == 4.0 and variables["x0"].origin == "--parameter-set mine.ssv"
    assert variables["k"].value == -2.0 and variables["k"].origin == "SSD (gain.ssv)"


@needs_reference_fmus
def test_a_users_scenario_gets_metrics_and_compare_without_the_papers_names(tmp_path, capsys):
    """Done-when of issue 22: plot, inspect (above), metrics on the signals it names and compare,
    no file of the paper involved. Oracle for the metrics: SPEC section 4's RAE and MAE computed
    here from the CSV's columns (e = through - x0 = x0 + 0.5, as through = 2 x0 + 0.5)."""
    archive = own_scenario(tmp_path / "vdp")
    full, coarse = tmp_path / "full.csv", tmp_path / "coarse.csv"
    for out, extra in ((full, []), (coarse, ["--output-interval", "0.1"])):
        assert main(["run", str(archive), "--quiet", "--no-plot", "--output", str(out), *extra]) == 0
    capsys.readouterr()
    assert main(["metrics", str(full), "--signal", "through.Float64_continuous_output",
                 "--reference", "vdp.x0"]) == 0
    row = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| full |")][0]
    data = read_csv(full)
    y, e = data["through.Float64_continuous_output"], data["vdp.x0"] + 0.5
    rae, mae = np.sqrt(np.sum(e**2) / np.sum(y**2)), np.mean(np.abs(e))
    cells = [float(cell) for cell in row.split("|")[2:6]]
    assert cells[0] == pytest.approx(rae, rel=1e-3) and cells[3] == pytest.approx(mae, rel=1e-3)
    assert main(["compare", str(coarse), str(full)]) == 0  # decimated against its full-rate self
    assert "PASS: 4 of 4 signals inside their tubes at the 21 times both have" in capsys.readouterr().out
    assert main(["compare", str(full), str(full), "--tol", "vdp.x0=1e-12"]) == 0
