# SPDX-License-Identifier: BSD-2-Clause
"""The five FMUs on a colleague's machine that has no Python at all (tests/colleague.py), in hosts
nobody here wrote: the Reference FMUs' fmusim, the FMU Compliance Checker (FMI Library) and
OMSimulator's program; and in fmpy under a second Python version. Each result is compared with the
same FMU run by fmpy in this process (the build's Python): the FMU's own runtime must give the
same numbers as the host's interpreter."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmu_helpers import unzipped

from orchestrator.crosscheck.colleague import PYTHON_PROBE, hidden, refusal

pytestmark = pytest.mark.system

TOOLS = Path(__file__).resolve().parents[2] / "shared" / "tools"
FMUSIM = TOOLS / "fmusim" / "bin" / "fmusim"
FMUCHECK = TOOLS / "fmucheck" / "bin" / "fmuCheck"
OMSIMULATOR = TOOLS / "omsimulator" / "bin" / "OMSimulator"
ALT_PYTHON = Path(__file__).resolve().parent.parent / ".venv-alt" / "bin" / "python"
STOP, H = 1.0, 1e-3
# Start values per model: inputs held, so that every output moves (the controller's law is active).
CASES = {
    "Reference": {"amplitude": 1.5, "omega": 2.0},
    "FixedTimeController": {"x1": 0.7, "x2": -0.2, "yd": 0.5, "yd_dot": 0.1, "yd_ddot": -0.05},
    "Actuator": {"v": 1.7, "x1": 0.4, "x2": -0.3, "t_fault": 0.5},
    "Example1Plant": {"x1_0": 0.3, "x2_0": -0.2, "uf": 0.5},
    "PendulumPlant": {"x1_0": 0.6, "x2_0": 0.1, "uf": -2.0},
}
# fmusim and fmuCheck make their own time grid (k h, or h summed) and print it with 16 and 17
# digits: stepped on the grid read back, step sizes can differ from theirs in the last bit, which
# the plants' integrators and the controller's RK4 carry into the last bits of the states
# (measured: at most 3e-16 absolute over 1 s). Bit for bit is checked where the stepping is ours
# (tests/test_fmu_c_host.py, on the same colleague's machine) and in fmpy on another Python.
HOST_GRID = 1e-13
NO_NAMESPACE = refusal()
needs_namespace = pytest.mark.skipif(NO_NAMESPACE is not None, reason=str(NO_NAMESPACE))


@pytest.fixture(scope="module")
def sent(fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The FMUs as a colleague receives them: copied to a fresh folder."""
    folder = tmp_path_factory.mktemp("received")
    return {model: Path(shutil.copy(fmu, folder)) for model, fmu in fmus.items()}


def by_fmpy(fmu: Path, start: dict[str, float]) -> np.ndarray:
    """The FMU in fmpy's ``simulate_fmu`` in this process (the build's interpreter), 1 ms step."""
    return fmpy.simulate_fmu(str(fmu), stop_time=STOP, output_interval=H, start_values=start)


def on_grid(fmu: Path, start: dict[str, float], times: np.ndarray) -> np.ndarray:
    """The FMU stepped by fmpy in this process from each communication point of ``times`` (another
    host's CSV) to the next, its outputs recorded at each point."""
    md = fmpy.read_model_description(str(fmu))
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    slave = fmpy.fmi2.FMU2Slave(guid=md.guid, unzipDirectory=unzipped(fmu),
                                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="reference")
    slave.instantiate()
    try:
        fmpy.simulation.apply_start_values(slave, md, start)
        slave.setupExperiment(startTime=times[0])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        rows = []
        for k, t in enumerate(times):
            if k:
                slave.doStep(currentCommunicationPoint=times[k - 1], communicationStepSize=t - times[k - 1])
            rows.append((t, *slave.getReal([v.valueReference for v in outputs])))
        slave.terminate()
    finally:
        slave.freeInstance()
    return np.array(rows, dtype=[("time", float)] + [(v.name, float) for v in outputs])


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as file:
        rows = list(csv.reader(file))
    return {name: np.array([float(row[i]) for row in rows[1:]]) for i, name in enumerate(rows[0])}


def assert_same(got: dict[str, np.ndarray], expected: np.ndarray, rtol: float = 0.0,
                atol: float = 0.0) -> None:
    """Every output of ``expected`` on the same time grid, within the tolerances (0: bit for bit)."""
    np.testing.assert_array_equal(got["time"], expected["time"])
    for name in expected.dtype.names[1:]:
        np.testing.assert_allclose(got[name], expected[name], rtol=rtol, atol=atol, err_msg=name)


@needs_namespace
def test_the_colleague_machine_has_no_python() -> None:
    result = subprocess.run(hidden(["sh", "-c", PYTHON_PROBE]), capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "", f"Python still usable on the colleague's machine: {result.stdout}"


@needs_namespace
@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
@pytest.mark.parametrize("model", list(CASES))
def test_fmusim_without_python(sent: dict[str, Path], model: str, tmp_path: Path) -> None:
    """fmusim's values equal fmpy's stepped on fmusim's grid (within HOST_GRID)."""
    out = tmp_path / "out.csv"
    starts = [arg for name, value in CASES[model].items() for arg in ("--start-value", name, repr(value))]
    command = [str(FMUSIM), "--interface-type", "cs", "--stop-time", repr(STOP), "--output-interval", repr(H)]
    result = subprocess.run(hidden([*command, *starts, "--output-file", str(out), str(sent[model])]),
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    got = read_csv(out)
    assert len(got["time"]) == round(STOP / H) + 1
    assert_same(got, on_grid(sent[model], CASES[model], got["time"]), rtol=HOST_GRID, atol=HOST_GRID)


@needs_namespace
@pytest.mark.skipif(not FMUCHECK.is_file(), reason=f"fmuCheck not found at {FMUCHECK}")
@pytest.mark.parametrize("model", list(CASES))
def test_fmucheck_without_python(sent: dict[str, Path], model: str, tmp_path: Path) -> None:
    """The checker finds nothing to report, and its CSV equals fmpy's run stepped on the checker's
    grid within HOST_GRID (default start values: fmuCheck sets none)."""
    out, log = tmp_path / "out.csv", tmp_path / "check.log"
    command = [str(FMUCHECK), "-h", repr(H), "-n", "0", "-s", repr(STOP), "-o", str(out), "-e", str(log)]
    command.append(str(sent[model]))
    result = subprocess.run(hidden(command), capture_output=True, text=True, timeout=300)
    report = log.read_text(errors="replace")
    assert result.returncode == 0, result.stdout + result.stderr + report
    assert "\t0 Error(s)" in report and "\t0 Warning(s)" in report, report
    got = read_csv(out)
    assert len(got["time"]) == round(STOP / H) + 1
    assert_same(got, on_grid(sent[model], {}, got["time"]), rtol=HOST_GRID, atol=HOST_GRID)


@needs_namespace
@pytest.mark.skipif(not OMSIMULATOR.is_file(), reason=f"OMSimulator not found at {OMSIMULATOR}")
def test_omsimulator_without_python(built: Path, tmp_path: Path) -> None:
    """A whole scenario (the four FMUs of example1) in OMSimulator's program with no Python on the
    machine equals the same program where the machine's Pythons are visible: the FMUs never use
    them."""
    results = {}
    visible = ["env", "-i", "PATH=/usr/bin:/bin"]
    for name, wrap in (("hidden", hidden), ("visible", lambda argv: [*visible, *argv])):
        work = tmp_path / name
        work.mkdir()
        command = [str(OMSIMULATOR), str(built / "ssp" / "example1.ssp"), "--stopTime=1",
                   f"--resultFile={work / 'r.csv'}", f"--tempDir={work}"]
        result = subprocess.run(wrap(command), cwd=work, capture_output=True, text=True, timeout=300)
        assert result.returncode == 0 and "error:" not in result.stdout, result.stdout + result.stderr
        results[name] = (work / "r.csv").read_text()
    assert results["hidden"] == results["visible"]
    table = read_csv(tmp_path / "hidden" / "r.csv")
    y = next(v for k, v in table.items() if k.endswith(".plant.y"))
    assert len(y) > 1000 and np.all(np.isfinite(y)) and abs(y[-1]) < 2.0


ALT_SCRIPT = """
import json, sys
import fmpy
cases, stop, h = json.loads(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
out = {}
for model, (path, start) in cases.items():
    r = fmpy.simulate_fmu(path, stop_time=stop, output_interval=h, start_values=start)
    out[model] = {n: [float(x).hex() for x in r[n]] for n in r.dtype.names}
print(json.dumps({"version": sys.version.split()[0], "results": out}))
"""


@pytest.mark.skipif(not ALT_PYTHON.is_file(), reason=f"no venv of a second Python version: {ALT_PYTHON}")
def test_fmpy_under_another_python_version(sent: dict[str, Path]) -> None:
    """fmpy in a venv of another Python version (make's .venv-alt): the FMUs run on that host's
    interpreter, and give the same numbers bit for bit as on the build's."""
    cases = {model: (str(sent[model]), start) for model, start in CASES.items()}
    command = [str(ALT_PYTHON), "-c", ALT_SCRIPT, json.dumps(cases), repr(STOP), repr(H)]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout.splitlines()[-1])
    assert answer["version"].split(".")[:2] != [str(v) for v in sys.version_info[:2]]
    for model, start in CASES.items():
        got = {n: np.array([float.fromhex(x) for x in v]) for n, v in answer["results"][model].items()}
        assert_same(got, by_fmpy(sent[model], start), rtol=0.0)
