# SPDX-License-Identifier: BSD-2-Clause
"""Masters on a loop with a closed-form answer: x' = k x through an integrator (explicit Euler per
step, no feedthrough) and a gain (direct feedthrough).

Oracles: gauss-seidel resolves the gain at each communication point, so x_k = x0 (1 + h k)^k;
jacobi (libcosim's algorithm) delays each connection by one step, x_{k+1} = x_k + h k x_{k-1};
libcosim itself on the same archive; the CSV against the returned array.
"""

from __future__ import annotations

import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, SimulationError
from orchestrator.cli import main
from orchestrator.crosscheck import run_libcosim
from orchestrator.master import time_grid
from orchestrator.ssp import ParameterSet, write_ssv

pytestmark = pytest.mark.system

H, K, X0 = 0.01, -2.0, 1.0


@pytest.fixture(scope="module")
def loop(test_fmus, tmp_path_factory) -> Path:
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, gain=K, x0=X0, stop=1.0, step=H)


def test_time_column_is_exactly_t0_plus_k_h():
    t = time_grid(0.0, 30.0, 1e-3)
    assert len(t) == 30001
    exact = [float(Fraction(k) * Fraction("0.001")) for k in range(30001)]
    assert t.tolist() == exact
    assert time_grid(0.5, 0.95, 0.1).tolist() == [0.5, 0.6, 0.7, 0.8, 0.9]  # last point not after stop


def test_gauss_seidel_closed_form(loop):
    r = orchestrator.run(loop).rows
    k = np.arange(len(r))
    assert r["time"].tolist() == [float(Fraction(int(i)) * Fraction("0.01")) for i in k]
    np.testing.assert_allclose(r["integrator.x"], X0 * (1 + H * K) ** k, rtol=1e-13)
    np.testing.assert_allclose(r["gain.y"], K * r["integrator.x"], rtol=1e-15)
    assert (r["gain.u"] == r["integrator.x"]).all() and (r["integrator.u"] == r["gain.y"]).all()
    np.testing.assert_allclose(r["source.y"], 2.0 * np.sin(3.0 * r["time"]), rtol=0, atol=1e-15)


def test_jacobi_one_step_delay_per_connection(loop):
    r = orchestrator.run(loop, RunOptions(master="jacobi")).rows
    x = [X0, X0 + H * K * X0]
    while len(x) < len(r):
        x.append(x[-1] + H * K * x[-2])
    np.testing.assert_allclose(r["integrator.x"], x, rtol=1e-13)
    np.testing.assert_allclose(r["gain.y"][1:], K * r["integrator.x"][:-1], rtol=1e-15)
    gs = orchestrator.run(loop).rows
    assert np.max(np.abs(gs["integrator.x"] - r["integrator.x"])) > 1e-4  # they differ, as they should


def test_jacobi_equals_libcosim(loop):
    ours = orchestrator.run(loop, RunOptions(master="jacobi")).rows
    theirs, _ = run_libcosim(loop, 1.0, ["time", "source.y", "gain.y", "integrator.x", "gain.u"])
    assert ours["time"].tolist() == theirs["time"].tolist()
    for name in ("source.y", "gain.y", "integrator.x"):
        np.testing.assert_allclose(ours[name], theirs[name], rtol=0, atol=1e-12)
    # an input column holds the value applied from that time on; libcosim reports it one row later
    np.testing.assert_allclose(ours["gain.u"][:-1], theirs["gain.u"][1:], rtol=0, atol=1e-12)


def test_factor_on_connection_equals_doubled_gain(test_fmus, tmp_path):
    with_factor = loop_scenario(tmp_path / "f", test_fmus, gain=K, factor=2.0)
    a = orchestrator.run(with_factor).rows
    b = orchestrator.run(loop_scenario(tmp_path / "g", test_fmus, gain=K),
                         RunOptions(overrides={"gain.k": 2 * K})).rows
    assert (a["integrator.x"] == b["integrator.x"]).all()  # 2*(k*x) == (2k)*x exactly
    assert (a["integrator.u"] == 2.0 * a["gain.y"]).all()


def test_offset_on_connection_closed_form(test_fmus, tmp_path):
    """x' = k x + c: x_k = (x0 + c/k)(1 + h k)^k - c/k."""
    c = 0.75
    r = orchestrator.run(loop_scenario(tmp_path / "o", test_fmus, gain=K, offset=c)).rows
    k = np.arange(len(r))
    np.testing.assert_allclose(r["integrator.x"], (X0 + c / K) * (1 + H * K) ** k - c / K, rtol=1e-12)


def test_parameter_set_and_set_override(loop, tmp_path):
    ssv = tmp_path / "override.ssv"
    write_ssv(ssv, ParameterSet.of("override.ssv", {"gain.k": -3.0, "integrator.x0": 2.0}))
    r = orchestrator.run(loop, RunOptions(parameter_sets=[ssv])).rows
    k = np.arange(len(r))
    np.testing.assert_allclose(r["integrator.x"], 2.0 * (1 - 3.0 * H) ** k, rtol=1e-13)
    # --set applies last
    r = orchestrator.run(loop, RunOptions(parameter_sets=[ssv], overrides={"gain.k": "-1"})).rows
    np.testing.assert_allclose(r["integrator.x"], 2.0 * (1 - H) ** k, rtol=1e-13)


def test_csv_matches_array_and_is_read_by_fmpy(loop, tmp_path):
    r = orchestrator.run(loop, RunOptions(output=tmp_path / "out.csv", master="jacobi")).rows
    csv = read_csv(tmp_path / "out.csv")
    assert csv.dtype.names == r.dtype.names and csv.dtype.names[0] == "time"
    for name in r.dtype.names:
        assert (csv[name] == r[name]).all()


def test_failure_mid_run_keeps_rows(test_fmus, tmp_path, capsys):
    ssp = loop_scenario(tmp_path / "fail", test_fmus, fail_at=0.5)
    with pytest.raises(SimulationError) as info:
        orchestrator.run(ssp)
    assert str(info.value) == "integrator: fmi2DoStep returned fmi2Discard at t=0.500 s"
    assert len(info.value.result.rows) == 51 and info.value.result.status == "failed"
    csv = tmp_path / "out.csv"
    status = main(["run", str(ssp), "--output", str(csv), "--no-plot", "--quiet"])
    captured = capsys.readouterr()
    assert status == 1
    assert captured.err.strip().splitlines() == [
        f"orchestrate: error: integrator: fmi2DoStep returned fmi2Discard at t=0.500 s; 51 rows kept in {csv}"
    ]
    rows = read_csv(csv)
    assert rows["time"].tolist() == [float(Fraction(k, 100)) for k in range(51)]


def test_cli_run_metrics_plot_and_usage(loop, tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert (
        main(
            [
                "run",
                str(loop),
                "--stop-time",
                "0.2",
                "--step",
                "0.05",
                "--set",
                "gain.k=-1",
                "--output",
                str(out),
                "--plot",
                str(tmp_path / "r.png"),
                "--master",
                "jacobi",
            ]
        )
        == 0
    )
    assert read_csv(out)["time"].tolist() == [0.0, 0.05, 0.1, 0.15, 0.2]
    assert (tmp_path / "r.png").stat().st_size > 0
    assert main(["plot", str(out), "--output", str(tmp_path / "p.png")]) == 0
    assert main(["metrics", str(out)]) == 1  # no plant.y / reference.yd columns
    assert "no column plant.y, reference.yd (choose with --signal and --reference" in capsys.readouterr().err
    for bad in (["run", str(loop), "--set", "gain.k"], ["run", str(loop), "--master", "nope"], [],
                ["run", str(loop), "--stop-time", "nan"], ["run", str(loop), "--step", "inf"]):
        with pytest.raises(SystemExit) as info:
            main(bad)
        assert info.value.code == 2
    assert main(["run", "no_such_scenario", "--quiet"]) == 1
    assert "no built scenario build/ssp/no_such_scenario.ssp" in capsys.readouterr().err
    for delegated in (["report", "--help"], ["baseline", "--help"], ["compare", "--help"]):
        with pytest.raises(SystemExit) as info:  # registered by orchestrator.experiments and .regress
            main(delegated)
        assert info.value.code == 0


def test_installed_script(loop, tmp_path):
    script = Path(sys.executable).with_name("orchestrate")
    done = subprocess.run(
        [
            str(script),
            "run",
            str(loop),
            "--stop-time",
            "0.1",
            "--no-plot",
            "--output",
            str(tmp_path / "s.csv"),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert "loop: 11 rows" in done.stdout
    help_text = subprocess.run([str(script), "run", "--help"], capture_output=True, text=True).stdout
    assert "gauss-seidel" in help_text and "--parameter-set" in help_text


@pytest.mark.parametrize("command", ["metrics", "plot"])
def test_cli_unreadable_result_is_one_line_usage_error(tmp_path, capsys, command):
    """A missing file or a file that is not a result CSV: exit 2, one line naming the file, no
    traceback, the file untouched."""
    text = tmp_path / "notes.csv"
    text.write_text("# not a result\n\nhello, world\n")
    for path, reason in ((tmp_path / "missing.csv", "no such file"), (text, "not a result CSV")):
        with pytest.raises(SystemExit) as info:
            main([command, str(path)])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert f"orchestrate: error: {path}: {reason}" in err and "Traceback" not in err
    assert text.read_text() == "# not a result\n\nhello, world\n"
    assert not (tmp_path / "notes.png").exists()


def test_cli_unwritable_output_is_one_line_error(loop, tmp_path, capsys):
    """--output naming a folder, or a path under a file: exit 1 and one line naming the path; the
    file in the way is untouched. An unwritable --plot keeps the CSV."""
    blocker = tmp_path / "notes.txt"
    blocker.write_text("keep me\n")
    for output, reason in ((tmp_path, "Is a directory"), (blocker / "r.csv", str(blocker))):
        argv = ["run", str(loop), "--stop-time", "0.1", "--no-plot", "--quiet", "--output", str(output)]
        assert main(argv) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("orchestrate: error: cannot write the results: ")
        assert reason in err[0]
    assert blocker.read_text() == "keep me\n"
    csv = tmp_path / "r.csv"
    assert main(["run", str(loop), "--stop-time", "0.1", "--quiet", "--output", str(csv),
                 "--plot", str(blocker / "r.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("orchestrate: error: cannot write the plot: ")
    assert err[0].endswith(f"results kept in {csv}")
    assert read_csv(csv)["time"].tolist() == [float(Fraction(k, 100)) for k in range(11)]
    assert blocker.read_text() == "keep me\n"
