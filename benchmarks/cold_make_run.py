# SPDX-License-Identifier: BSD-2-Clause
"""The README's first command, cold: CPU and wall of ``make run`` in a fresh clone (issue 42's
target: under 90 s of CPU on 2 cores once pip's downloads are cached), by phase.

Each phase is its own command in the clone, timed by this small parent with the CPU of its
children (``RUSAGE_CHILDREN``: user + system of every process the phase ran, compilers and pip
included). The phases: the set-up (``make .venv/.installed``: venv, pip, the launcher), the
build (``orchestrate build pendulum --platform linux64 --no-fmi3``: what ``make run`` builds,
the runtime's ``.deb`` files fetched into the clone), the run (``make run`` with everything
up to date), and ``make run`` once more. ``--rev`` measures another commit the same way (its
``make run`` in one piece: older Makefiles have no such phases); the pip cache is the user's.

Usage: ``python benchmarks/cold_make_run.py [--rev REV]``
"""

from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def timed(command: list[str], cwd: Path) -> tuple[float, float, int]:
    """Wall seconds, CPU seconds (user + system of its processes) and exit status of ``command``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        print(f"  ({' '.join(command)} exited {done.returncode}: {done.stderr.strip().splitlines()[-1:]})")
    return wall, cpu, done.returncode


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rev", default="HEAD", help="the commit to measure (default HEAD)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cold-make-run-") as tmp:
        clone = Path(tmp) / "clone"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(clone)], check=True)
        subprocess.run(["git", "checkout", "--quiet", args.rev], cwd=clone, check=True)
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=clone, capture_output=True,
                             text=True).stdout.strip()
        phased = "--platform linux64" in (clone / "Makefile").read_text()
        phases = ([("set-up (venv, pip, launcher)", ["make", ".venv/.installed"]),
                   ("build (4 FMUs linux64, 1 archive)",
                    [".venv/bin/orchestrate", "build", "pendulum", "--platform", "linux64", "--no-fmi3"]),
                   ("run (make run, built)", ["make", "run"])] if phased else
                  [("make run (one piece)", ["make", "run"])])
        phases.append(("make run again", ["make", "run"]))
        print(f"cold make run of {rev} in a fresh clone ({shutil.which('python3')}, pip cache warm)")
        total_wall = total_cpu = 0.0
        for number, (what, command) in enumerate(phases):
            wall, cpu, _ = timed(command, clone)
            if number < len(phases) - 1:
                total_wall, total_cpu = total_wall + wall, total_cpu + cpu
            print(f"  {what:36s} {wall:7.1f} s wall {cpu:7.1f} s CPU")
        print(f"  {'cold make run, all':36s} {total_wall:7.1f} s wall {total_cpu:7.1f} s CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
