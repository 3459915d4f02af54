# SPDX-License-Identifier: BSD-2-Clause
"""Campaigns end to end (issue 9): ``orchestrate sweep`` on the embedded Dask cluster and through a
real external ``dask scheduler`` with two ``dask worker`` processes, a failing variant kept as a row,
a timeout, resume, and Ctrl-C keeping every finished row.

Oracles: every row's metrics against a bare ``orchestrator.run`` of the same variant in this
process with SPEC section 4's metrics (no Dask, no campaign layer); the FMU's own parameter check
for the failing variant; the embedded cluster's table for the external one.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from orch_helpers import DaskCluster

import orchestrator
from orchestrator import RunOptions
from orchestrator.campaign.table import read_rows
from orchestrator.cli import main
from orchestrator.experiments.metrics import tracking_metrics

pytestmark = pytest.mark.system

VENV_BIN = Path(sys.executable).parent
STOP = 0.3
GRID = {"plant.x1_0": [-1.0, 1.5], "controller.mode": [0, 1]}


def design(folder: Path, grid: dict, name: str = "design.json", **extra: object) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(json.dumps({"stop_time": STOP, "grid": grid, **extra}), encoding="utf-8")
    return path


def as_text(rows: list[dict], drop: tuple[str, ...] = ()) -> str:
    """Rows as JSON text, so NaN compares equal to NaN (and None stays apart from it)."""
    return json.dumps([{k: v for k, v in r.items() if k not in drop} for r in rows])


@pytest.fixture(scope="module")
def scenario(built: Path) -> Path:
    return built / "ssp" / "example1_no_fault.ssp"


@pytest.fixture(scope="module")
def embedded(scenario: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The small grid on the embedded cluster (2 worker processes), trajectories every 10th row."""
    folder = tmp_path_factory.mktemp("embedded")
    heatmap = {"kind": "heatmap", "x": "plant.x1_0", "y": "controller.mode", "metric": "settling_time"}
    path = design(folder, GRID, plots=[heatmap])
    assert (
        main(
            [
                "sweep",
                str(scenario),
                "--design",
                str(path),
                "--out",
                str(folder / "out"),
                "--quiet",
                "--workers",
                "2",
                "--keep-trajectories",
                "--trajectory-every",
                "10",
            ]
        )
        == 0
    )
    return folder / "out"


def test_embedded_grid_matches_bare_runs(embedded: Path, scenario: Path) -> None:
    header, rows = read_rows(embedded / "runs.csv")
    assert [r["run"] for r in rows] == [0, 1, 2, 3]
    assert [(r["plant.x1_0"], r["controller.mode"]) for r in rows] == [(-1, 0), (-1, 1), (1.5, 0), (1.5, 1)]
    assert as_text(pq.read_table(embedded / "runs.parquet").to_pylist()) == as_text(rows)  # CSV = Parquet
    for row in rows:
        assert row["status"] == "ok" and row["reason"] == "" and row["wall_time"] > 0
        overrides = {"plant.x1_0": row["plant.x1_0"], "controller.mode": int(row["controller.mode"])}
        bare = orchestrator.run(scenario, RunOptions(stop_time=STOP, overrides=overrides)).rows
        m = tracking_metrics(
            bare["time"],
            bare["plant.y"],
            bare["reference.yd"],
            bare["controller.v"],
            bare["actuator.uf"],
            band=0.05,
        )
        assert (row["rae"], row["mse"], row["mae"], row["settling_time"], row["peak_v"]) == (
            m.rae,
            m.mse,
            m.mae,
            m.settling_time,
            m.peak_v,
        )
        assert row["final_error"] == abs(bare["plant.y"][-1] - bare["reference.yd"][-1])
        assert math.isnan(row["mae_after_fault"])  # no actuator.t_fault among the parameters
        trajectory = pq.read_table(next((embedded / "trajectories").glob(f"run-{row['run']:05d}-*.parquet")))
        assert trajectory.column("time").to_pylist() == bare["time"][::10].tolist()
        assert trajectory.column("plant.y").to_pylist() == bare["plant.y"][::10].tolist()
        assert trajectory.column("plant.y")[0].as_py() == row["plant.x1_0"]  # the variant reached the plant


def test_report_names_the_worst_runs(embedded: Path, tmp_path: Path) -> None:
    assert main(["campaign-report", str(embedded / "runs.parquet"), "--out", str(tmp_path)]) == 0
    summary = (tmp_path / "summary.md").read_text(encoding="utf-8")
    _, rows = read_rows(embedded / "runs.csv")
    slowest = max(rows, key=lambda r: r["settling_time"])
    assert "4 of 4 runs in the table: 4 ok, 0 failed, 0 timed out" in summary
    worst_table = summary.split("## Worst runs by settling_time")[1]
    assert worst_table.split("\n")[4].startswith(f"| {slowest['run']} | example1_no_fault |")
    assert list(tmp_path.glob("*.png"))


@pytest.fixture
def external_cluster(tmp_path: Path) -> Iterator[str]:
    """A real ``dask scheduler`` and two ``dask worker`` processes on localhost (free ports), torn
    down afterwards."""
    cluster = DaskCluster(tmp_path, 2)
    try:
        yield cluster.address
    finally:
        cluster.stop()


def test_external_scheduler_gives_the_same_table(
    embedded: Path, scenario: Path, external_cluster: str, tmp_path: Path
) -> None:
    path = design(tmp_path, GRID)
    env = {**os.environ, "ORCHESTRATE_SCHEDULER": external_cluster}
    done = subprocess.run(
        [
            str(VENV_BIN / "orchestrate"),
            "sweep",
            str(scenario),
            "--design",
            str(path),
            "--out",
            str(tmp_path / "out"),
        ],  # not --quiet (issue 36: it silences the summary too); no progress bar off a terminal
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "on 2 workers" in done.stdout
    _, ours = read_rows(tmp_path / "out" / "runs.csv")
    _, reference = read_rows(embedded / "runs.csv")
    assert as_text(ours, drop=("wall_time",)) == as_text(reference, drop=("wall_time",))


def test_failing_variant_is_a_row_and_the_rest_finish(scenario: Path, tmp_path: Path) -> None:
    # k1 = 0: inside the FMU's declared range (the finite-time law has k = 0), refused by the FMU's
    # own check of the fixed-time law (mode 0); beta = 1.0 did it before issue 36 refused it up front
    path = design(tmp_path, {"controller.k1": [10.0, 0.0], "plant.x1_0": [0.0, 1.0]})
    assert (
        main(
            [
                "sweep",
                str(scenario),
                "--design",
                str(path),
                "--out",
                str(tmp_path / "out"),
                "--quiet",
                "--workers",
                "2",
            ]
        )
        == 1
    )
    _, rows = read_rows(tmp_path / "out" / "runs.csv")
    assert len(rows) == 4
    for row in rows:
        if row["controller.k1"] == 0.0:
            assert row["status"] == "failed" and row["rae"] is None
            assert row["reason"].startswith("controller: fmi2GetReal returned fmi2Fatal at t=0.000 s")
            assert "k1 must satisfy k1 > 0 (got 0.0)" in row["reason"]
        else:
            assert row["status"] == "ok" and row["reason"] == "" and row["rmse"] > 0


def test_timeout_is_a_row(scenario: Path, tmp_path: Path) -> None:
    path = design(tmp_path, {"plant.x1_0": [0.5]}, timeout=0.05)
    assert (
        main(
            [
                "sweep",
                str(scenario),
                "--design",
                str(path),
                "--out",
                str(tmp_path / "out"),
                "--quiet",
                "--workers",
                "1",
                "--stop-time",
                "5",
            ]
        )
        == 1
    )
    _, [row] = read_rows(tmp_path / "out" / "runs.csv")
    assert row["status"] == "timeout" and row["reason"].startswith(
        "wall-clock limit of 0.05 s (timeout) reached at t="  # the design's key: the API names its fields
    )
    assert row["stop_time"] == 5.0


def test_ctrl_c_keeps_finished_rows_and_resume_skips_them(scenario: Path, tmp_path: Path) -> None:
    values = [round(-2 + 0.25 * i, 2) for i in range(8)]
    path = design(tmp_path, {"plant.x1_0": values, "controller.mode": [0, 1]})
    out = tmp_path / "out"
    command = [
        str(VENV_BIN / "orchestrate"),
        "sweep",
        str(scenario),
        "--design",
        str(path),
        "--out",
        str(out),
        "--workers",
        "1",
    ]
    proc = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 90
        seen = 0
        while seen < 3 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
            if (out / "runs.csv").is_file():
                seen = len(read_rows(out / "runs.csv")[1])
        assert 3 <= seen < 16, "the campaign did not run, or ran too fast to interrupt"
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in a terminal goes to the whole process group
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "interrupted;" in stderr and "rerun with --resume" in stderr
    assert "Traceback" not in stderr  # the workers leave Ctrl-C to the client
    _, kept = read_rows(out / "runs.csv")
    assert seen <= len(kept) < 16
    assert all(r["status"] == "ok" for r in kept)
    assert pq.read_table(out / "runs.parquet").num_rows == len(kept)

    with pytest.raises(SystemExit) as usage:  # the table exists: neither --resume nor --force is an error
        main(["sweep", str(scenario), "--design", str(path), "--out", str(out), "--quiet"])
    assert usage.value.code == 2
    done = subprocess.run(command + ["--resume"], capture_output=True, text=True, timeout=120)  # a summary
    assert done.returncode == 0, done.stderr
    assert f"16 runs ({len(kept)} kept from before)" in done.stdout
    _, rows = read_rows(out / "runs.csv")
    assert [r["run"] for r in rows] == list(range(16))
    before = {r["run_id"]: r["wall_time"] for r in kept}
    assert all(r["wall_time"] == before[r["run_id"]] for r in rows if r["run_id"] in before)  # not rerun
