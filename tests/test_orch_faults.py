# SPDX-License-Identifier: BSD-2-Clause
"""Faults at run time, each through ``orchestrate run`` in its own process, as a user meets them.

A small pythonfmu FMU (tests/fmus/Faulty.py) fails on purpose at its k-th step: it raises, its
output becomes NaN or infinite, it returns fmi2Discard, it never returns (ended by --timeout), or
reading its output fails. Beside it a healthy instance of the same FMU writes a line when it is
terminated and when it is freed. Oracles: the FMU's own step counter (row j holds y = j), the
number of rows the fault allows (k: t_0 .. t_{k-1}), the healthy instance's trace, the temporary
folder left empty. Then signals (SIGINT/SIGTERM) and the file system (missing, read-only and full
output, two runs writing one file).
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv
from orch_helpers import build_test_fmu, loop_scenario

from orchestrator.formats import read_table
from orchestrator.provenance import read_provenance
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

pytestmark = pytest.mark.system

ORCHESTRATE = Path(sys.executable).with_name("orchestrate")
H = 0.01
K = 7  # the faulty step
MODES = {"raise": 1, "nan": 2, "inf": 3, "discard": 4, "hang": 5, "get_real": 6}


@pytest.fixture(scope="module")
def faulty_fmu(tmp_path_factory) -> Path:
    return build_test_fmu("Faulty", tmp_path_factory.mktemp("faulty"))


def fault_scenario(folder: Path, fmu: Path, mode: int, trace: Path, stop: float = 0.2) -> Path:
    """faulty (fails at step K in ``mode``) and witness (healthy, traced), each feeding the other."""
    connectors = [("u", "input", "Real"), ("y", "output", "Real")]
    components = (component("faulty", "Faulty.fmu", connectors, {"mode": mode, "k": K}),
                  component("witness", "Faulty.fmu", connectors, {"mode": 0, "trace": str(trace)}))
    connections = (Connection.between("witness.y", "faulty.u"), Connection.between("faulty.y", "witness.u"))
    write_ssd(folder, SystemStructure("faults", components, connections, Experiment(0.0, stop, H)))
    return pack_ssp(folder, {"Faulty.fmu": fmu}, folder.parent / f"{folder.name}.ssp")


def orchestrate(*args: str, tmp: Path, **kwargs) -> subprocess.CompletedProcess:
    """``orchestrate ARGS`` in a new process whose temporary folder is ``tmp``."""
    env = {**os.environ, "TMPDIR": str(tmp)}
    return subprocess.run([str(ORCHESTRATE), *args], capture_output=True, text=True, env=env,
                          timeout=120, **kwargs)


@pytest.mark.parametrize("fault", list(MODES))
def test_fault_at_step_k(fault, faulty_fmu, tmp_path):
    trace = tmp_path / "witness.txt"
    ssp = fault_scenario(tmp_path / "s", faulty_fmu, MODES[fault], trace)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    csv = tmp_path / "out" / "r.csv"
    extra = ["--timeout", "1"] if fault == "hang" else []
    started = time.monotonic()
    r = orchestrate("run", str(ssp), "--output", str(csv), "--no-plot", "--quiet", *extra, tmp=tmp)
    elapsed = time.monotonic() - started
    assert r.returncode == 1, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orchestrate: error: faulty: "), r.stderr
    t_fault, t_before = f"t={K * H:.3f} s", f"t={(K - 1) * H:.3f} s"
    expected = {
        "raise": f"fmi2DoStep returned fmi2Fatal at {t_before}",
        "nan": f"output 'y' is nan at {t_fault}",
        "inf": f"output 'y' is inf at {t_fault}",
        "discard": f"fmi2DoStep returned fmi2Discard at {t_before}",
        "hang": f"fmi2DoStep did not return within 1 s + 2 s (--timeout) at {t_before}",
        "get_real": f"fmi2GetReal returned fmi2Fatal at {t_fault}",
    }[fault]
    assert expected in lines[0], lines[0]
    assert lines[0].endswith(f"; {K} rows kept in {csv}")
    data = read_csv(csv)
    assert len(data) == K
    np.testing.assert_array_equal(data["time"], np.arange(K) * H)
    np.testing.assert_array_equal(data["faulty.y"], np.arange(K))  # the counter: no row lost or NaN
    status = "timeout" if fault == "hang" else "failed"
    assert json.loads(csv.with_name("r.csv.json").read_text())["status"] == status
    assert trace.read_text().splitlines() == ["terminate", "free"]  # the healthy one: terminated, freed
    assert list(tmp.iterdir()) == []  # no temporary folder left
    assert sorted(p.name for p in csv.parent.iterdir()) == ["r.csv", "r.csv.json"]  # no temporary CSV
    if fault == "hang":
        assert elapsed < 20


def _default_sigint() -> None:
    """In the child: Ctrl-C as in a terminal (a test worker may run with SIGINT ignored, which the
    child would inherit and orchestrate would respect)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_for_rows(csv_folder: Path, process: subprocess.Popen, rows: int = 300) -> None:
    """Wait until the CSV being written (temporary name) holds ``rows`` lines."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and process.poll() is None:
        parts = list(csv_folder.glob(".r.csv.*.part"))
        if parts and parts[0].stat().st_size > 0 and len(parts[0].read_bytes().splitlines()) > rows:
            return
        time.sleep(0.05)
    raise AssertionError("the run wrote no rows")


@pytest.mark.parametrize("signum, status", [(signal.SIGINT, 130), (signal.SIGINT, 130), (signal.SIGINT, 130),
                                            (signal.SIGTERM, 143), (signal.SIGTERM, 143)])
def test_signal_stops_at_a_communication_point_and_keeps_rows(signum, status, test_fmus, tmp_path):
    """Every time: exit 130/143, one line, every row computed kept (consecutive grid, the closed
    form of the loop), the plot of them written, provenance 'interrupted' with the same count."""
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=1000.0, step=H)
    out = tmp_path / "out"
    out.mkdir()
    csv = out / "r.csv"
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    process = subprocess.Popen([str(ORCHESTRATE), "run", str(ssp), "--output", str(csv), "--quiet"],
                               stderr=subprocess.PIPE, text=True, env=env, preexec_fn=_default_sigint)
    _wait_for_rows(out, process)
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == status, err
    lines = err.strip().splitlines()
    name = signal.Signals(signum).name
    assert lines[0].startswith(f"orchestrate: interrupted by {name} at t="), err
    assert "fmi2Fatal" not in err and "Traceback" not in err
    data = read_csv(csv)
    n = len(data)
    assert len(lines) == 1 and lines[0].endswith(f"; {n} rows kept in {csv} (plot: {out / 'r.png'})")
    assert n > 300
    np.testing.assert_allclose(data["time"], np.arange(n) * H, rtol=1e-12)
    # a fast machine reaches subnormal x (below 2.2e-308), whose few bits rtol cannot describe
    np.testing.assert_allclose(data["integrator.x"], (1 - 2.0 * H) ** np.arange(n), rtol=1e-12, atol=1e-300)
    record = json.loads((out / "r.csv.json").read_text())
    assert record["status"] == "interrupted" and record["rows"] == n
    assert (out / "r.png").stat().st_size > 0
    assert sorted(p.name for p in out.iterdir()) == ["r.csv", "r.csv.json", "r.png"]


def test_output_folder_is_created(test_fmus, tmp_path):
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=0.1, step=H)
    csv = tmp_path / "new" / "deeper" / "r.csv"
    r = orchestrate("run", str(ssp), "--output", str(csv), "--no-plot", tmp=tmp_path)
    assert r.returncode == 0, r.stderr
    assert len(read_csv(csv)) == 11


def _unwritable(tmp_path: Path) -> Path:
    """A folder this process cannot create files in (root ignores permission bits: /sys then)."""
    if os.geteuid() == 0:
        return Path("/sys/kernel")
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    return folder


def _file_size_limit(limit: int) -> Callable[[], None]:
    """A ``preexec_fn`` limiting the files the process writes to ``limit`` bytes (RLIMIT_FSIZE): a
    full disk for its writes, with no device (Python ignores SIGXFSZ: the write fails, EFBIG)."""
    return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


@pytest.mark.parametrize("case", ["read_only", "full_disk", "file_as_folder"])
def test_unwritable_output_is_one_line(case, test_fmus, tmp_path):
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=200.0 if case == "full_disk" else 1.0, step=H)
    target = {"read_only": _unwritable(tmp_path) / "r.csv", "full_disk": tmp_path / "r.csv",
              "file_as_folder": tmp_path / "loop.ssp" / "r.csv"}[case]
    limit = {"preexec_fn": _file_size_limit(1 << 20)} if case == "full_disk" else {}
    r = orchestrate("run", str(ssp), "--output", str(target), "--no-plot", tmp=tmp_path, **limit)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orchestrate: error: cannot write the results: "), r.stderr
    reason = {"read_only": "Permission denied", "full_disk": "File too large",
              "file_as_folder": "File exists"}[case]
    assert reason in lines[0]
    if case == "read_only":
        assert not target.exists()
    if case == "full_disk":  # no CSV, and the sidecar does not claim rows (it said 'failed, N rows')
        assert not target.exists() and not list(tmp_path.glob(".r.csv.*.part"))
        record = read_provenance(target)
        assert record is not None and record["status"] == "failed" and record["rows"] == 0, record


def test_non_finite_start_value_fails_at_t0_with_no_row(test_fmus, tmp_path):
    """A NaN in the first row: no row kept, the CSV holds the header only, no temporary file left."""
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=0.5, step=H)
    csv = tmp_path / "r.csv"
    r = orchestrate("run", str(ssp), "--output", str(csv), "--no-plot", "--set", "integrator.x0=nan",
                    tmp=tmp_path)
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        "orchestrate: error: integrator: output 'x' is nan at t=0.000 s (not finite; the run stops at the "
        f"first such value); 0 rows kept in {csv}"]
    assert csv.read_text().splitlines() == ["time,gain.u,integrator.u,source.y,gain.y,integrator.x"]
    assert not list(tmp_path.glob(".r.csv.*.part"))


@pytest.mark.parametrize("name", ["r.csv", "r.parquet"])
def test_two_runs_writing_one_file_leave_a_complete_file(test_fmus, tmp_path, name):
    """Both runs succeed; the file and its sidecar are each one run's, complete; no temporary file
    is left (the CSV is streamed, the Parquet file made from a staging CSV of each process)."""
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=20.0, step=H)
    out = tmp_path / "results" / name
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    runs = [subprocess.Popen([str(ORCHESTRATE), "run", str(ssp), "--output", str(out), "--no-plot", "--quiet",
                              "--set", f"integrator.x0={x0}"], env=env, stderr=subprocess.PIPE)
            for x0 in (1.0, 2.0)]
    for p in runs:
        assert p.wait(timeout=120) == 0, p.stderr.read()
    data = read_csv(out) if out.suffix == ".csv" else read_table(out)
    assert len(data) == 2001
    x0 = data["integrator.x"][0]
    assert x0 in (1.0, 2.0)
    np.testing.assert_allclose(data["integrator.x"], x0 * (1 - 2.0 * H) ** np.arange(2001), rtol=1e-12)
    assert json.loads((tmp_path / "results" / f"{name}.json").read_text())["status"] == "complete"
    assert sorted(p.name for p in out.parent.iterdir()) == [name, f"{name}.json"]


def test_timeout_stops_a_long_run_at_a_communication_point(test_fmus, tmp_path):
    """A run slower than --timeout (every step returns): stopped at the next communication point,
    exit 1, one line, the rows kept are every row computed."""
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=10000.0, step=H)
    csv = tmp_path / "r.csv"
    r = orchestrate("run", str(ssp), "--output", str(csv), "--no-plot", "--timeout", "1", tmp=tmp_path)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    data = read_csv(csv)
    n = len(data)
    assert len(lines) == 1 and lines[0].startswith("orchestrate: error: wall-clock limit of 1 s (--timeout) "
                                                   f"reached at t={(n - 1) * H:.3f} s"), lines
    assert lines[0].endswith(f"; {n} rows kept in {csv}")
    # a fast machine reaches subnormal x (below 2.2e-308), whose few bits rtol cannot describe
    np.testing.assert_allclose(data["integrator.x"], (1 - 2.0 * H) ** np.arange(n), rtol=1e-12, atol=1e-300)
