# SPDX-License-Identifier: BSD-2-Clause
"""The controller as a sampled controller: the clocked twin of the controller FMU (FMI 3.0
Co-Simulation with Event Mode, an input clock of interval sample_time; fmu_src/toolchain/clocked.py,
fmu_src/toolchain/shim/fmi3_clocks.c) and the shipped clocked scenarios (SSP 2.0 archives,
orchestrator/experiments/clocked.py).

Oracles: the unclocked scenarios (where the master steps once per sample time the clocked run
must give their bits), the same scenario at the sample time where the master's step does not
divide it (the clock keeps the sampling instants; the unclocked controller samples at every step,
which is a different, wrong, controller), fmpy's FMI 3.0 schema, and fmusim (the Modelica
Reference FMUs' importer) driving the twin in Event Mode, checked against the Python reference law
replayed on fmusim's activation schedule."""

from __future__ import annotations

import csv
import math
import subprocess
import warnings
import zipfile
from ctypes import c_double, c_int
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi3 import FMU3Slave, fmi3ValueReference
from fmpy.util import read_csv
from fmpy.validation import validate_fmu

import orchestrator
from controller.native import ReferenceLaw
from controller.params import ControllerParameters
from fmu_src.models.examples import EXAMPLE1
from orchestrator import RunOptions
from orchestrator.export import export

pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.EngineNote"),
              pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")]

REPO = Path(__file__).resolve().parent.parent
FMUSIM = REPO.parent / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
SHORT = 3.0


def rows(archive: Path, **options: object) -> np.ndarray:
    return orchestrator.run(archive, RunOptions(**options)).rows  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def twin(built: Path) -> Path:
    return built / "fmus_clocked" / "FixedTimeController_clocked.fmu"


def test_the_twin_declares_its_clock_as_fmi3_says(twin: Path) -> None:
    """fmpy's FMI 3.0 schema and checks pass; Event Mode; one input clock, fixed, without
    intervalDecimal (its interval depends on a parameter); every output clocked, no input."""
    assert validate_fmu(str(twin)) == []
    md = fmpy.read_model_description(str(twin))
    assert md.coSimulation.hasEventMode
    (clock,) = [v for v in md.modelVariables if v.type == "Clock"]
    assert (clock.name, clock.causality, clock.intervalVariability) == ("sample", "input", "fixed")
    assert 'intervalDecimal' not in zipfile.ZipFile(twin).read("modelDescription.xml").decode().split(
        '<Clock', 1)[1].split('/>', 1)[0]
    for v in md.modelVariables:
        clocks = [c.name for c in v.clocks or []]
        assert clocks == (["sample"] if v.causality == "output" else []), v.name


def test_interval_is_sample_time_and_it_needs_event_mode(twin: Path, tmp_path: Path,
                                                          capfd: pytest.CaptureFixture[str]) -> None:
    """fmi3GetIntervalDecimal in Initialization Mode answers the sample_time set; without
    eventModeUsed instantiation refuses (the clock could never be activated)."""
    md = fmpy.read_model_description(str(twin))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    folder = fmpy.extract(str(twin), str(tmp_path / "unzipped"))
    slave = FMU3Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="c")
    with pytest.raises(Exception, match="Failed to instantiate"):
        slave.instantiate(eventModeUsed=False)
    said = "c: fmi3InstantiateCoSimulation: this clocked FMU is activated by its input clock in Event Mode: "
    assert said + "instantiate it with eventModeUsed = true" in capfd.readouterr().err
    slave.instantiate(eventModeUsed=True)
    try:
        slave.setFloat64([vr["sample_time"]], [0.0025])
        slave.enterInitializationMode(startTime=0.0)
        interval, qualifier = (c_double * 1)(), (c_int * 1)()
        slave.getIntervalDecimal((fmi3ValueReference * 1)(vr["sample"]), interval, qualifier)
        assert interval[0] == 0.0025 and qualifier[0] == 2  # fmi3IntervalChanged
        shift = (c_double * 1)()
        slave.getShiftDecimal((fmi3ValueReference * 1)(vr["sample"]), shift)
        assert shift[0] == 0.0
        slave.exitInitializationMode()
        slave.terminate()
    finally:
        slave.freeInstance()


@pytest.mark.parametrize("name, master", [("example1", "gauss-seidel"), ("pendulum", "gauss-seidel"),
                                          ("pendulum_smooth", "gauss-seidel")])
def test_clocked_scenario_gives_the_sampled_scenarios_bits(built: Path, name: str, master: str) -> None:
    """The master steps once per sample time: the clocked scenario (SSP 2.0, the twin activated by
    its clock) gives every row of the unclocked one, bit for bit."""
    plain = rows(built / "ssp" / f"{name}.ssp", stop_time=SHORT, master=master)
    clocked = rows(built / "ssp" / f"{name}_clocked.ssp", stop_time=SHORT, master=master)
    assert plain.dtype.names == clocked.dtype.names and len(plain) == len(clocked)
    for column in plain.dtype.names or ():
        np.testing.assert_array_equal(clocked[column], plain[column], err_msg=column)


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("name, step", [("example1", None), ("pendulum", None), ("pendulum_smooth", None),
                                        ("pendulum_smooth", 0.0003), ("example1_smooth", 0.0004)])
def test_the_compiled_executor_gives_the_python_masters_bits(built: Path, name: str, step: float | None,
                                                             master: str) -> None:
    """The _clocked scenarios under the compiled executor (core.c ticks the twin's clock) and under
    the Python master: every row bit for bit, at the sample time and at a step that does not divide
    it (0.3 ms against 0.5 ms; 0.4 ms against 1 ms)."""
    archive = built / "ssp" / f"{name}_clocked.ssp"
    python = rows(archive, stop_time=SHORT, step=step, master=master, executor="python")
    compiled = rows(archive, stop_time=SHORT, step=step, master=master, executor="compiled")
    assert python.dtype.names == compiled.dtype.names and len(python) == len(compiled) > SHORT / 0.001
    for column in python.dtype.names or ():
        np.testing.assert_array_equal(compiled[column], python[column], err_msg=column)


@pytest.mark.parametrize("fmi, master", [("2", "gauss-seidel"), ("3", "gauss-seidel"), ("3", "jacobi")])
def test_the_exported_clocked_scenario_runs_in_fmpy_and_fmusim_as_orchestrate_runs_it(
        built: Path, tmp_path: Path, fmi: str, master: str) -> None:
    """``orchestrate export`` of example1_clocked at a step of 0.4 ms, which does not divide the
    1 ms sample time: the container ticks the twin's clock itself (asked in Initialization Mode,
    steps cut at the ticks) behind a plain Co-Simulation interface (no clock, no event mode in its
    model description). FMPy (host step 1.2 ms) gives ``orchestrate run``'s rows bit for bit,
    fmusim (0.4 ms) within the 16 digits it prints."""
    archive = built / "ssp" / "example1_clocked.ssp"
    fmu, _ = export(archive, tmp_path / "e.fmu", fmi=fmi, master=master, step=0.0004, stop_time=0.3)
    md = zipfile.ZipFile(fmu).read("modelDescription.xml").decode()
    assert "<Clock" not in md and 'hasEventMode="true"' not in md and "clocks=" not in md
    expected = rows(archive, stop_time=0.3, step=0.0004, master=master)
    got = fmpy.simulate_fmu(str(fmu), stop_time=0.3, step_size=0.0012, output_interval=0.0012)
    assert len(got) == 251
    columns = [c for c in got.dtype.names or () if c != "time"]
    assert "controller.v" in columns and "plant.x1" in columns
    for column in columns:
        np.testing.assert_array_equal(got[column], expected[column][::3], err_msg=column)
    if FMUSIM.is_file():
        subprocess.run([str(FMUSIM), "--interface-type", "cs", "--stop-time", "0.3", "--output-interval",
                        "0.0004", "--output-file", str(tmp_path / "out.csv"), str(fmu)], check=True,
                       timeout=300, capture_output=True)
        theirs = read_csv(str(tmp_path / "out.csv"))
        assert len(theirs) == len(expected)
        for column in columns:
            np.testing.assert_allclose(theirs[column], expected[column], rtol=1e-15, atol=0, err_msg=column)


def on_common_times(run: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of ``run`` and ``reference`` rows at the same times (to 1 ns)."""
    at = np.searchsorted(run["time"], reference["time"] - 1e-12)
    found = np.abs(run["time"][np.minimum(at, len(run) - 1)] - reference["time"]) < 1e-9
    return at[found], np.flatnonzero(found)


@pytest.mark.parametrize("step", [0.0004, 0.0003])
def test_where_the_step_does_not_divide_the_sample_time_the_clock_keeps_the_instants(
        built: Path, step: float) -> None:
    """pendulum_smooth samples every 0.5 ms. At a master step of 0.4 or 0.3 ms the clocked
    controller still acts at 0.5 ms multiples: at their common times the run agrees with the
    0.5 ms one to the plant solver's grid effect (the plant steps on a finer grid), while the
    unclocked controller, which acts at every step, is a different controller (off by 1e-3 in
    x1 and by 10^2 in v)."""
    reference = rows(built / "ssp" / "pendulum_smooth.ssp", stop_time=SHORT)
    clocked = rows(built / "ssp" / "pendulum_smooth_clocked.ssp", stop_time=SHORT, step=step)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = rows(built / "ssp" / "pendulum_smooth.ssp", stop_time=SHORT, step=step)
    mine, theirs = on_common_times(clocked, reference)
    assert len(mine) >= SHORT / 0.002  # a common time every 2 (0.4 ms) or 1.5 ms (0.3 ms)
    assert np.abs(clocked["plant.x1"][mine] - reference["plant.x1"][theirs]).max() < 1e-9
    assert np.abs(clocked["controller.v"][mine] - reference["controller.v"][theirs]).max() < 1e-5
    mine, theirs = on_common_times(plain, reference)
    assert np.abs(plain["plant.x1"][mine] - reference["plant.x1"][theirs]).max() > 1e-3
    assert np.abs(plain["controller.v"][mine] - reference["controller.v"][theirs]).max() > 1.0


def replay(run: np.ndarray, present: int, integrated: int) -> float:
    """The largest |v - law| of ``run`` (example1, one step per sample time) against the Python
    reference law replayed on its own rows: v at row j is the law at the state advanced over each
    step with the inputs of row j - ``integrated``, evaluated with the inputs of row j - ``present``
    (the controller's input columns of a row are the values transferred there)."""
    law = ReferenceLaw(ControllerParameters(**{**EXAMPLE1.controller.__dict__}))
    names = ("x1", "x2", "yd", "yd_dot", "yd_ddot")
    inputs = [tuple(float(run[f"controller.{n}"][j]) for n in names) for j in range(len(run))]
    state: tuple[float, ...] = (EXAMPLE1.controller.r0, *EXAMPLE1.controller.eta0)
    worst = 0.0
    for j in range(len(run)):
        if j:
            step = float(run["time"][j] - run["time"][j - 1])
            state = law.advance(step, None, state, inputs[max(j - integrated, 0)])
        worst = max(worst, abs(law.evaluate(state, inputs[max(j - present, 0)])[0] - run["controller.v"][j]))
    return worst


@pytest.mark.parametrize("archive, master, lags", [
    ("example1", "gauss-seidel", (0, 1)), ("example1_clocked", "gauss-seidel", (0, 1)),
    ("example1", "jacobi", (1, 1)), ("example1_clocked", "jacobi", (1, 2))])
def test_what_each_master_gives_the_controller_replays_the_law_exactly(
        built: Path, archive: str, master: str, lags: tuple[int, int]) -> None:
    """Which inputs the law acts on, under each master, replayed through the reference law to the
    bit. Gauss-Seidel: both controllers output with the inputs of the same point and advanced with
    those of the step's start. Jacobi computes everything at a point from the inputs of the
    previous one: the clocked twin's activation at t_k+1 sees those of t_k, and samples them for
    its next interval (lags 1, 2: a sampled controller whose measurement is one step late). The
    unclocked FMU under Jacobi is no sampled system: it advances over [t_k, t_k+1] with the
    inputs of t_k and outputs at t_k+1 with the same ones (lags 1, 1). So jacobi clocked and
    unclocked cannot be equal (v differs by 8.3e-3 at most over 0.5 s, x1 by 1.6e-5 over 3 s);
    the other lags miss by 8.3e-3 to 345."""
    run = rows(built / "ssp" / f"{archive}.ssp", stop_time=0.5, master=master)
    assert replay(run, *lags) == 0.0
    others = {(0, 1), (1, 1), (1, 2)} - {lags}
    assert all(replay(run, *other) > 1e-3 for other in others)


@pytest.mark.skipif(not FMUSIM.is_file(), reason="no fmusim")
def test_fmusim_drives_the_twin_in_event_mode_as_the_law_says(twin: Path, tmp_path: Path) -> None:
    """fmusim (--event-mode-used) activates the clock from its CSV input every 1 ms from t = 1 ms
    (it cannot activate at t0; it steps from activation to activation: between them its input
    file would hold the clock active, in Step Mode), the inputs held; its rows after each
    activation hold the Python reference law at the state advanced from the previous activation
    over the time between them: the law's own arithmetic, replayed."""
    x = (0.5, -0.25, 1.0, 0.0, 0.0)  # x1, x2, yd, yd', yd''
    ticks = [round(k * 1e-3, 9) for k in range(1, 41)]
    with (tmp_path / "in.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time", "x1", "x2", "yd", "yd_dot", "yd_ddot", "sample"])
        writer.writerow([0.0, *x, 0])
        for t in ticks:
            writer.writerows([[t, *x, 0], [t, *x, 1]])
    subprocess.run([str(FMUSIM), "--interface-type", "cs", "--event-mode-used", "--stop-time", "0.04",
                    "--output-interval", "0.001", "--input-file", str(tmp_path / "in.csv"),
                    "--output-file", str(tmp_path / "out.csv"), str(twin)], check=True, timeout=120,
                   capture_output=True)
    theirs = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    law = ReferenceLaw(ControllerParameters(**{**EXAMPLE1.controller.__dict__}))
    state: tuple[float, ...] = (EXAMPLE1.controller.r0, *EXAMPLE1.controller.eta0)
    held, last = None, None
    expected = {}
    for t in ticks:
        if last is not None:
            state = law.advance(t - last, None, state, x)
        stage = law.evaluate(state, x)
        held, last = (stage[0], state[0]), t
        expected[t] = held
    checked = 0
    for row in theirs:
        t = float(row["time"])
        before = [k for k in ticks if k <= t + 1e-12]
        if not before:
            continue
        v, r = expected[before[-1]]
        same = math.isclose(row["v"], v, rel_tol=1e-15) and math.isclose(row["r"], r, rel_tol=1e-15)
        if math.isclose(t, before[-1], abs_tol=1e-12) and not same and len(before) > 1:
            continue  # the row fmusim samples before the event at a tick (its CSV: 16 digits)
        assert same, (t, row["v"], v, row["r"], r)
        checked += 1
    assert checked >= 39


def test_nonsense_clock_calls_get_an_error_and_never_crash(twin: Path, tmp_path: Path,
                                                           capfd: pytest.CaptureFixture[str]) -> None:
    """The twin's clock functions check what a careless host passes: NULL arrays with a count, a
    value reference that is not the clock, a clock set outside Event Mode, no place for the
    qualifiers; each answers fmi3Error and one message, and the instance goes on (the guard's
    latch aside, it is freed cleanly)."""
    md = fmpy.read_model_description(str(twin))
    clock = next(v.valueReference for v in md.modelVariables if v.type == "Clock")
    folder = fmpy.extract(str(twin), str(tmp_path / "unzipped"))
    calls = {
        "set-clock-null": lambda s: s.fmi3SetClock(s.component, None, 1, None),
        "set-clock-not-a-clock": lambda s: s.fmi3SetClock(s.component, (fmi3ValueReference * 1)(1), 1,
                                                           (fmpy.fmi3.fmi3Clock * 1)(True)),
        "interval-no-qualifiers": lambda s: s.fmi3GetIntervalDecimal(
            s.component, (fmi3ValueReference * 1)(clock), 1, (c_double * 1)(), None),
        "set-clock-in-step-mode": lambda s: s.fmi3SetClock(s.component, (fmi3ValueReference * 1)(clock), 1,
                                                            (fmpy.fmi3.fmi3Clock * 1)(True)),
    }
    for name, call in calls.items():
        slave = FMU3Slave(guid=md.guid, unzipDirectory=folder,
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        slave.instantiate(eventModeUsed=True)
        try:
            slave.enterInitializationMode(startTime=0.0)
            if name == "set-clock-in-step-mode":
                slave.exitInitializationMode()
                slave.enterStepMode()
            capfd.readouterr()
            with pytest.raises(fmpy.fmi1.FMICallException) as refused:
                call(slave)
            assert refused.value.status == 3, name  # fmi3Error
            assert len(capfd.readouterr().err.strip().splitlines()) == 1, name
        finally:
            slave.freeInstance()
