# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrator.run`` returns a RunResult, and every run error carries one (issue 22).

Oracles: the loop x' = k x of tests/orch_helpers.py, which gauss-seidel solves as
x_k = x0 (1 + h k)^k exactly in exact time t_k = k h; the files written, read back with fmpy; the
integrator's ``fail_at`` parameter, which makes it return fmi2Error at a known step.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, RunResult, SimulationError, UsageError
from orchestrator.cli import main
from orchestrator.master import time_grid
from orchestrator.plots import build_figure

pytestmark = pytest.mark.system

H, K, X0 = 0.01, -2.0, 1.0


@pytest.fixture(scope="module")
def loop(test_fmus, tmp_path_factory):
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, gain=K, x0=X0, stop=0.5, step=H)


def test_run_returns_a_result_with_rows_time_provenance_and_outputs(loop, tmp_path):
    out = tmp_path / "r.csv"
    result = orchestrator.run(loop, RunOptions(output=out))
    assert isinstance(result, RunResult)
    assert (result.status, result.message, result.success) == ("complete", "", True)
    assert result.count == len(result.rows) == 51 and result.time == 0.5 and not result.preview
    assert result.rows["time"].tolist() == time_grid(0.0, 0.5, H).tolist()
    np.testing.assert_allclose(result.rows["integrator.x"], X0 * (1 + H * K) ** np.arange(51), rtol=1e-13)
    assert result.columns[0] == "time" and "gain.u" in result.columns
    assert result.outputs == {"result": out, "provenance": out.with_name("r.csv.json")}
    on_disk = json.loads(result.outputs["provenance"].read_text())
    assert on_disk == json.loads(json.dumps(result.provenance))  # the record run() wrote, not read back
    assert on_disk["status"] == "complete" and on_disk["rows"] == 51
    assert on_disk["outputs"] == ["source.y", "gain.y", "integrator.x"]
    np.testing.assert_array_equal(read_csv(out)["integrator.x"], result.rows["integrator.x"])
    frame = result.to_pandas()
    assert frame.index.name == "time" and list(frame.index) == result.rows["time"].tolist()
    np.testing.assert_array_equal(frame["gain.y"].to_numpy(), result.rows["gain.y"])
    assert result.plot(tmp_path / "r.png").stat().st_size > 5000


def test_run_without_output_still_has_provenance(loop):
    result = orchestrator.run(loop, RunOptions(stop_time=0.1))
    assert result.outputs == {} and result.provenance["stop_time"] == 0.1
    assert result.provenance["status"] == "complete" and result.count == 11


def test_a_failed_run_raises_carrying_the_result_of_the_rows_kept(test_fmus, tmp_path):
    failing = loop_scenario(tmp_path / "f", test_fmus, gain=K, x0=X0, stop=0.5, step=H, fail_at=0.2)
    out = tmp_path / "f.csv"
    with pytest.raises(SimulationError, match="integrator: fmi2DoStep") as info:
        orchestrator.run(failing, RunOptions(output=out))
    result = info.value.result
    assert isinstance(result, RunResult) and result.status == "failed" and not result.success
    assert result.message == str(info.value)
    assert result.count == len(result.rows) == len(read_csv(out)) and result.count > 1
    assert result.time == result.rows["time"][-1] < 0.5
    assert json.loads(out.with_name("f.csv.json").read_text())["status"] == "failed"


def test_options_are_checked_when_made():
    with pytest.raises(UsageError, match="unknown master 'seidel'"):
        RunOptions(master="seidel")
    with pytest.raises(UsageError, match=r"step must be positive and finite \(got -0.1\)"):
        RunOptions(step=-0.1)
    with pytest.raises(UsageError, match=r"timeout must be positive and finite \(got nan\)"):
        RunOptions(timeout=float("nan"))
    options = RunOptions(parameter_sets=["a.ssv"], output_variables="plant.*")
    assert options.parameter_sets == (Path("a.ssv"),)
    assert options.output_variables == ("plant.*",)


def test_an_output_variable_matching_nothing_fails_before_the_run(loop, tmp_path, capsys):
    """Before: a typo in --output-variables was reported after the whole run, leaving the
    streamed .partial.csv and a sidecar at 'running' behind."""
    out = tmp_path / "out" / "r.csv"
    with pytest.raises(UsageError, match="'gain.z' matches no column"):
        orchestrator.run(loop, RunOptions(output=out, output_variables=("gain.z",)))
    assert not out.parent.exists() or list(out.parent.iterdir()) == []
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(loop), "--quiet", "--output", str(out), "--output-variables", "gain.z"])
    assert exit_.value.code == 2 and "'gain.z' matches no column" in capsys.readouterr().err
    assert not out.parent.exists() or list(out.parent.iterdir()) == []


def test_the_default_figure_of_a_users_scenario_shows_every_output_by_component(loop, tmp_path):
    """Before: a scenario without plant/reference got the first 8 columns, input copies
    (gain.u, integrator.u) among them, one panel each."""
    result = orchestrator.run(loop)
    fig = build_figure(result.rows, "loop", result.units, record=result.provenance)
    plotted = {ax.get_ylabel(): [line.get_label() for line in ax.get_lines()] for ax in fig.axes}
    assert plotted == {"source (-)": ["source.y"], "gain (-)": ["gain.y"], "integrator (-)": ["integrator.x"]}
    fig = build_figure(result.rows, "loop", result.units, variables=["gain.*"])
    assert [[line.get_label() for line in ax.get_lines()] for ax in fig.axes] == [["gain.u", "gain.y"]]
    with pytest.raises(UsageError, match="^variables: 'plant.y' matches no column"):
        build_figure(result.rows, variables=["plant.y"])
    assert main(["run", str(loop), "--quiet", "--output", str(tmp_path / "l.csv"),
                 "--plot-variables", "integrator.*"]) == 0
    assert (tmp_path / "l.png").stat().st_size > 5000


def test_input_file_drives_an_unconnected_input_of_a_real_fmu(test_fmus, tmp_path, capsys):
    """The loop's free sine source replaced by a file: a lone gain (y = k u) whose u no connection
    feeds, driven by u(t) = 1 + 2t (rows 0.25 s apart: interpolation is exact)."""
    from orchestrator.ssp import Experiment, SystemStructure, component, pack_ssp, write_ssd

    folder = tmp_path / "one"
    gain = component("gain", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": 3.0})
    write_ssd(folder, SystemStructure("one", (gain,), (), Experiment(0.0, 0.5, H)))
    archive = pack_ssp(folder, {"Gain.fmu": test_fmus["Gain"]}, tmp_path / "one.ssp")
    inputs = tmp_path / "u.csv"
    inputs.write_text("time,gain.u\n0.0,1.0\n0.25,1.5\n0.5,2.0\n")
    result = orchestrator.run(archive, RunOptions(input_file=inputs))  # no 'not connected' warning
    t = result.rows["time"]
    np.testing.assert_allclose(result.rows["gain.u"], 1 + 2 * t, rtol=1e-14)
    np.testing.assert_allclose(result.rows["gain.y"], 3 * (1 + 2 * t), rtol=1e-14)
    assert result.provenance["input_file"]["inputs"] == ["gain.u"]
    assert main(["run", str(archive), "--quiet", "--no-plot", "--input-file", str(inputs),
                 "--output", str(tmp_path / "r.csv")]) == 0
    np.testing.assert_allclose(read_csv(tmp_path / "r.csv")["gain.y"], 3 * (1 + 2 * t), rtol=1e-14)
    (tmp_path / "bad.csv").write_text("time,gain.y,gain.v\n0.0,1.0,1.0\n0.5,1.0,1.0\n")
    with pytest.raises(UsageError, match=r"'gain.y' is not a Real input of the scenario; 'gain.v' is not a "
                                         r"Real input of the scenario \(inputs it can drive: gain.u\)"):
        orchestrator.run(archive, RunOptions(input_file=tmp_path / "bad.csv"))
    (tmp_path / "short.csv").write_text("time,gain.u\n0.0,1.0\n0.25,1.5\n")
    with pytest.warns(orchestrator.ScenarioWarning, match=r"covers t = 0 .. 0.25 s of the run's 0 .. 0.5 s"):
        orchestrator.run(archive, RunOptions(input_file=tmp_path / "short.csv"))


def test_input_file_refuses_a_connected_input(loop, tmp_path):
    (tmp_path / "u.csv").write_text("time,gain.u\n0.0,1.0\n1.0,1.0\n")
    with pytest.raises(UsageError, match=r"'gain.u' is fed by integrator.x \(inputs it can drive: none\)"):
        orchestrator.run(loop, RunOptions(input_file=tmp_path / "u.csv"))


def test_fmi_log_traces_the_calls_of_the_chosen_components(loop, tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert main(["run", str(loop), "--stop-time", "0.02", "--quiet", "--no-plot", "--output", str(out),
                 "--fmi-log", "gain"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("fmi: ")]
    assert lines[0] == "fmi: gain: fmi2Instantiate(Gain.fmu) -> ok"
    assert all(line.startswith("fmi: gain: ") for line in lines)  # the integrator is not traced
    steps = [line for line in lines if "fmi2DoStep" in line]
    assert steps == ["fmi: gain: fmi2DoStep(t=0.0, h=0.01) -> fmi2OK",
                     "fmi: gain: fmi2DoStep(t=0.01, h=0.01) -> fmi2OK"]
    functions = [line.split(": ")[2].split("(")[0] for line in lines]
    assert functions.index("fmi2SetupExperiment + fmi2EnterInitializationMode") < functions.index(
        "fmi2ExitInitializationMode") < functions.index("fmi2DoStep") < functions.index("fmi2Terminate")
    gets = [line for line in lines if "fmi2GetReal" in line]
    assert gets and all(line.endswith("fmi2OK") for line in gets)
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(loop), "--quiet", "--no-plot", "--output", str(out), "--fmi-log", "gian"])
    assert exit_.value.code == 2 and "--fmi-log: no component matches gian" in capsys.readouterr().err


def test_ctrl_c_while_a_block_is_written_writes_no_row_twice_or_half(tmp_path, monkeypatch):
    """A handler that raises (a second Ctrl-C) at the moment a block of rows has been written but
    not yet counted made close() write the block again. close() now cuts the CSV back to the last
    committed block first: it holds every row once (oracle: the rows appended). Holding the signals
    was not enough: under xdist another thread of the process took the signal."""
    import os
    import signal

    from orchestrator import results
    from orchestrator.results import Recorder, read_result

    real = results._write_all
    fired = []

    def write_then_signal(fd: int, data: bytes) -> None:
        real(fd, data)
        if len(data) > 1000 and not fired:
            fired.append(True)
            os.kill(os.getpid(), signal.SIGINT)  # handled as soon as Python may: KeyboardInterrupt

    monkeypatch.setattr(results, "_write_all", write_then_signal)
    recorder = Recorder(["time", "x"], 1000, tmp_path / "r.csv")
    with pytest.raises(KeyboardInterrupt):
        for k in range(1000):
            recorder.append(np.array([k / 1000, float(k)]))
    recorder.close()
    rows = read_result(tmp_path / "r.csv")
    assert fired and rows["x"].tolist() == [float(k) for k in range(len(rows))] and len(rows) >= 208


def test_a_result_that_cannot_be_renamed_into_place_keeps_its_rows(tmp_path):
    """Review: when the last step of close(), renaming the temporary file onto the result's name,
    failed (here a folder put at that name during the run), the temporary file holding every row
    was removed with it. It is now kept, and the error names it."""
    from orchestrator.errors import OutputError
    from orchestrator.results import Recorder

    target = tmp_path / "r.csv"
    recorder = Recorder(["time", "x"], 500, target)
    for k in range(500):
        recorder.append(np.array([k * 0.01, k * k * 0.5]))
    target.mkdir()
    (target / "something").write_text("x")  # a folder that is not empty: no rename replaces it
    with pytest.raises(OutputError, match="the 500 rows written are kept in") as info:
        recorder.close()
    kept = Path(str(info.value).rsplit(" kept in ", 1)[1])
    data = read_csv(kept)
    assert kept.parent == tmp_path and len(data) == 500
    assert np.array_equal(data["x"], np.arange(500) ** 2 * 0.5)
    assert recorder.saved == 0
