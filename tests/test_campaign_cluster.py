# SPDX-License-Identifier: BSD-2-Clause
"""Campaigns that survive their cluster (issue 20, item 5), on a real ``dask scheduler`` and real
``dask worker`` processes on localhost, killed with SIGKILL in the middle of a campaign.

Oracles: the campaign's own plan (every run index once, no duplicate row, every row ``ok``: the
loop scenario cannot fail), the scheduler's log of the worker it removed, the sockets the embedded
dashboard listens on, the bytes on the worker's disk against the archive's referenced members.
Each test failed on main: the runs the scheduler did not finish were written as ``failed``
(``--resume`` ran none of them), a lost worker was not reported, the dashboard listened on all
interfaces, and a worker extracted every member of the archive (``extractall``).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from orch_helpers import DaskCluster, loop_scenario, write_zip, zip_members

from orchestrator.campaign.plugin import ScenarioPlugin
from orchestrator.campaign.sweep import connect, sweep
from orchestrator.campaign.table import read_rows
from orchestrator.ssp import Limits

pytestmark = pytest.mark.system

VENV_BIN = Path(sys.executable).parent
RUNS = 12


def worker_process(nanny: subprocess.Popen) -> int:
    """The pid of the worker process a ``dask worker`` nanny started."""
    for entry in Path("/proc").iterdir():
        try:
            ppid = int(entry.joinpath("stat").read_text().rsplit(")", 1)[1].split()[1])
            if ppid == nanny.pid and b"spawn_main" in entry.joinpath("cmdline").read_bytes():
                return int(entry.name)
        except (OSError, ValueError, IndexError):
            continue
    raise AssertionError("no worker process")


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[DaskCluster]:
    started = DaskCluster(tmp_path, 2)
    try:
        yield started
    finally:
        started.stop()


@pytest.fixture(scope="module")
def scenario(test_fmus, tmp_path_factory) -> Path:
    """The loop scenario, 10 000 steps a run (about a second)."""
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, stop=100.0, step=0.01)


@pytest.fixture
def design(tmp_path: Path) -> Path:
    path = tmp_path / "design.json"
    path.write_text(json.dumps({"grid": {"gain.k": [-0.5 - 0.1 * i for i in range(RUNS)]}}))
    return path


def _when_rows(table: Path, rows: int, action) -> threading.Thread:
    """Call ``action`` once ``table`` holds ``rows`` rows (in a thread, while the sweep runs)."""
    def watch() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if table.is_file() and len(table.read_text().splitlines()) > rows:
                action()
                return
            time.sleep(0.05)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def _indices(table: Path) -> list[int]:
    _, rows = read_rows(table)
    assert all(r["status"] == "ok" for r in rows), rows
    return sorted(int(r["run"]) for r in rows)


def test_runs_the_dead_scheduler_did_not_finish_are_not_run_and_resume_finishes_them(
        cluster, scenario, design, tmp_path):
    out = tmp_path / "out"
    watcher = _when_rows(out / "runs.csv", 2, lambda: cluster.scheduler.send_signal(signal.SIGKILL))
    summary = sweep([scenario], design, out, scheduler=cluster.address, progress=False)
    watcher.join()
    assert summary.not_run > 0 and summary.failed == 0
    assert "scheduler-connection-lost" in summary.not_run_reason
    first = _indices(out / "runs.csv")
    assert len(first) == RUNS - summary.not_run and summary.ok == len(first)
    cluster.stop()
    (tmp_path / "again").mkdir()
    again = DaskCluster(tmp_path / "again", 1)
    try:
        resumed = sweep([scenario], design, out, scheduler=again.address, resume=True, progress=False)
    finally:
        again.stop()
    assert resumed.skipped == len(first) and resumed.ok == RUNS and resumed.not_run == 0
    assert _indices(out / "runs.csv") == list(range(RUNS))  # every run once: no duplicate row
    assert pq.read_table(out / "runs.parquet").num_rows == RUNS


def test_a_killed_worker_is_reported_with_the_runs_it_held(cluster, scenario, design, tmp_path):
    out = tmp_path / "out"
    victim = worker_process(cluster.workers[0])
    watcher = _when_rows(out / "runs.csv", 1, lambda: os.kill(victim, signal.SIGKILL))
    summary = sweep([scenario], design, out, scheduler=cluster.address, progress=False)
    watcher.join()
    assert summary.ok == RUNS and summary.not_run == 0 and _indices(out / "runs.csv") == list(range(RUNS))
    log = (tmp_path / "dask.log").read_text().splitlines()
    removed = [line for line in log if "Remove worker addr" in line]
    assert len(summary.lost_workers) == 1, (summary.lost_workers, removed)
    (worker, runs), = summary.lost_workers.items()
    assert any(worker in line for line in removed)
    assert runs and set(runs) <= set(range(RUNS))  # it was running one of them when it died


def test_the_embedded_dashboard_listens_on_localhost_only():
    """main: ':0', every interface (the dashboard lists every task and its arguments)."""
    with connect(workers=1, processes=False) as client:
        server = client.cluster.scheduler.http_server
        hosts = {sock.getsockname()[0] for sock in server._sockets.values()}
    assert hosts == {"127.0.0.1"}, hosts


def test_workers_unpack_only_what_the_ssd_references(scenario, tmp_path):
    """An archive with an unreferenced 64 MiB member of zeros (a 64 KiB zip bomb): a worker writes
    the SSD, the parameter files and the FMUs, about what the archive holds besides the bomb."""
    files = {**zip_members(scenario), "resources/bomb.bin": bytes(64 << 20)}
    data = write_zip(tmp_path / "bomb.ssp", files).read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    useful = sum(len(v) for k, v in files.items() if k != "resources/bomb.bin")

    def disk(dask_worker) -> int:
        return sum(f.stat().st_size for f in Path(dask_worker.local_directory).rglob("*") if f.is_file())

    with connect(workers=1, processes=False) as client:
        client.register_plugin(ScenarioPlugin({digest: data}, Limits()), name="bomb")
        (written,) = client.run(disk).values()
    assert written < useful + (1 << 20), (written, useful)
