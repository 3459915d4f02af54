# SPDX-License-Identifier: BSD-2-Clause
"""System tests of the regression: every scenario against its stored baseline (full 30 s), and one
perturbation at a time must be flagged with the stored tolerances while an unchanged rerun passes.

The perturbations run 1 s, inside the quiet phase (t <= quiet_until) where the tubes are tight and
every change shows; the fault-related ones move the fault to t = 0.5 s in both runs so that it acts
there. After the first chattering burst (~1.3 s) the tubes must be as wide as the amplified noise,
and changes as small as these are no longer visible to them (see tests/baselines/tolerances.json).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from orch_helpers import BASELINE_DIR

from orchestrator import RunOptions, run
from orchestrator.cli import main
from orchestrator.experiments.scenarios import all_scenarios
from orchestrator.regress.tubes import (
    BASELINE_GRID,
    compare,
    format_comparison,
    load_tolerances,
    output_columns,
    resample,
    write_baseline,
)
from orchestrator.results import read_result

pytestmark = pytest.mark.system

SCENARIOS = all_scenarios()
TOLERANCES = load_tolerances(BASELINE_DIR / "tolerances.json")
SHORT = 1.0
EARLY_FAULT = {"actuator.t_fault": 0.5}


@pytest.fixture(scope="module")
def archives(built: Path) -> dict[str, Path]:
    return {name: built / "ssp" / f"{name}.ssp" for name in SCENARIOS}


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_matches_its_baseline(archives: dict[str, Path], name: str) -> None:
    result = run(archives[name]).rows
    comparison = compare(result, read_result(BASELINE_DIR / f"{name}.csv"), TOLERANCES.for_scenario(name),
                         f"{name} (this run)", f"tests/baselines/{name}.csv")
    assert comparison.passed, format_comparison(comparison)
    assert len(comparison.checks) == len(output_columns(archives[name]))


# glibc's x86-64 libm picks FMA variants of sin, cos, exp, pow and tanh on CPUs that have FMA; these
# hide them, as a CPU without FMA would
NO_FMA = "glibc.cpu.hwcaps=-AVX2_Usable,-FMA_Usable,-FMA4_Usable,-AVX2,-FMA"


def test_a_cpu_without_fma_gives_the_same_bits(archives: dict[str, Path], tmp_path: Path) -> None:
    """A baseline recorded on one CPU, checked in CI on another: glibc's FMA and plain variants
    differ in the last bit for about 0.07 % of sin, cos, exp and pow results, and the chattering
    fixed-time law grew that to a difference of 2.2e-2 in example1 while the FMUs called the C
    library's math. With controller/fmath's functions in every FMU, example1 run with the plain
    variants gives the same bits as with FMA."""
    results = {}
    for label, extra in (("fma", {}), ("plain", {"GLIBC_TUNABLES": NO_FMA})):
        csv = tmp_path / f"{label}.csv"
        command = [sys.executable, "-m", "orchestrator", "run", str(archives["example1"]),
                   "--output", str(csv), "--no-plot", "--quiet"]
        subprocess.run(command, env={**os.environ, **extra}, check=True, timeout=600)
        results[label] = read_result(csv)
    columns = [c for c in results["fma"].dtype.names if c != "time"]
    differing = [c for c in columns if not np.array_equal(results["fma"][c], results["plain"][c])]
    assert not differing, f"example1 with glibc's plain variants differs from the FMA run in {differing}"


def short_baseline(archive: Path, **kwargs: object) -> np.ndarray:
    result = run(archive, RunOptions(stop_time=SHORT, **kwargs)).rows
    return resample(result, BASELINE_GRID, output_columns(archive))


@pytest.fixture(scope="module")
def reference_runs(archives: dict[str, Path]) -> dict[str, np.ndarray]:
    """The unperturbed 1 s runs the perturbations are compared with."""
    archive = archives["example1"]
    return {"plain": short_baseline(archive), "early fault": short_baseline(archive, overrides=EARLY_FAULT)}


PERTURBATIONS = {
    "controller gain k1 +5 %": ("plain", {"overrides": {"controller.k1": 10.5}}),
    "plant integrator max_step 2.5e-5 -> 1e-3": ("plain", {"overrides": {"plant.max_step": 1e-3}}),
    "jacobi master instead of gauss-seidel": ("plain", {"master": "jacobi"}),
    "dead-zone break point b_l +10 %": ("early fault", {"overrides": {**EARLY_FAULT, "actuator.b_l": 0.66}}),
    "fault time 0.5 s -> 0.55 s": ("early fault", {"overrides": {"actuator.t_fault": 0.55}}),
}


@pytest.mark.parametrize("label", PERTURBATIONS)
def test_one_perturbation_is_flagged(archives: dict[str, Path], reference_runs: dict[str, np.ndarray],
                                     label: str) -> None:
    which, kwargs = PERTURBATIONS[label]
    result = run(archives["example1"], RunOptions(stop_time=SHORT, **kwargs)).rows
    comparison = compare(result, reference_runs[which], TOLERANCES, label, which)
    assert not comparison.passed, format_comparison(comparison)


@pytest.mark.parametrize("which", ["plain", "early fault"])
def test_unchanged_rerun_passes(archives: dict[str, Path], reference_runs: dict[str, np.ndarray],
                                which: str) -> None:
    overrides = EARLY_FAULT if which == "early fault" else {}
    result = run(archives["example1"], RunOptions(stop_time=SHORT, overrides=overrides)).rows
    comparison = compare(result, reference_runs[which], TOLERANCES)
    assert comparison.passed, format_comparison(comparison)
    assert all(check.max_deviation == 0 for check in comparison.checks)  # reruns are bit-identical


def test_command_flags_a_gain_change_from_csv_files(archives: dict[str, Path], tmp_path: Path,
                                                    reference_runs: dict[str, np.ndarray],
                                                    capsys: pytest.CaptureFixture) -> None:
    """The whole path: orchestrator CSV -> compare command -> exit 1, table and plot."""
    baseline = write_baseline(reference_runs["plain"], tmp_path / "baseline.csv")
    result = tmp_path / "k1.csv"
    run(archives["example1"], RunOptions(stop_time=SHORT, overrides={"controller.k1": 10.5}, output=result))
    tolerances = str(BASELINE_DIR / "tolerances.json")
    status = main(["compare", str(result), str(baseline), "--tolerances", tolerances,
                   "--plot-dir", str(tmp_path / "plots")])
    out = capsys.readouterr().out
    assert status == 1, out
    assert "| plant.y |" in out
    assert (tmp_path / "plots" / "plant.y.png").is_file()


# Issue 12: changes that pass every tube of the burst phase (the fault 1 s later, a dead-zone break
# point 10 % off) are flagged against the stored baselines through the scenarios' own tubes on
# controller.eta1_hat; the horizons end 3 s after the fault (see tests/baselines/tolerances.json).
LATE = {
    "pendulum": (8.0, {"fault time 5 s -> 6 s": {"actuator.t_fault": 6.0},
                       "dead-zone b_r +10 %": {"actuator.b_r": 0.55},
                       "dead-zone b_l +10 %": {"actuator.b_l": 0.66}}),
    "example1": (13.0, {"fault time 10 s -> 11 s": {"actuator.t_fault": 11.0},
                        "dead-zone b_r +10 %": {"actuator.b_r": 0.55},
                        "dead-zone b_l +10 %": {"actuator.b_l": 0.66}}),
}


@pytest.mark.parametrize(("name", "label"), [(n, label) for n, (_, cases) in LATE.items() for label in cases])
def test_a_late_change_is_flagged(archives: dict[str, Path], name: str, label: str) -> None:
    horizon, cases = LATE[name]
    stored = read_result(BASELINE_DIR / f"{name}.csv")
    baseline = stored[stored["time"] <= horizon]
    tubes = TOLERANCES.for_scenario(name)
    result = run(archives[name], RunOptions(stop_time=horizon, overrides=cases[label])).rows
    comparison = compare(result, baseline, tubes, label, name)
    assert not comparison.passed, format_comparison(comparison)
    assert "controller.eta1_hat" in [c.name for c in comparison.failed]
    # the common tubes alone miss each of them (the silent case of the issue), except the later
    # fault on example1, which plant.z's tube sees too (3.9e-5 against 1e-5)
    seen_by_common_tubes = (name, label) == ("example1", "fault time 10 s -> 11 s")
    assert compare(result, baseline, TOLERANCES).passed is not seen_by_common_tubes
