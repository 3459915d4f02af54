# SPDX-License-Identifier: BSD-2-Clause
"""Issue 36: no wrong verdicts, no surprises. One test (or a few) per item of the issue, each
failing on main 5287c35 (items 1 and 7, compare and baseline, are issue 38's).

Oracles: the loop's closed form x_k = x0 (1 + h k)^k (tests/test_orch_master.py), the rows a file
holds counted by the standard library's csv module, pyarrow's own reading of the Parquet metadata,
the FMUs' modelDescription.xml, the controller's own parameter check (controller.params), the
argparse parsers themselves, the figure's artists and their positions, a filesystem made full by
the kernel (a tmpfs of a few KiB), and the exit status and stderr of the real command.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, ScenarioError, ScenarioWarning, UsageError
from orchestrator.cli import _parser, main
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

REPO = Path(__file__).resolve().parent.parent
ORCHESTRATE = REPO / ".venv" / "bin" / "orchestrate"
H, K, X0 = 0.01, -2.0, 1.0


@pytest.fixture(scope="module")
def loop(test_fmus, tmp_path_factory) -> Path:
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, gain=K, x0=X0, stop=1.0, step=H)


def closed_form(k: np.ndarray) -> np.ndarray:
    return X0 * (1 + H * K) ** k


def command(*argv: str, cwd: Path | None = None, env: dict[str, str] | None = None,
            timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """The real ``orchestrate`` (the launcher) in a process of its own."""
    return subprocess.run([str(ORCHESTRATE), *argv], capture_output=True, text=True, cwd=cwd, timeout=timeout,
                          env={**os.environ, **(env or {})})


def no_traceback(r: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in r.stderr and "Traceback" not in r.stdout, r.stderr


# -- item 2: undefined is not failed; the sweep warns of runs that stop before their event -----------
def _table(folder: Path, rows: list[dict[str, object]]) -> Path:
    """A campaign table as the sweep's journal writes it."""
    from orchestrator.campaign.table import Journal

    columns = ["run", "run_id", "scenario", "controller.mode", "stop_time", "step", "status", "reason",
               "wall_time", "mae_after_fault"]
    meta = {"design": "d.toml", "columns": ["controller.mode"], "metrics": ["mae_after_fault"],
            "runs": len(rows),
            "labels": {"controller.mode": {"0": "fixed-time"}}, "scenarios": {"example1": "x"},
            "plots": [{"kind": "scatter", "x": "controller.mode", "metric": "mae_after_fault",
                       "facet": "controller.mode"}]}
    journal = Journal(folder, columns, meta)
    journal.start([])
    for i, r in enumerate(rows):
        journal.append({"run": i, "run_id": f"{i:016x}", "scenario": "example1", "controller.mode": 0,
                        "stop_time": 2.0, "step": 0.001, "reason": "", "wall_time": 0.1, **r})
    journal.finish()
    return journal.parquet_path


@pytest.mark.system
def test_a_metric_undefined_on_finished_runs_is_not_called_failed(tmp_path):
    """Before: 'fixed-time (40 failed/infinite)' on 40 ok runs whose fault came after the horizon."""
    import matplotlib.pyplot as plt

    from orchestrator.campaign import report
    from orchestrator.campaign.table import read_table

    ok_nan = {"status": "ok", "mae_after_fault": math.nan}
    table = _table(tmp_path / "t", [ok_nan, ok_nan, {"status": "failed", "mae_after_fault": math.nan},
                                    {"status": "ok", "mae_after_fault": 0.25}])
    rows, meta = read_table(table)
    fig, ax = plt.subplots()
    try:
        report._scatter(ax, meta["plots"][0], report._facets(meta["plots"][0], rows, meta))
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert legend == ["fixed-time (1 shown; 1 failed, 2 undefined)"]
    finally:
        plt.close(fig)
    summary = report.write_report(table, tmp_path / "r").read_text()
    assert "| mae_after_fault | 0.25 | 0.25 | 0.25 | 0 | 2 |" in summary  # the undefined counted apart
    # a panel with nothing to draw says why
    only_nan = _table(tmp_path / "u", [ok_nan, ok_nan])
    rows, meta = read_table(only_nan)
    fig, ax = plt.subplots()
    try:
        report._scatter(ax, meta["plots"][0], report._facets(meta["plots"][0], rows, meta))
        assert any("no finite mae_after_fault: 2 undefined" in t.get_text() for t in ax.texts)
    finally:
        plt.close(fig)
    assert "Undefined (NaN) in every one of the 2 finished runs, not failed: `mae_after_fault`" in \
        report.write_report(only_nan, tmp_path / "v").read_text()


@pytest.mark.system
def test_sweep_warns_before_running_when_runs_stop_before_their_fault(built, tmp_path):
    """Before: 80 runs of fault_tolerance.toml at --stop-time 2 ran without a word (faults at 2-8 s)."""
    from dataclasses import replace

    from orchestrator.campaign.design import read_design
    from orchestrator.campaign.sweep import late_events, plan
    from orchestrator.experiments.campaigns import TRACKING

    design = read_design(REPO / "ssp" / "campaigns" / "fault_tolerance.toml")
    scenario = built / "ssp" / "example1.ssp"
    _, specs = plan([scenario], replace(design, stop_time=2.0))
    faults = [float(s.overrides["actuator.t_fault"]) for s in specs]
    assert len(specs) == 80 and min(faults) > 2.0  # the oracle: every fault after the horizon
    (message,) = late_events(specs, TRACKING)
    assert message.startswith("80 of 80 runs stop (t = 2 s) at or before their actuator.t_fault ")
    assert "mae_after_fault, max_error_after_fault will be undefined" in message
    _, specs = plan([scenario], design)  # the design's own 12 s horizon covers every fault
    assert late_events(specs, TRACKING) == []


# -- item 3: crosscheck on a user's own scenario ---------------------------------------------------
REFERENCE_FMUS = REPO.parent / "shared" / "tools" / "reference-fmus" / "2.0"
needs_reference_fmus = pytest.mark.skipif(not (REFERENCE_FMUS / "VanDerPol.fmu").is_file(),
                                          reason=f"no Modelica Reference FMUs in {REFERENCE_FMUS}")


def own_scenario(folder: Path) -> Path:
    """VanDerPol into Feedthrough (Reference FMUs): no plant.y, and Feedthrough's other inputs free."""
    comps = (component("vdp", "VanDerPol.fmu", [("x0", "output", "Real"), ("x1", "output", "Real")], {}),
             component("through", "Feedthrough.fmu", [("Float64_continuous_input", "input", "Real"),
                                                     ("Float64_continuous_output", "output", "Real")]))
    conns = (Connection.between("vdp.x0", "through.Float64_continuous_input"),)
    write_ssd(folder, SystemStructure("vdp", comps, conns, Experiment(0.0, 1.0, 0.01)))
    return pack_ssp(folder, {n: REFERENCE_FMUS / n for n in ("VanDerPol.fmu", "Feedthrough.fmu")},
                    folder.parent / f"{folder.name}.ssp")


@pytest.mark.system
@needs_reference_fmus
def test_crosscheck_of_a_users_scenario_compares_its_outputs(tmp_path, capsys, monkeypatch):
    """Before: every cell red, our own two masters included ('plant.y not recorded'); no --signal;
    the unconnected inputs' warnings printed as Python warnings with their source lines."""
    from orchestrator.crosscheck import cli as crosscheck_cli

    archive = own_scenario(tmp_path / "vdp")
    monkeypatch.setattr(crosscheck_cli, "select_tools", lambda keys: [])  # our two masters only
    out = tmp_path / "matrix"
    assert main(["crosscheck", str(archive), "--output", str(out)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "warnings.warn" not in err and "UserWarning" not in err
    warnings = [line for line in err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].startswith("orchestrate: warning: ")  # once, one line
    with open(out / "matrix.csv", newline="") as f:
        cells = list(csv.DictReader(f))
    assert {c["tool"]: c["status"] for c in cells} == {"orchestrate-gauss-seidel": "ok",
                                                       "orchestrate-jacobi": "ok"}
    assert main(["crosscheck", str(archive), "--signal", "vdp.x1", "--output", str(out)]) == 0
    assert main(["crosscheck", str(archive), "--signal", "plant.y", "--output", str(out)]) == 1
    assert "no output plant.y (outputs: vdp.x0, vdp.x1, through.Float64_continuous_output)" in \
        capsys.readouterr().err


def test_the_matrix_compares_the_signals_asked_for():
    """Every output of a scenario without plant.y; a signal a tool did not record is named."""
    from orchestrator.crosscheck.ecos import EcosCliTool
    from orchestrator.crosscheck.matrix import evaluate, signals_of
    from orchestrator.crosscheck.tools import Scenario, ToolRun
    from orchestrator.results import structured

    scenario = Scenario("s", Path("s.ssp"), "s", 0.0, 2.0, 0.5, ("a.y", "b.y"), {}, {}, {})
    assert signals_of(scenario) == ("a.y", "b.y")
    t = np.arange(5) * 0.5
    ours = structured(np.column_stack([t, np.sin(t), np.cos(t)]), ["time", "a.y", "b.y"])
    theirs = ours.copy()
    theirs["b.y"][3] += 1.0  # at t = 1.5 s
    cell = evaluate(EcosCliTool(), scenario, ToolRun(theirs, 1.0, None, {}), ours,
                    signals=signals_of(scenario))
    failed = [c for c in cell.checks if not c.ok]
    assert [c.name for c in failed] == ["2 outputs after 1 s"] and "(b.y)" in failed[0].detail
    assert cell.deviation is not None and cell.deviation.column == "b.y"
    assert cell.deviation.after == pytest.approx(1.0)
    partial = ToolRun(structured(np.column_stack([t, np.sin(t)]), ["time", "a.y"]), 1.0, None, {})
    cell = evaluate(EcosCliTool(), scenario, partial, ours, signals=signals_of(scenario))
    assert [c.detail for c in cell.checks if not c.ok] == ["b.y not recorded"]


# -- item 4: rows are the rows the file holds ---------------------------------------------------------
@pytest.mark.system
@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_the_summary_and_provenance_count_the_rows_in_the_file(loop, tmp_path, capsys, suffix):
    """Before: '101 rows' were '2001 rows' in the summary and the record (every step computed)."""
    out = tmp_path / f"r{suffix}"
    assert main(["run", str(loop), "--output-interval", "0.05", "--no-plot", "--output", str(out)]) == 0
    if suffix == ".csv":
        with open(out, newline="") as f:
            in_file = sum(1 for _ in csv.reader(f)) - 1
    else:
        in_file = pq.read_metadata(out).num_rows
    assert in_file == 21  # t = 0, 0.05, ..., 1
    record = json.loads(Path(f"{out}.json").read_text())
    assert record["rows"] == in_file and record["rows_computed"] == 101
    assert capsys.readouterr().out.startswith("loop: 21 rows (every 0.05 s of 101 computed), t = 0 .. 1 s")


# -- item 5: the Python API is the CLI's equal ---------------------------------------------------------
@pytest.mark.system
def test_the_api_runs_a_built_scenario_by_name(loop, tmp_path, monkeypatch):
    """Before: run('pendulum') said the scenario does not exist (the CLI resolved names, the API not)."""
    (tmp_path / "build" / "ssp").mkdir(parents=True)
    shutil.copy(loop, tmp_path / "build" / "ssp" / "loop.ssp")
    monkeypatch.chdir(tmp_path)
    rows = orchestrator.run("loop", RunOptions(stop_time=0.1)).rows
    np.testing.assert_allclose(rows["integrator.x"], closed_form(np.arange(len(rows))), rtol=1e-13)
    with pytest.raises(ScenarioError, match=r"no scenario 'lop'.*did you mean loop\?"):
        orchestrator.run("lop")


@pytest.mark.system
def test_api_errors_name_the_api_and_check_every_option(loop):
    """Before: '--output-variables: ...' (a CLI flag) and only with an output; an option typo with no
    output went through silently; RunOptions(stop_time='2') said 'must be finite'."""
    with pytest.raises(UsageError, match=r"^output_variables: 'integrator.y' matches no column"):
        orchestrator.run(loop, RunOptions(output_variables=["integrator.y"]))
    with pytest.raises(ScenarioError, match=r"^overrides: no component named 'gian'"):
        orchestrator.run(loop, RunOptions(overrides={"gian.k": 1}))
    with pytest.raises(UsageError, match=r"^stop_time must be a number of seconds \(got str '2'\)$"):
        RunOptions(stop_time="2")  # type: ignore[arg-type]
    assert RunOptions(stop_time=np.int64(2)).stop_time == 2  # a NumPy number is a number


# -- item 6: interactive use ---------------------------------------------------------------------------
@pytest.mark.system
def test_a_run_result_is_readable_in_a_session_and_keeps_its_units(built, tmp_path):
    """Before: repr printed the whole array (6.6 kB), no _repr_html_, plot() needed a file, no units
    in to_pandas() or the Parquet file, dir(orchestrator) listed np, os, Path."""
    import matplotlib
    import pandas

    out = tmp_path / "p.parquet"
    result = orchestrator.run(built / "ssp" / "pendulum.ssp", RunOptions(stop_time=0.05, output=out))
    text = repr(result)  # 101 rows of the pendulum's 0.5 ms step
    assert text.startswith("RunResult(status='complete', 101 rows, t = 0 .. 0.05 s, 25 signals, outputs: ")
    assert len(text) < 150 + sum(len(str(p)) for p in result.outputs.values())  # no array in it
    html = result._repr_html_()
    assert "<td><code>plant.y</code></td><td>rad</td>" in html and len(html) < 20_000
    frame = result.to_pandas()
    assert frame.attrs["units"]["plant.y"] == "rad" and frame.attrs["units"]["time"] == "s"
    assert pandas.read_parquet(out).attrs["units"]["plant.x2"] == "rad/s"  # pandas reads our metadata
    field = pq.read_schema(out).field("plant.y")
    assert field.metadata[b"unit"] == b"rad" and field.metadata[b"description"].endswith(b"[rad]")
    with matplotlib.rc_context({"backend": "Agg"}):
        figure = result.plot()  # shown in the current backend, returned
    assert isinstance(figure, matplotlib.figure.Figure) and figure.axes
    import matplotlib.pyplot as plt

    plt.close(figure)
    assert not {"np", "os", "Path", "warnings", "fnmatch"} & set(dir(orchestrator))
    assert {"run", "RunOptions", "RunResult", "plots"} <= set(dir(orchestrator))
    assert all(getattr(orchestrator, name) is not None for name in dir(orchestrator))  # each one reachable


# -- item 8: where a missing FMU was looked for --------------------------------------------------------
@pytest.mark.system
def test_a_missing_fmu_of_a_folder_names_where_it_was_looked_for(test_fmus, tmp_path, monkeypatch):
    """Before: "FMU 'resources/Gain.fmu' is missing", whatever the working directory."""
    folder = loop_scenario(tmp_path / "project" / "ssp" / "loop", test_fmus, pack=False)
    (folder / "resources" / "Gain.fmu").unlink()
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    with pytest.raises(ScenarioError) as caught:
        orchestrator.run(Path("..") / "project" / "ssp" / "loop")
    assert f"FMU 'resources/Gain.fmu' is missing (looked for {folder.resolve() / 'resources' / 'Gain.fmu'})" \
        in str(caught.value)


# -- item 9: warnings aggregated, --quiet quiet ----------------------------------------------------------
@pytest.mark.system
def test_unconnected_inputs_are_one_warning_and_quiet_is_quiet(test_fmus, tmp_path, capsys):
    """Before: one line per unconnected input on every run, also with --quiet."""
    comps = (component("gain", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": 2.0}),
             component("integrator", "Integrator.fmu", [("u", "input", "Real"), ("x", "output", "Real")], {}))
    write_ssd(tmp_path / "s", SystemStructure("s", comps, (), Experiment(0.0, 0.1, 0.01)))
    archive = pack_ssp(tmp_path / "s", {n: test_fmus[n[:-4]] for n in ("Gain.fmu", "Integrator.fmu")},
                       tmp_path / "s.ssp")
    argv = ["run", str(archive), "--no-plot", "--output", str(tmp_path / "r.csv")]
    assert main(argv) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"orchestrate: warning: {archive}:SystemStructure.ssd: 2 inputs are not "
                             "connected")
    assert "for the whole run: gain: u (0); integrator: u (0) (give values with --set" in err[0]
    assert main([*argv, "--quiet"]) == 0
    assert capsys.readouterr() == ("", "")


# -- item 10: a name that is no scenario ---------------------------------------------------------------
@pytest.mark.system
def test_a_mistyped_name_gets_did_you_mean_and_an_fmu_how_to_run_it(loop, test_fmus, tmp_path):
    """Before: "run 'orchestrate build' first" after a build; a bare .fmu: 'SystemStructure.ssd missing'."""
    (tmp_path / "build" / "ssp").mkdir(parents=True)
    for name in ("example1", "example1_smooth", "pendulum"):
        shutil.copy(loop, tmp_path / "build" / "ssp" / f"{name}.ssp")
    r = command("run", "exmple1", cwd=tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1
    assert "did you mean example1 or example1_smooth?" in r.stderr
    assert "(built: example1, example1_smooth, pendulum)" in r.stderr and "orchestrate build" not in r.stderr
    r = command("run", str(test_fmus["Gain"]), cwd=tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1
    assert "is an FMU, not a scenario" in r.stderr and f"fmpy simulate {test_fmus['Gain']}" in r.stderr


# -- item 11: one command line -------------------------------------------------------------------------
def _subparsers():
    import argparse

    parser = _parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices


OWN = ("run", "validate", "inspect", "plot", "sweep", "campaign-report", "export", "crosscheck", "build",
       "metrics", "report")  # compare and baseline: issue 38
OUTPUTS = ("run", "plot", "sweep", "campaign-report", "export", "crosscheck", "build", "report")


def test_every_command_documents_its_exit_status_takes_quiet_and_o():
    """Before: exit codes documented on 7 of 13 commands, --quiet on 2, and five spellings of the
    output option ('run -o' refused)."""
    commands = _subparsers()
    for name, parser in commands.items():
        assert "exit status" in parser.format_help().lower(), name
    for name in OWN:
        options = {o for a in commands[name]._actions for o in a.option_strings}
        assert {"-q", "--quiet"} <= options, name
        if name in OUTPUTS:
            assert {"-o", "--output"} <= options, name


def test_sizes_print_as_the_options_take_them(capsys):
    """Before: '(default 1.07374e+09)'."""
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "(default 1G)" in out and "(default 512M)" in out and "e+0" not in out


def test_a_usage_error_shows_the_subcommands_usage_and_a_set_twice_is_refused(capsys):
    """Before: a usage error of a subcommand printed orchestrate's usage; --set X=a --set X=b took b."""
    with pytest.raises(SystemExit) as caught:
        main(["validate", "nothing.ssp", "--set", "gain.k=1", "--set", "gain.k=2"])
    assert caught.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("usage: orchestrate validate ")
    assert err[-1] == "orchestrate: error: --set gain.k is given twice ('1' and '2'): give it once"
    assert main(["validate", "nothing.ssp", "--set", "gain.k=1", "--set", "gain.k=1"]) == 1  # the same: fine


@pytest.mark.system
def test_metrics_names_results_that_share_a_stem_apart(built, tmp_path, capsys):
    """Before: p.csv, p.parquet and p.mat were three rows called p."""
    for suffix in (".csv", ".parquet"):
        assert main(["run", str(built / "ssp" / "example1.ssp"), "--stop-time", "0.1", "--quiet", "--no-plot",
                     "--output", str(tmp_path / f"p{suffix}")]) == 0
    assert main(["metrics", str(tmp_path / "p.csv"), str(tmp_path / "p.parquet")]) == 0
    table = capsys.readouterr().out.split("\n\n")[0].splitlines()
    assert [line.split("|")[1].strip() for line in table[2:]] == ["p.csv", "p.parquet"]


@pytest.mark.system
def test_validate_refuses_what_the_controller_refuses(built, capsys):
    """Before: beta = 1.0 passed validate (max="1.0") and failed in the FMU at t = 0. Oracle: the
    controller's own check, controller.params."""
    from dataclasses import replace

    from controller.params import ParameterError
    from fmu_src.models.examples import EXAMPLE1

    for changes in ({"beta": 1.0, "alpha": 1.0, "q1": 0.0}, {"beta": 0.5}):  # one validate reports all
        for name, value in changes.items():
            field = {"q1": "q"}.get(name, name)
            with pytest.raises(ParameterError):  # the law refuses it
                replace(EXAMPLE1.controller, **{field: (value, 8.0) if field == "q" else value})
        argv = [a for name, value in changes.items() for a in ("--set", f"controller.{name}={value}")]
        assert main(["validate", str(built / "ssp" / "example1.ssp"), *argv]) == 1
        out = capsys.readouterr().out
        assert all(f"controller.{name} = {value!r} is " in out for name, value in changes.items()), out
    assert main(["validate", str(built / "ssp" / "example1.ssp"), "--set", "controller.beta=0.9999"]) == 0


# -- item 12: the run figure ---------------------------------------------------------------------------
def test_the_control_panel_has_a_tick_per_decade_v_on_top_and_legends_beside():
    """Before: ticks only at 0, +-1e3, +-1e4 for |v| up to 1.5e4 over a level of a few; uf drawn over
    v; legends inside the panels, on the traces."""
    import matplotlib.pyplot as plt

    from orchestrator.experiments.figures import tracking_figure

    t = np.linspace(0.0, 30.0, 30001)
    yd = np.sin(0.5 * t)
    v = np.where(t < 0.01, 1.5e4, 3.0 * np.sin(50 * t))  # the fixed-time spike, then bursts of 3
    columns = {"time": t, "plant.y": yd + 0.6 * np.exp(-40 * t), "reference.yd": yd, "controller.v": v,
               "actuator.uf": 0.8 * v}
    result = np.zeros(len(t), dtype=[(n, float) for n in columns])
    for n, values in columns.items():
        result[n] = values
    fig = tracking_figure(result, {}, None)
    assert fig is not None
    try:
        control = fig.axes[-1]
        fig.canvas.draw()
        positive = sorted(tick for tick in control.get_yticks() if tick > 0)
        assert positive == [1.0, 10.0, 100.0, 1000.0, 10000.0]  # 10^0 (the linear part) up to 10^4
        lines = {line.get_label(): line for line in control.get_lines()}
        assert lines["controller.v"].get_zorder() > lines["actuator.uf"].get_zorder()
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is not None:
                box, area = legend.get_window_extent(), ax.get_window_extent()
                assert box.x0 >= area.x1, ax.get_ylabel()  # beside the panel, not on its traces
    finally:
        plt.close(fig)


# -- item 13: shell completion --------------------------------------------------------------------------
def _complete(line: str, cwd: Path) -> list[str]:
    """What ``orchestrate`` answers bash for ``line`` (argcomplete's protocol: the answer on fd 8)."""
    env = {**os.environ, "_ARGCOMPLETE": "1", "_ARGCOMPLETE_SHELL": "bash", "COMP_LINE": line,
           "COMP_POINT": str(len(line)), "_ARGCOMPLETE_IFS": "\n", "COMP_TYPE": "9"}
    r = subprocess.run(["sh", "-c", 'exec "$0" 8>&1 1>/dev/null', str(ORCHESTRATE)], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=120)
    return [w.strip() for w in r.stdout.split("\n") if w.strip()]


@pytest.mark.system
def test_the_shell_completes_commands_scenarios_and_set_names(built, tmp_path):
    (tmp_path / "build").symlink_to(built)
    assert {"run", "report"} <= set(_complete("orchestrate r", tmp_path))
    assert "example1_smooth" in _complete("orchestrate run example1_s", tmp_path)
    with zipfile.ZipFile(built / "fmus" / "Actuator.fmu") as fmu:  # the oracle: the FMU's own names
        md = fmu.read("modelDescription.xml").decode()
    names = _complete("orchestrate run example1 --set actuator.", tmp_path)
    assert "actuator.t_fault=" in names and all(f'name="{n.split(".", 1)[1][:-1]}"' in md for n in names)
    r = command("completion", "bash")
    assert r.returncode == 0 and "complete " in r.stdout and "_ARGCOMPLETE" in r.stdout


@pytest.mark.system
@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
def test_bash_itself_completes_through_the_printed_script(built, tmp_path):
    script = (f'source <("{ORCHESTRATE}" completion bash)\n'
              'COMP_LINE="orchestrate run example1 --mas"; COMP_POINT=${#COMP_LINE}\n'
              'COMP_WORDS=(orchestrate run example1 --mas); COMP_CWORD=3\n'
              '_python_argcomplete orchestrate --mas example1; printf "%s\\n" "${COMPREPLY[@]}"\n')
    (tmp_path / "build").symlink_to(built)
    r = subprocess.run(["bash", "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                       env={**os.environ, "PATH": f"{ORCHESTRATE.parent}:{os.environ['PATH']}"})
    assert r.stdout.split() == ["--master"], r.stderr


# -- item 14: the FMU cache never fails a run -----------------------------------------------------------
def _mounted_tmpfs(kib: int) -> list[str] | None:
    """A command prefix that runs its command with a tmpfs of ``kib`` KiB at $FULL (a user and mount
    namespace: no root needed), or None where the kernel does not allow it."""
    if shutil.which("unshare") is None:
        return None
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=4k none /tmp && echo ok"],
                           capture_output=True, text=True, timeout=60)
    if probe.stdout.strip() != "ok":
        return None
    return ["unshare", "-rm", "sh", "-c", f'mount -t tmpfs -o size={kib}k none "$FULL" && exec "$0" "$@"']


@pytest.mark.system
def test_a_full_cache_disk_falls_back_to_the_runs_folder(loop, test_fmus, tmp_path):
    """Before: every run failed with a bare '[Errno 28] No space left on device'."""
    prefix = _mounted_tmpfs(16)
    if prefix is None:
        pytest.skip("no user or mount namespaces here (unshare -rm)")
    cache = tmp_path / "cache"
    cache.mkdir()
    out = tmp_path / "r.csv"
    r = subprocess.run([*prefix, str(ORCHESTRATE), "run", str(loop), "--no-plot", "--output", str(out)],
                       capture_output=True, text=True, timeout=300,
                       env={**os.environ, "FULL": str(cache), "ORCHESTRATE_CACHE": str(cache)})
    assert r.returncode == 0, r.stderr
    (line,) = [x for x in r.stderr.splitlines() if x]
    assert line.startswith(f"orchestrate: warning: FMU cache {cache / 'fmus'}: cannot unpack ")
    assert "(No space left on device); FMUs are unpacked into the run's folder instead" in line
    with open(out, newline="") as f:
        x = [float(row["integrator.x"]) for row in csv.DictReader(f)]
    np.testing.assert_allclose(x, closed_form(np.arange(len(x))), rtol=1e-13)
    # no room anywhere: one line naming the FMU, the folder and the reason
    folder = loop_scenario(tmp_path / "folder", test_fmus, gain=K, x0=X0, stop=1.0, step=H, pack=False)
    r = subprocess.run([*prefix, str(ORCHESTRATE), "run", str(folder), "--no-plot", "--output", str(out)],
                       capture_output=True, text=True, timeout=300,
                       env={**os.environ, "FULL": str(cache), "ORCHESTRATE_CACHE": "off",
                            "TMPDIR": str(cache)})
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("orchestrate: error: cannot unpack FMU ") and "No space left" in r.stderr


@pytest.mark.system
def test_a_damaged_cache_entry_is_found_and_unpacked_again(loop, tmp_path):
    """Before: a truncated library in the cache failed every later run until deleted by hand."""
    env = {"ORCHESTRATE_CACHE": str(tmp_path / "cache")}
    out = str(tmp_path / "r.csv")
    assert command("run", str(loop), "--no-plot", "--quiet", "--output", out, env=env).returncode == 0
    libraries = sorted((tmp_path / "cache" / "fmus").glob("*/binaries/*/*.so"))
    assert libraries
    damaged = libraries[0]
    size = damaged.stat().st_size
    damaged.write_bytes(b"")  # a disk that filled up while it was written, a cleaner ...
    r = command("run", str(loop), "--no-plot", "--output", out, env=env)
    assert r.returncode == 0, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("orchestrate: warning: FMU cache entry ") and "was damaged (binaries/" in line
    assert damaged.stat().st_size == size  # whole again
    r = command("run", str(loop), "--no-plot", "--output", out, env=env)
    assert r.returncode == 0 and r.stderr == ""


# -- item 15: bounded memory ------------------------------------------------------------------------------
@pytest.mark.system
def test_an_input_file_too_large_to_hold_is_refused_before_reading(loop, tmp_path):
    """Before: a 1 GB --input-file reached 6.9 GB of memory and was still parsing after 400 s."""
    big = tmp_path / "big.csv"
    with open(big, "wb") as f:
        f.write(b"time,integrator.u\n")
        f.truncate(300 << 20)  # sparse: no disk used, and never read
    r = command("run", str(loop), "--no-plot", "--input-file", str(big), "--output", str(tmp_path / "r.csv"),
                timeout=120)
    no_traceback(r)
    assert r.returncode == 2
    assert r.stderr.splitlines()[-1].startswith(f"orchestrate: error: --input-file {big}: ")
    assert "more than an input file may have (256 MiB" in r.stderr


@pytest.mark.system
def test_a_design_too_large_is_refused_before_it_is_made(built, tmp_path):
    """Before: a range of num = 1e9 reached 3.6 GB in 2 minutes and ignored SIGINT and SIGTERM."""
    design = tmp_path / "d.toml"
    design.write_text('stop_time = 0.1\n[grid]\n"plant.x1_0" = { start = -1, stop = 1, num = 1000000000 }\n')
    r = command("sweep", str(built / "ssp" / "example1.ssp"), "--design", str(design),
                "--out", str(tmp_path / "o"), timeout=60)
    no_traceback(r)
    assert r.returncode == 2 and r.stderr == (f"orchestrate: error: {design}: 1000000000 points, more than a "
                                              "design may have (100000); split it\n")
    design.write_text('stop_time = 0.1\n[grid]\n"plant.x1_0" = { start = -1, stop = 1, num = 1000 }\n'
                      '"plant.x2_0" = { start = -1, stop = 1, num = 1000 }\n')
    r = command("sweep", str(built / "ssp" / "example1.ssp"), "--design", str(design),
                "--out", str(tmp_path / "o"), timeout=60)
    assert r.returncode == 2 and "1000000 points, more than a design may have (100000)" in r.stderr


# -- item 16: four tracebacks ------------------------------------------------------------------------------
@pytest.mark.system
@pytest.mark.parametrize(("extra", "expected"), [
    (["--scheduler", "garbage"], "--scheduler 'garbage': not a Dask scheduler address"),
    (["--dashboard", "no-such-host.invalid:8787"], "--dashboard 'no-such-host.invalid:8787': cannot resolve"),
    (["--out", "FILE"], "--output FILE: not a folder"),  # --out: main's spelling, still taken
])
def test_sweep_refuses_bad_cluster_options_in_one_line(built, tmp_path, extra, expected):
    """Before: tracebacks from distributed (ValueError, RuntimeError) and from mkdir (FileExistsError)."""
    design = tmp_path / "d.toml"
    design.write_text('stop_time = 0.1\n[grid]\n"plant.x1_0" = [0.5]\n')
    (tmp_path / "FILE").write_text("mine\n")
    extra = [str(tmp_path / "FILE") if a == "FILE" else a for a in extra]
    expected = expected.replace("FILE", str(tmp_path / "FILE"))
    r = command("sweep", str(built / "ssp" / "example1.ssp"), "--design", str(design), *extra, timeout=120)
    no_traceback(r)
    assert r.returncode == 2 and r.stderr.splitlines()[-1].startswith(f"orchestrate: error: {expected}")
    assert (tmp_path / "FILE").read_text() == "mine\n"


FMI3_DAHLQUIST = REPO.parent / "shared" / "tools" / "reference-fmus" / "3.0" / "Dahlquist.fmu"


@pytest.mark.system
@pytest.mark.skipif(not FMI3_DAHLQUIST.is_file(), reason=f"no {FMI3_DAHLQUIST}")
def test_an_fmi3_start_that_is_no_number_is_refused_by_validate_and_run(tmp_path):
    """Before: validate passed start="" and run died in the master with a ValueError traceback."""
    fmu = tmp_path / "Dahlquist.fmu"
    with zipfile.ZipFile(FMI3_DAHLQUIST) as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                assert data.count(b'initial="exact" start="1"/>\n    <Float64 name="der(x)"') == 1
                data = data.replace(b'initial="exact" start="1"/>\n    <Float64 name="der(x)"',
                                    b'initial="exact" start=""/>\n    <Float64 name="der(x)"')
            zout.writestr(item, data)
    comps = (component("d", "Dahlquist.fmu", [("x", "output", "Real")], {}),)
    write_ssd(tmp_path / "s", SystemStructure("s", comps, (), Experiment(0.0, 1.0, 0.1)))
    archive = pack_ssp(tmp_path / "s", {"Dahlquist.fmu": fmu}, tmp_path / "s.ssp")
    expected = "component 'd': FMU 'Dahlquist.fmu': variable 'x': start=\"\" is no Float64 value"
    r = command("validate", str(archive))
    assert r.returncode == 1 and expected in r.stdout
    r = command("run", str(archive), "--no-plot", "--output", str(tmp_path / "r.csv"))
    no_traceback(r)
    assert r.returncode == 1 and expected in r.stderr and r.stderr.count("\n") == 1


# -- warnings of the whole command line: one line each -----------------------------------------------------
def test_a_python_warning_during_a_command_is_one_line(monkeypatch, capsys):
    """Before: crosscheck and sweep printed Python's warning format (file, line, source)."""
    import warnings

    from orchestrator import cli

    def handler(args: object) -> int:
        warnings.warn("first line\nsecond line", ScenarioWarning, stacklevel=1)
        warnings.warn("first line\nsecond line", ScenarioWarning, stacklevel=1)  # the same: once
        warnings.warn("a library's", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(cli, "_plot", handler)
    assert main(["plot", "x.csv"]) == 0
    assert capsys.readouterr().err.splitlines() == ["orchestrate: warning: first line second line",
                                                    "orchestrate: warning: a library's (RuntimeWarning)"]
    assert main(["plot", "x.csv", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_the_api_refuses_options_of_the_wrong_type():
    """RunOptions given as a dict: one UsageError, not an AttributeError deep in the run."""
    with pytest.raises(UsageError, match="options must be a RunOptions"):
        orchestrator.run("x.ssp", {"stop_time": 1.0})  # type: ignore[arg-type]


# -- found by the attack of 152 bad command lines (issue 36's "tried again") ----------------------------
@pytest.mark.system
def test_bad_command_lines_the_attack_found(loop, capsys):
    """'run X -o ""' was a ValueError traceback (Path('') is '.', its plot's name); argparse's own
    errors of a subcommand read 'orchestrate run: error:' where every other error reads
    'orchestrate: error:'."""
    assert main(["run", str(loop), "-o", ""]) == 1  # as with --no-plot: the folder '.' is refused
    assert capsys.readouterr().err.splitlines() == [
        "orchestrate: error: cannot write the results: .: Is a directory, not a regular file"]
    with pytest.raises(SystemExit) as caught:
        main(["run", str(loop), "--master", "nope"])
    err = capsys.readouterr().err.splitlines()
    assert caught.value.code == 2 and err[0].startswith("usage: orchestrate run ")
    assert err[-1].startswith("orchestrate: error: argument --master: invalid choice: 'nope'")
