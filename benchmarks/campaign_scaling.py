# SPDX-License-Identifier: BSD-2-Clause
"""Campaign throughput: runs per minute with 1 and 2 workers on the embedded Dask cluster, 2 workers
as threads of one process, and 2 workers behind an external ``dask scheduler``; and the per-run
overhead of the campaign layer against a bare ``orchestrator.run`` measured in this process.

    python benchmarks/campaign_scaling.py [--scenario build/ssp/example1.ssp] [--stop-time 30] [--runs 8]

Throughput counts from the first task submitted to the last row written (cluster start-up is
reported apart). Overhead per run, with 1 worker: run phase / runs minus the time each run spent
inside ``orchestrator.run`` on the worker (both measured in the same minutes, so a load from other
work on the machine cancels), and against the bare run measured here.

Parallel efficiency, apart from the machine's load: the CPU the workers spent (user + system of
the worker processes: for the embedded cluster read from this process's reaped children, the
workers' start-up and shut-down included, over the campaign's whole wall time; for the external
cluster read on its workers before and after the campaign, over the campaign's wall time) per
run, and that CPU over the wall time times the workers (1.0: every worker busy all the time). On
a loaded machine runs per minute fall, CPU per run does not: a regression shows in CPU per run; a
busy machine shows in the efficiency alone.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import orchestrator
from orchestrator import RunOptions
from orchestrator.campaign import read_design, read_table, sweep
from orchestrator.experiments.campaigns import TRACKING

VENV_BIN = Path(sys.executable).parent


@contextmanager
def external_cluster(folder: Path, workers: int) -> Iterator[str]:
    """A ``dask scheduler`` and ``workers`` single-threaded ``dask worker`` processes on localhost."""
    dask = str(VENV_BIN / "dask")
    file = folder / "scheduler.json"
    log = open(folder / "dask.log", "w")  # noqa: SIM115 (closed below)
    procs = [
        subprocess.Popen(
            [
                dask,
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(file),
            ],
            stdout=log,
            stderr=log,
        )
    ]
    try:
        address = ""
        while not address:  # the file appears before its JSON does
            try:
                address = json.loads(file.read_text())["address"]
            except (OSError, ValueError, KeyError):
                if procs[0].poll() is not None:
                    raise SystemExit(f"the scheduler ended: see {folder / 'dask.log'}") from None
                time.sleep(0.2)
        procs += [
            subprocess.Popen(
                [
                    dask,
                    "worker",
                    address,
                    "--nthreads",
                    "1",
                    "--no-dashboard",
                    "--local-directory",
                    str(folder / f"w{i}"),
                ],
                stdout=log,
                stderr=log,
            )
            for i in range(workers)
        ]
        from distributed import Client

        with Client(address) as client:
            client.wait_for_workers(workers, timeout=120)
        yield address
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)
        log.close()


def children_cpu() -> float:
    """CPU seconds (user + system) of this process's children that have ended and been reaped."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def workers_cpu(address: str) -> float:
    """User + system CPU seconds the worker processes of the cluster at ``address`` have spent so
    far (``os.times`` run on each worker)."""
    from distributed import Client

    with Client(address) as client:
        times = client.run(os.times)
    return sum(t[0] + t[1] for t in times.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", type=Path, help="default: build example1_no_fault into a temp folder")
    parser.add_argument("--stop-time", type=float, default=30.0)
    parser.add_argument("--runs", type=int, default=8)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="campaign-bench-") as tmp:
        tmp = Path(tmp)
        scenario = args.scenario
        if scenario is None:
            from orchestrator.experiments.scenarios import build_scenarios

            scenario = build_scenarios(["example1_no_fault"], tmp / "build")["example1_no_fault"]
        values = [round(-1 + 2 * i / max(args.runs - 1, 1), 6) for i in range(args.runs)]
        (tmp / "design.json").write_text(
            json.dumps({"stop_time": args.stop_time, "grid": {"plant.x1_0": values}})
        )
        design = read_design(tmp / "design.json")

        print(f"load average before: {os.getloadavg()[0]:.2f} (2 cores; other work shares them)")
        bare = []
        for x in values[:3]:
            started = time.perf_counter()
            orchestrator.run(scenario, RunOptions(stop_time=args.stop_time, overrides={"plant.x1_0": x}))
            bare.append(time.perf_counter() - started)
        t_bare = statistics.median(bare)
        print(f"bare orchestrator.run, {args.stop_time:g} s: {t_bare:.3f} s (median of {len(bare)})")

        results = {}
        cases = [
            ("embedded, 1 worker process", {"workers": 1}),
            ("embedded, 2 worker processes", {"workers": 2}),
            ("embedded, 2 worker threads in one process", {"workers": 2, "processes": False}),
        ]
        cpu: dict[str, float] = {}
        for label, options in cases:
            before = children_cpu()
            try:
                s = sweep(
                    [scenario],
                    design,
                    tmp / label.replace(" ", "_"),
                    metrics=TRACKING,
                    progress=False,
                    **options,
                )
            except Exception as exc:  # the threads case may not survive: report it
                print(f"{label}: failed ({type(exc).__name__}: {exc})")
                continue
            results[label] = s
            cpu[label] = children_cpu() - before
        with external_cluster(tmp, 2) as address:
            start = workers_cpu(address)  # the cluster is up: its start-up is not the campaign's
            results["external scheduler, 2 workers"] = sweep(
                [scenario], design, tmp / "external", metrics=TRACKING, scheduler=address, progress=False
            )
            cpu["external scheduler, 2 workers"] = workers_cpu(address) - start
        for label, s in results.items():
            rate = 60 * args.runs / s.run_time
            print(
                f"{label}: {rate:.1f} runs/min ({s.ok}/{s.total} ok; run phase {s.run_time:.1f} s, "
                f"start-up and shut-down {s.wall_time - s.run_time:.1f} s)"
            )
            if "threads" not in label:  # the threads run in this process: no child's CPU to read
                workers = 1 if "1 worker" in label else 2
                efficiency = cpu[label] / (s.wall_time * workers)
                print(f"    workers' CPU {cpu[label] / args.runs:.3f} s per run; efficiency {efficiency:.2f} "
                      f"(workers' CPU / (wall x {workers} workers))")
        one = results["embedded, 1 worker process"]
        rows, _ = read_table(one.parquet)
        in_worker = statistics.mean(r["wall_time"] for r in rows)
        per_run = one.run_time / args.runs
        print(
            f"1 worker: {per_run:.3f} s per run in the campaign, of which {in_worker:.3f} s inside "
            f"orchestrator.run on the worker (bare run here: {t_bare:.3f} s)"
        )
        overhead = per_run - in_worker
        print(
            f"per-run overhead of the campaign layer (dispatch, transfer, table): {overhead * 1e3:.0f} ms "
            f"= {100 * overhead / t_bare:.2f} % of a bare {args.stop_time:g} s run; "
            f"against the bare run: {100 * (per_run - t_bare) / t_bare:+.1f} %"
        )
        print(f"load average after: {os.getloadavg()[0]:.2f}")
        two = results.get("embedded, 2 worker processes")
        if two is not None:
            print(
                f"scaling 1 -> 2 worker processes: {one.run_time / two.run_time:.2f}x "
                f"({100 * (one.run_time / two.run_time - 1):.0f} % per added core)"
            )


if __name__ == "__main__":
    main()
