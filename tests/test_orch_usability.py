# SPDX-License-Identifier: BSD-2-Clause
"""Issue 12: mistakes that used to pass silently with exit 0 now fail or warn.

Each test reproduces one silent case of the issue and checks the one-line error or warning.
Oracles: the time grid by exact fractions, the loop's closed form x_k = x0 (1 + h k)^k (see
test_orch_master), package metadata, the files as written by hand.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import io
import json
import math
import os
import re
import subprocess
import sys
import warnings
import zipfile
from fractions import Fraction
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv
from lxml import etree
from orch_helpers import loop_scenario

import orchestrator
import orchestrator.validate
from orchestrator import RunOptions
from orchestrator.cli import _parser, main, plot_title
from orchestrator.errors import ScenarioError, ScenarioWarning, UsageError, command_line
from orchestrator.provenance import summary
from orchestrator.ssp import NS, SSD_NAME, Experiment, ParameterSet, SystemStructure, write_ssv
from orchestrator.validate import timing

H, K, X0 = 0.01, -2.0, 1.0


@pytest.fixture(scope="module")
def loop(test_fmus, tmp_path_factory) -> Path:
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, gain=K, x0=X0, stop=1.0, step=H)


def _structure(start: float = 0.0, stop: float | None = 30.0, step: float | None = 1e-3) -> SystemStructure:
    return SystemStructure("s", (), (), Experiment(start, stop, step), ssd_file="s/SystemStructure.ssd")


# -- part 7: CLI consistency ----------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    expected = f"orchestrate {version('fixed-time-cosim')} (fmpy {version('fmpy')}"
    assert capsys.readouterr().out.startswith(expected)


def test_every_subcommand_help_is_under_the_orchestrate_name(capsys):
    parser = _parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert {"run", "validate", "plot", "metrics", "compare", "baseline", "report"} <= set(sub.choices)
    for name in sub.choices:
        with pytest.raises(SystemExit) as info:
            main([name, "--help"])
        assert info.value.code == 0
        assert capsys.readouterr().out.startswith(f"usage: orchestrate {name} "), name


@pytest.mark.parametrize(("stop", "step"), [(30.0005, 1e-3), (1.0, 0.3), (0.105, 0.01)])
def test_a_step_that_does_not_divide_the_run_is_refused(stop, step):
    """Before: the run silently ended at the last whole step (e.g. 0.9 s of 1 s with h = 0.3)."""
    last = Fraction(stop) // Fraction(step) * Fraction(step)
    assert last < Fraction(stop)  # the oracle: the grid would have ended early
    with pytest.raises(UsageError, match=r"^stop_time, step: the step .* does not divide the run"):
        timing(_structure(), stop, step)  # the Python API names RunOptions' fields (issue 36)
    with command_line(), pytest.raises(UsageError, match=r"^--stop-time, --step: the step .* does not"):
        timing(_structure(), stop, step)
    with pytest.raises(ScenarioError, match=r"s/SystemStructure.ssd: the step .* does not divide"):
        timing(_structure(stop=stop, step=step))


def test_a_step_longer_than_the_run_is_a_usage_error():
    """Before: '--step 40' with stop 30 ran zero steps and exited 0."""
    with pytest.raises(UsageError, match=r"^step: the step 40 s is longer than the run 0 .. 30 s "
                                         r"\(from s/SystemStructure.ssd\)"):
        timing(_structure(), step=40.0)


def test_timing_takes_start_and_defaults():
    assert timing(_structure(start=2.0, stop=30.0, step=None)) == (2.0, 30.0, 1e-3)
    assert timing(_structure(), start_time=0.5, stop_time=1.0, step=0.25) == (0.5, 1.0, 0.25)
    with pytest.raises(UsageError, match="before the start time"):
        timing(_structure(), start_time=5.0, stop_time=1.0)


@pytest.mark.system
def test_cli_refuses_bad_grids_and_honours_start_time(loop, tmp_path, capsys):
    for argv in (["--stop-time", "0.105"], ["--step", "40"]):
        with pytest.raises(SystemExit) as info:
            main(["run", str(loop), "--quiet", "--no-plot", "--output", str(tmp_path / "r.csv"), *argv])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert "orchestrate: error: --" in err
        assert err.startswith("usage: orchestrate run ")  # the subcommand's own usage (issue 36)
    r = orchestrator.run(loop, RunOptions(start_time=0.5, stop_time=1.0)).rows
    k = np.arange(len(r))
    assert r["time"].tolist() == [float(Fraction("0.5") + Fraction(int(i)) * Fraction("0.01")) for i in k]
    np.testing.assert_allclose(r["integrator.x"], X0 * (1 + H * K) ** k, rtol=1e-13)
    assert main(["run", str(loop), "--start-time", "0.5", "--quiet", "--no-plot",
                 "--output", str(tmp_path / "s.csv")]) == 0


def test_baseline_resolves_paths_from_the_working_directory(tmp_path):
    """Before: 'baseline' read ssp/ and wrote tests/baselines/ beside the installed package while
    'build' and 'run' used the working directory (a scenario name is a built one, build/ssp/NAME.ssp,
    of the working directory, as for 'run')."""
    done = subprocess.run([str(Path(sys.executable).with_name("orchestrate")), "baseline", "example1"],
                          cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})
    assert done.returncode == 2
    assert "no scenario 'example1'" in done.stderr and "build/ssp/example1.ssp" in done.stderr
    assert not (tmp_path / "tests").exists() and not (tmp_path / "baselines").exists()


# -- part 3: unconnected inputs -------------------------------------------------------------------
def _without_connection(archive: Path, folder: Path, start: str, end: str) -> Path:
    """The scenario of ``archive`` unpacked into ``folder`` with the connection start -> end deleted
    by hand in the SSD's XML."""
    with zipfile.ZipFile(archive) as zf:
        zf.extractall(folder)
    ssd = folder / SSD_NAME
    tree = etree.parse(str(ssd))
    (a, b), (c, d) = start.split("."), end.split(".")
    found = tree.getroot().findall(
        f"ssd:System/ssd:Connections/ssd:Connection[@startElement='{a}'][@startConnector='{b}']"
        f"[@endElement='{c}'][@endConnector='{d}']", NS)
    assert len(found) == 1
    found[0].getparent().remove(found[0])
    tree.write(str(ssd))
    return folder


@pytest.mark.system
def test_an_unconnected_input_warns_on_run_and_validate_and_fails_with_strict(built, tmp_path, capsys):
    """Before: deleting plant.x2 -> actuator.x2 ran to the end with no word (x2 stayed at its start 0)."""
    folder = _without_connection(built / "ssp" / "pendulum.ssp", tmp_path / "p", "plant.x2", "actuator.x2")
    expected = (f"{folder / SSD_NAME}: component 'actuator', input 'x2' is not connected: it keeps the "
                "FMU's start value 0 for the whole run")
    with pytest.warns(ScenarioWarning) as caught:
        orchestrator.run(folder, RunOptions(stop_time=0.002))
    assert [str(w.message) for w in caught] == [expected]
    argv = ["run", str(folder), "--stop-time", "0.002", "--no-plot", "--output", str(tmp_path / "r.csv")]
    assert main(argv) == 0
    assert capsys.readouterr().err.splitlines() == [f"orchestrate: warning: {expected}"]
    assert main([*argv, "--quiet"]) == 0  # issue 36: --quiet means quiet
    assert capsys.readouterr().err == ""
    assert main([*argv, "--strict"]) == 1
    assert capsys.readouterr().err.splitlines() == [f"orchestrate: error: {expected}"]
    assert main(["validate", str(folder)]) == 0
    assert f"warning: {expected}" in capsys.readouterr().out.splitlines()
    # a value given on purpose is not a mistake: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", ScenarioWarning)
        orchestrator.run(folder, RunOptions(stop_time=0.002, overrides={"actuator.x2": 0.0}))


# -- part 2: stale builds -------------------------------------------------------------------------
@pytest.mark.system
def test_a_stale_build_is_refused_naming_the_changed_file(test_fmus, tmp_path, monkeypatch, capsys):
    """Before: after editing ssp/NAME/X.ssv, 'orchestrate run NAME' ran the old build/ssp/NAME.ssp.
    Packed as 'orchestrate build' packs (its record of the sources, fmu_src/toolchain/stamps.py)."""
    from orchestrator.experiments.scenarios import _pack

    monkeypatch.chdir(tmp_path)
    source = loop_scenario(Path("ssp") / "loop", test_fmus, stop=0.1, pack=False)
    for fmu in (source / "resources").glob("*.fmu"):  # as 'orchestrate build' lays them out
        (Path("build") / "fmus").mkdir(parents=True, exist_ok=True)
        fmu.rename(Path("build") / "fmus" / fmu.name)
    (source / "resources").rmdir()
    fmus = {f.name: f for f in Path("build", "fmus").glob("*.fmu")}
    archive = _pack("loop", Path("ssp"), fmus, Path("build") / "ssp" / "loop.ssp", root=tmp_path)
    argv = ["run", "loop", "--quiet", "--no-plot", "--output", "r.csv"]
    assert main(argv) == 0
    os.utime(source / "gain.ssv")  # touched, the same bytes: no change (before: stale for ever)
    assert main(argv) == 0
    gain = source / "gain.ssv"
    gain.write_text(gain.read_text().replace("</ssv:ParameterSet>", "<!-- edited --></ssv:ParameterSet>"))
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err == (f"orchestrate: error: {archive} is stale: ssp/loop/gain.ssv changed since it was built: "
                   "run 'orchestrate build loop' (it rebuilds what is stale; --force rebuilds everything), "
                   "or give --allow-stale\n")
    assert main([*argv, "--allow-stale"]) == 0
    (source / "extra.ssv").write_text("a file added to the scenario after the build\n")
    _pack("loop", Path("ssp"), fmus, archive, root=tmp_path)
    assert main(argv) == 0  # packed again: no longer stale
    (source / "later.ssv").write_text("and another\n")
    assert main(argv) == 1
    assert "ssp/loop/later.ssv changed since it was built" in capsys.readouterr().err
    # the source folder runs directly with the built FMUs, and its edited values apply
    write_ssv(source / "gain.ssv", ParameterSet.of("gain.ssv", {"k": -1.0}), "gain")
    assert main(["run", str(source), "--quiet", "--no-plot", "--output", "s.csv"]) == 0
    x = read_csv("s.csv")["integrator.x"]
    np.testing.assert_allclose(x, X0 * (1 - H) ** np.arange(len(x)), rtol=1e-13)


# -- part 4: provenance ---------------------------------------------------------------------------
def _guids(archive: Path) -> dict[str, str]:
    """FMU file name -> GUID, read from each modelDescription.xml inside the archive by hand."""
    found = {}
    with zipfile.ZipFile(archive) as zf:
        for name in zf.namelist():
            if name.startswith("resources/") and name.endswith(".fmu"):
                with zipfile.ZipFile(io.BytesIO(zf.read(name))) as fmu:
                    xml = fmu.read("modelDescription.xml").decode()
                found[name.removeprefix("resources/")] = re.search(r'guid="([^"]+)"', xml).group(1)
    return found


@pytest.mark.system
def test_every_result_has_a_provenance_file(loop, tmp_path, capsys):
    """Before: a result CSV did not say which overrides, sets, step, master or FMUs produced it."""
    gains = write_ssv(tmp_path / "gains.ssv", ParameterSet.of("gains.ssv", {"gain.k": -1.0}), "gains")
    out = tmp_path / "r.csv"
    before = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    assert main(["run", str(loop), "--set", "integrator.x0=2", "--parameter-set", str(gains), "--master",
                 "jacobi", "--stop-time", "0.5", "--quiet", "--output", str(out),
                 "--plot", str(tmp_path / "r.png")]) == 0
    record = json.loads((tmp_path / "r.csv.json").read_text())
    assert record["scenario"]["sha256"] == hashlib.sha256(loop.read_bytes()).hexdigest()
    assert {f["file"]: f["guid"] for f in record["fmus"].values()} == _guids(loop)
    assert record["overrides"] == {"integrator.x0": "2"}
    assert record["parameter_sets"] == [{"path": str(gains.resolve()),
                                         "sha256": hashlib.sha256(gains.read_bytes()).hexdigest()}]
    assert record["start_values"]["gain.k"] == -1.0 and record["start_values"]["integrator.x0"] == 2.0
    timing_ = (record["start_time"], record["stop_time"], record["step"], record["master"])
    assert timing_ == (0.0, 0.5, H, "jacobi")
    assert record["versions"]["fmpy"] == version("fmpy") and record["versions"]["numpy"] == version("numpy")
    head = subprocess.run(["git", "-C", str(Path(orchestrator.__file__).parent), "rev-parse", "HEAD"],
                          capture_output=True, text=True)
    assert record["git"]["commit"] == (head.stdout.strip() if head.returncode == 0 else None)
    now = datetime.datetime.now(datetime.timezone.utc)
    assert before <= datetime.datetime.fromisoformat(record["date"]) <= now
    assert (record["status"], record["rows"], record["last_time"]) == ("complete", 51, 0.5)
    # the plot title and metrics-style summaries show what was changed
    assert plot_title("r", record, "jacobi") == "r (jacobi)\nintegrator.x0=2, gains.ssv"
    assert "--set integrator.x0=2; --parameter-set gains.ssv" in summary(record)
    assert main(["compare", str(out), str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"result:   {out}: loop.ssp (sha256 {record['scenario']['sha256'][:12]}); "
                                 "--set integrator.x0=2")
    assert printed[1].startswith(f"baseline: {out}: loop.ssp")


@pytest.mark.system
def test_metrics_warns_on_a_partial_result(built, tmp_path, capsys):
    """Before: 'metrics' on a run that failed at 0.03 s of 30 s printed numbers with no warning.
    The pendulum under the jacobi master at 1 ms diverges at t = 0.031 s (see the README)."""
    out = tmp_path / "p.csv"
    assert main(["run", str(built / "ssp" / "pendulum.ssp"), "--master", "jacobi", "--step", "0.001",
                 "--stop-time", "1", "--quiet", "--no-plot", "--output", str(out)]) == 1
    capsys.readouterr()
    last = read_csv(out)["time"][-1]
    record = json.loads((tmp_path / "p.csv.json").read_text())
    assert record["status"] == "failed" and record["last_time"] == last and last < 0.1
    assert main(["metrics", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.err == (f"orchestrate: warning: {out}: partial result (failed at t = {last} s of "
                            "0.0 .. 1.0 s): the metrics cover only the rows written\n")
    assert "p: pendulum.ssp" in captured.out and f"failed at t = {last} s" in captured.out


# -- part 1: units --------------------------------------------------------------------------------
def _unpack(archive: Path, folder: Path) -> Path:
    with zipfile.ZipFile(archive) as zf:
        zf.extractall(folder)
    return folder


def _fault_time(result: np.ndarray) -> float:
    """The first time at which the actuator's output is not the controller's v (the paper's
    actuator: uf = v before t_fault)."""
    differs = np.flatnonzero(result["actuator.uf"] != result["controller.v"])
    return float(result["time"][differs[0]]) if differs.size else math.inf


@pytest.mark.system
def test_a_value_in_another_unit_is_converted_or_refused(built, tmp_path, capsys):
    """Before: value="80" unit="ms" was applied as 80 s (no fault in the run)."""
    folder = _unpack(built / "ssp" / "pendulum.ssp", tmp_path / "p")
    ssv = folder / "actuator.ssv"
    text = ssv.read_text()
    edited = re.sub(r'(<ssv:Parameter name="t_fault">\s*<ssv:Real) value="[^"]*"', r'\1 value="80" unit="ms"',
                    text)
    assert edited != text
    ssv.write_text(edited)
    result = orchestrator.run(folder, RunOptions(stop_time=0.1)).rows
    assert _fault_time(result) == 0.08  # the fault starts at 80 ms, on the 0.5 ms grid
    # the same value on the command line, with and without a space
    for value in ("80ms", "80 ms", "0.08"):
        out = tmp_path / "r.csv"
        assert main(["run", str(built / "ssp" / "pendulum.ssp"), "--set", f"actuator.t_fault={value}",
                     "--stop-time", "0.1", "--quiet", "--no-plot", "--output", str(out)]) == 0
        assert _fault_time(read_csv(out)) == 0.08
    # another dimension, or a unit on a dimensionless variable, is refused with one line
    ssv.write_text(edited.replace('unit="ms"', 'unit="m"'))
    with pytest.raises(ScenarioError) as info:
        orchestrator.run(folder, RunOptions(stop_time=0.1))
    assert str(info.value) == ("actuator.ssv: actuator.t_fault = 80.0 m: a value in m (m) cannot be "
                               "converted to the FMU's unit s (s)")
    assert main(["run", str(folder), "--set", "controller.k1=3ms", "--quiet", "--no-plot",
                 "--output", str(tmp_path / "r.csv")]) == 1
    assert capsys.readouterr().err.splitlines()[-1] == (
        "  - --set: controller.k1 = 3.0 ms: a value in ms (s) cannot be converted to the FMU's variable, "
        "which is dimensionless (give the value without a unit)")


@pytest.mark.system
def test_connector_units_are_checked_against_the_fmu_and_each_other(built, tmp_path):
    """Before: connectors declared unit="m" and unit="s" on plant.x1 -> controller.x1 (an angle in
    rad in the FMU) were accepted."""
    folder = _unpack(built / "ssp" / "pendulum.ssp", tmp_path / "p")
    ssd = folder / SSD_NAME
    tree = etree.parse(str(ssd))
    root = tree.getroot()
    for component, unit in (("plant", "m"), ("controller", "s")):
        real = root.find(f"ssd:System/ssd:Elements/ssd:Component[@name='{component}']/ssd:Connectors/"
                         "ssd:Connector[@name='x1']/ssc:Real", NS)
        real.set("unit", unit)
    tree.write(str(ssd))
    report = orchestrator.validate.validate(folder)
    assert [str(p) for p in report.errors] == [
        f"error: {ssd}: component 'plant', connector 'x1': declared unit m but the FMU's variable is in rad",
        f"error: {ssd}: connection plant.x1 -> controller.x1: unit mismatch (plant.x1 is in m, "
        "controller.x1 in s)"]


def _with_unit(fmu: Path, dest: Path, variable: str, unit: str) -> Path:
    """Copy of a test FMU whose Real ``variable`` is in ``unit`` (rad and deg defined)."""
    definitions = ('<UnitDefinitions><Unit name="rad"><BaseUnit rad="1"/></Unit><Unit name="deg">'
                   '<BaseUnit rad="1" factor="0.017453292519943295"/></Unit></UnitDefinitions>')
    with zipfile.ZipFile(fmu) as zf:
        files = {i.filename: zf.read(i) for i in zf.infolist()}
    xml = files["modelDescription.xml"].decode()
    xml = xml.replace("<LogCategories>", definitions + "<LogCategories>", 1)
    xml = re.sub(rf'(<ScalarVariable name="{variable}"[^>]*>\s*<Real)', rf'\1 unit="{unit}"', xml)
    files["modelDescription.xml"] = xml.encode()
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return dest


@pytest.mark.system
def test_a_connection_between_scalings_of_one_unit_converts(test_fmus, tmp_path):
    """integrator.x in rad -> gain.u in deg: SSP 1.0's implied unit conversion multiplies by 180/pi,
    so x_k = x0 (1 + h k 180/pi)^k."""
    fmus = {"Source": test_fmus["Source"],
            "Gain": _with_unit(test_fmus["Gain"], tmp_path / "Gain.fmu", "u", "deg"),
            "Integrator": _with_unit(test_fmus["Integrator"], tmp_path / "Integrator.fmu", "x", "rad")}
    k = -0.1
    r = orchestrator.run(loop_scenario(tmp_path / "deg" / "loop", fmus, gain=k, stop=0.2, step=H)).rows
    n = np.arange(len(r))
    np.testing.assert_allclose(r["gain.u"], r["integrator.x"] * 180 / math.pi, rtol=1e-15)
    np.testing.assert_allclose(r["integrator.x"], (1 + H * k * 180 / math.pi) ** n, rtol=1e-12)


def test_unit_conversions_against_their_definitions():
    from orchestrator.units import KNOWN, UnitError, convert, split_value

    assert convert(8000.0, KNOWN["ms"], KNOWN["s"]) == 8.0
    assert convert(90.0, KNOWN["deg"], KNOWN["rad"]) == pytest.approx(math.pi / 2, rel=1e-15)
    assert convert(60.0, KNOWN["rpm"], KNOWN["rad/s"]) == pytest.approx(2 * math.pi, rel=1e-15)
    assert convert(25.0, KNOWN["degC"], KNOWN["K"]) == pytest.approx(298.15, rel=1e-15)
    assert convert(36.0, KNOWN["km/h"], KNOWN["m/s"]) == pytest.approx(10.0, rel=1e-15)
    with pytest.raises(UnitError, match=r"ms \(s\) cannot be converted to m \(m\)"):
        convert(1.0, KNOWN["ms"], KNOWN["m"])
    assert [split_value(t) for t in ("8000ms", "8000 ms", "-1.5e3 deg", "1e-3", "3 1/s", "true")] == [
        ("8000", "ms"), ("8000", "ms"), ("-1.5e3", "deg"), ("1e-3", None), ("3", "1/s"), ("true", None)]


# -- part 8: plots ------------------------------------------------------------------------------
def test_the_run_figure_has_units_a_log_error_panel_a_fault_marker_and_readable_control_ticks():
    """A synthetic pendulum-like result (oracle: the columns written here): y in rad, a control
    spike of 1.5e4 over a chattering level of about 1."""
    import matplotlib.pyplot as plt

    from orchestrator.experiments.figures import tracking_figure

    t = np.linspace(0.0, 30.0, 30001)
    yd = np.sin(0.5 * t)
    y = yd + 0.6 * np.exp(-40 * t) + 1e-4 * np.sin(7 * t)
    v = np.where(t < 0.01, 1.5e4, np.sin(50 * t))
    columns = {"time": t, "plant.y": y, "reference.yd": yd, "controller.v": v, "actuator.uf": 0.5 * v}
    result = np.zeros(len(t), dtype=[(n, float) for n in columns])
    for n, values in columns.items():
        result[n] = values
    units = {"plant.y": "rad", "reference.yd": None, "controller.v": None, "actuator.uf": None}
    fig = tracking_figure(result, units, {"start_values": {"actuator.t_fault": 6.0}})
    assert fig is not None
    try:
        output, first, error, control = fig.axes
        assert [a.get_ylabel() for a in fig.axes] == ["output (rad)", "first second (rad)", "|y - yd| (rad)",
                                                      "control (-)"]
        assert error.get_yscale() == "log" and control.get_yscale() == "symlog"
        assert first.get_xlim()[1] <= 1.1  # the first second, on its own axis
        for ax in (output, error, control):
            assert any(list(line.get_xdata()) == [6.0, 6.0] for line in ax.get_lines()), ax.get_ylabel()
        fig.canvas.draw()
        low, high = control.get_ylim()
        ticks = [tick for tick in control.get_yticks() if low <= tick <= high]
        pixels = np.sort([control.transData.transform((0.0, tick))[1] for tick in ticks])
        font = control.yaxis.get_ticklabels()[0].get_fontsize() * fig.dpi / 72
        assert len(ticks) >= 3 and np.diff(pixels).min() > 1.2 * font  # labels cannot overlap
    finally:
        plt.close(fig)


@pytest.mark.system
def test_run_plot_title_and_axes_come_from_the_provenance(built, tmp_path):
    out = tmp_path / "p.csv"
    assert main(["run", str(built / "ssp" / "pendulum.ssp"), "--stop-time", "0.05",
                 "--set", "actuator.t_fault=20ms", "--quiet", "--output", str(out)]) == 0
    record = json.loads((tmp_path / "p.csv.json").read_text())
    assert record["units"]["plant.y"] == "rad" and record["units"]["plant.x2"] == "rad/s"
    assert record["start_values"]["actuator.t_fault"] == 0.02
    assert (tmp_path / "p.png").stat().st_size > 10000


# -- part 6: the scenario's own tubes are what 'compare' uses ----------------------------------------
def test_compare_uses_the_tubes_of_the_baselines_scenario(tmp_path, capsys):
    t = [k / 10 for k in range(11)]
    (tmp_path / "tolerances.json").write_text(json.dumps({
        "signals": {"s": {"atol": 1e-3}}, "scenarios": {"pendulum": {"s": {"atol": 1e-6}}}}))
    for name in ("pendulum", "other"):
        (tmp_path / f"{name}.csv").write_text("time,s\n" + "".join(f"{x!r},1.0\n" for x in t))
    (tmp_path / "r.csv").write_text("time,s\n" + "".join(f"{x!r},1.00001\n" for x in t))  # 1e-5 off
    assert main(["compare", str(tmp_path / "r.csv"), str(tmp_path / "other.csv")]) == 0
    assert main(["compare", str(tmp_path / "r.csv"), str(tmp_path / "pendulum.csv")]) == 1
    assert "| s |" in capsys.readouterr().out


# -- part 1: the checked ranges are in the FMUs' min/max -------------------------------------------
# SPEC section 1 and the models' constraints: (min, max); an open bound (0.5 < beta < 1, alpha > 1,
# q > 0) as the nearest double inside it (issue 36: beta = 1.0 passed the closed hull's check)
INSIDE = {"0.5<": repr(math.nextafter(0.5, 1)), "<1": repr(math.nextafter(1.0, 0)),
          "1<": repr(math.nextafter(1.0, 2)), "0<": repr(math.nextafter(0.0, 1))}
RANGES = {
    "FixedTimeController": {"beta": (INSIDE["0.5<"], INSIDE["<1"]), "alpha": (INSIDE["1<"], None),
                            "k1": ("0.0", None), "q2": (INSIDE["0<"], None), "mode": ("0", "1"),
                            "tau": (INSIDE["0<"], None), "substeps": ("1", None)},
    "Actuator": {"m_r": ("0.0", None), "b_l": ("0.0", None), "K_inf": ("0.0", None)},
    "PendulumPlant": {"M": ("0.0", None), "B": ("0.0", None), "rtol": ("0.0", "1.0"), "method": ("0", "1")},
}


@pytest.mark.system
def test_fmus_declare_the_ranges_their_checks_enforce(fmus, built, capsys):
    for model, ranges in RANGES.items():
        with zipfile.ZipFile(fmus[model]) as zf:
            xml = zf.read("modelDescription.xml").decode()
        for name, (low, high) in ranges.items():
            pattern = rf'<ScalarVariable name="{name}"[^>]*>\s*<(?:Real|Integer)([^>]*)/>'
            element = re.search(pattern, xml).group(1)
            assert re.search(r'min="([^"]*)"', element).group(1) == low, (model, name)
            found = re.search(r'max="([^"]*)"', element)
            assert (found.group(1) if found else None) == high, (model, name)
    # so the orchestrator refuses a value outside before any simulation, in one line
    assert main(["validate", str(built / "ssp" / "pendulum.ssp"), "--set", "controller.beta=1.5",
                 "--set", "actuator.b_r=-0.1"]) == 1
    assert capsys.readouterr().out.splitlines()[:2] == [
        f"error: --set: controller.beta = 1.5 is above the FMU's max {INSIDE['<1']}",
        "error: --set: actuator.b_r = -0.1 is below the FMU's min 0.0"]
