# SPDX-License-Identifier: BSD-2-Clause
"""SSP scenarios with FMI 3.0 components: the FMI 3.0 twin of every shipped scenario
(build/ssp/<name>_fmi3.ssp, the same SSD with the FMUs' FMI 3.0 variants), a mixed scenario, and
third-party FMI 3.0 FMUs (the Modelica Reference FMUs), each against an independent oracle: the FMI
2.0 run of the same scenario (bit for bit), the FMI 2.0 baselines, and fmusim on the FMU alone."""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest
from orch_helpers import BASELINE_DIR

import orchestrator
from orchestrator import RunOptions
from orchestrator.cli import main
from orchestrator.errors import ScenarioError, SimulationError
from orchestrator.experiments.scenarios import FMI3_SUFFIX, all_scenarios, component_sources
from orchestrator.regress import compare, format_comparison, load_tolerances
from orchestrator.results import read_result
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd
from orchestrator.validate import validate

pytestmark = pytest.mark.system

SCENARIOS = all_scenarios()
TOLERANCES = load_tolerances(BASELINE_DIR / "tolerances.json")
SHORT = 2.0
REPO = Path(__file__).resolve().parent.parent
REFERENCE_FMUS = REPO.parent / "shared" / "tools" / "reference-fmus"
FMUSIM = REPO.parent / "shared" / "tools" / "fmusim" / "bin" / "fmusim"


def run(scenario: Path, **options: object) -> np.ndarray:
    """The rows of ``orchestrate run`` on ``scenario`` (options as RunOptions takes them)."""
    return orchestrator.run(scenario, RunOptions(**options)).rows  # type: ignore[arg-type]


def assert_identical(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype.names == b.dtype.names and len(a) == len(b)
    for name in a.dtype.names or ():
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


@pytest.mark.parametrize("name", SCENARIOS)
def test_twin_equals_the_fmi2_scenario_and_its_baseline(built: Path, name: str) -> None:
    """The whole DefaultExperiment under the default master: the same rows, bit for bit, as the
    FMI 2.0 scenario, so the twin passes the FMI 2.0 baseline's regression tubes too."""
    twin = run(built / "ssp" / f"{name}{FMI3_SUFFIX}.ssp")
    assert_identical(twin, run(built / "ssp" / f"{name}.ssp"))
    comparison = compare(
        twin,
        read_result(BASELINE_DIR / f"{name}.csv"),
        TOLERANCES.for_scenario(name),
        f"{name}{FMI3_SUFFIX}",
        f"tests/baselines/{name}.csv",
    )
    assert comparison.passed and not comparison.missing, format_comparison(comparison)


@pytest.mark.parametrize("name", SCENARIOS)
def test_twin_equals_the_fmi2_scenario_under_jacobi(built: Path, name: str) -> None:
    twin = run(built / "ssp" / f"{name}{FMI3_SUFFIX}.ssp", master="jacobi", stop_time=SHORT)
    assert_identical(twin, run(built / "ssp" / f"{name}.ssp", master="jacobi", stop_time=SHORT))


def test_mixed_fmi2_and_fmi3_components(built: Path, tmp_path: Path) -> None:
    """example1 with the controller and the plant in FMI 3.0, the others in FMI 2.0."""
    fmus = {}
    for source in component_sources(REPO / "ssp" / "example1"):
        version = "fmus3" if source in ("FixedTimeController.fmu", "Example1Plant.fmu") else "fmus"
        fmus[source] = built / version / source
    mixed = pack_ssp(REPO / "ssp" / "example1", fmus, tmp_path / "mixed.ssp")
    for master in ("gauss-seidel", "jacobi"):
        assert_identical(
            run(mixed, master=master, stop_time=SHORT),
            run(built / "ssp" / "example1.ssp", master=master, stop_time=SHORT),
        )


def test_validate_checks_the_fmi3_model_descriptions(built: Path) -> None:
    """The same checks and counts as the FMI 2.0 scenario, and nothing to report."""
    two, three = (
        validate(built / "ssp" / "pendulum.ssp"),
        validate(built / "ssp" / f"pendulum{FMI3_SUFFIX}.ssp"),
    )
    assert three.ok and two.ok and [p for p in three.problems if "time" not in str(p)] == list(two.problems)
    assert (three.components, three.connections, three.parameters) == (
        two.components,
        two.connections,
        two.parameters,
    )


def test_units_parameters_and_provenance(built: Path, tmp_path: Path) -> None:
    """A value with a unit is converted with the FMI 3.0 FMU's unit; a value outside its max is
    refused before anything runs; the provenance names the FMI 3.0 FMUs and their tokens."""
    twin = built / "ssp" / f"example1{FMI3_SUFFIX}.ssp"
    out = tmp_path / "r.csv"
    assert (
        main(
            [
                "run",
                str(twin),
                "--stop-time",
                "0.05",
                "--set",
                "actuator.t_fault=20ms",
                "--quiet",
                "--output",
                str(out),
            ]
        )
        == 0
    )
    expected = run(built / "ssp" / "example1.ssp", stop_time=0.05, overrides={"actuator.t_fault": 0.02})
    assert_identical(read_result(out), expected)
    provenance = json.loads(out.with_name("r.csv.json").read_text())
    assert provenance["start_values"]["actuator.t_fault"] == 0.02
    token = fmpy.read_model_description(str(built / "fmus3" / "FixedTimeController.fmu")).guid
    assert provenance["fmus"]["controller"]["guid"] == token
    with pytest.raises(ScenarioError, match=r"controller\.beta = 1\.5 is above the FMU's max"):
        run(twin, stop_time=0.05, overrides={"controller.beta": 1.5})


def test_failure_names_the_fmi3_function_and_keeps_the_rows(built: Path) -> None:
    """The pendulum at 1 ms under the delayed master: the plant refuses the step at t = 0.031 s (as
    in FMI 2.0, README); the message names fmi3DoStep and fmi3Discard, the rows up to there equal
    the FMI 2.0 run's."""
    errors = {}
    for suffix in ("", FMI3_SUFFIX):
        with pytest.raises(SimulationError) as caught:
            run(built / "ssp" / f"pendulum{suffix}.ssp", master="jacobi", step=1e-3, stop_time=0.1)
        errors[suffix] = caught.value
    two, three = errors[""], errors[FMI3_SUFFIX]
    assert "plant: fmi2DoStep returned fmi2Discard" in str(two)
    assert "plant: fmi3DoStep returned fmi3Discard" in str(three)
    assert str(three).replace("fmi3", "fmi2") == str(two)
    assert_identical(three.result.rows, two.result.rows)


# -- third-party FMI 3.0 FMUs --------------------------------------------------------------------------
def reference_scenario(version: str, folder: Path, connectors: str = "Float64_continuous") -> Path:
    """Dahlquist (x' = -k x) feeding Feedthrough, from the Reference FMUs of ``version``."""
    folder.mkdir(parents=True)
    components = (
        component("dahlquist", "Dahlquist.fmu", [("x", "output", "Real")], {"k": 2.0}),
        component(
            "feedthrough",
            "Feedthrough.fmu",
            [(f"{connectors}_input", "input", "Real"), (f"{connectors}_output", "output", "Real")],
            {},
        ),
    )
    connections = (Connection.between("dahlquist.x", f"feedthrough.{connectors}_input"),)
    write_ssd(folder, SystemStructure("reference", components, connections, Experiment(0.0, 2.0, 0.1)))
    fmus = {f"{m}.fmu": REFERENCE_FMUS / version / f"{m}.fmu" for m in ("Dahlquist", "Feedthrough")}
    return pack_ssp(folder, fmus, folder.parent / f"{folder.name}.ssp")


needs_reference_fmus = pytest.mark.skipif(
    not (REFERENCE_FMUS / "3.0" / "Dahlquist.fmu").is_file(),
    reason=f"Reference FMUs not found in {REFERENCE_FMUS}",
)


@needs_reference_fmus
@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
@pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")  # Feedthrough's other inputs
def test_reference_fmus_same_trajectory_in_both_fmi_versions(tmp_path: Path) -> None:
    """orchestrate gives the same trajectory for the FMI 2.0 and 3.0 builds of the Reference FMUs,
    under both masters, and the same as fmusim running Dahlquist alone (FMI 3.0)."""
    results = {}
    for version in ("2.0", "3.0"):
        scenario = reference_scenario(version, tmp_path / f"v{version[0]}")
        for master in ("gauss-seidel", "jacobi"):
            results[version, master] = run(scenario, master=master)
    for master in ("gauss-seidel", "jacobi"):
        assert_identical(results["3.0", master], results["2.0", master])
    ours = results["3.0", "gauss-seidel"]
    out = tmp_path / "fmusim.csv"
    subprocess.run(
        [
            str(FMUSIM),
            "--interface-type",
            "cs",
            "--stop-time",
            "2",
            "--output-interval",
            "0.1",
            "--start-value",
            "k",
            "2",
            "--output-file",
            str(out),
            str(REFERENCE_FMUS / "3.0" / "Dahlquist.fmu"),
        ],
        check=True,
        capture_output=True,
        timeout=300,
    )
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    np.testing.assert_allclose(ours["time"], [float(r["time"]) for r in rows], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours["dahlquist.x"], [float(r["x"]) for r in rows], rtol=1e-12, atol=0)
    # Feedthrough passes its input on within the step under the delay-free master
    np.testing.assert_array_equal(ours["feedthrough.Float64_continuous_output"], ours["dahlquist.x"])
    assert abs(ours["dahlquist.x"][-1] - np.exp(-4.0)) < 0.05  # x(2) of x' = -2 x, forward Euler


@needs_reference_fmus
def test_unsupported_fmi3_type_refused_naming_the_connector(tmp_path: Path) -> None:
    """A Float32 connector of an FMI 3.0 FMU: one line naming component, connector and the type."""
    scenario = reference_scenario("3.0", tmp_path / "float32", connectors="Float32_continuous")
    with pytest.raises(ScenarioError) as caught:
        run(scenario)
    lines = [p for p in caught.value.problems if "Float32" in p]
    assert len(lines) == 2, caught.value.problems
    assert (
        "component 'feedthrough', connector 'Float32_continuous_input': the FMU's variable is Float32, "
        "an FMI 3.0 type orchestrate does not support yet" in lines[0]
    )
