# SPDX-License-Identifier: BSD-2-Clause
"""How late ``orchestrate`` serves Ctrl-C and how much memory it takes for large files (issue 44).

    python benchmarks/orchestrate_limits.py interrupt [--copies 50] [--master jacobi] [--before COMMIT]
    python benchmarks/orchestrate_limits.py input-file [--mib 250] [--before COMMIT]
    python benchmarks/orchestrate_limits.py compare [--rows 1000000] [--columns 8]
        [--grids same|different] [--before COMMIT]

* ``interrupt``: example1's loop ``--copies`` times in one system (4 components each: 50 copies are
  200 components, ``build/ssp/example1.ssp``, run ``make build`` first), ``orchestrate run`` for
  ever; one real SIGINT per process, sent ``--delays`` seconds after the start (spanning
  unpacking, instantiating, initializing and the first steps); how long until the process has
  ended (wall time: the machine may be loaded; the worst of the delays is the figure).
* ``input-file``: a ``--mib`` MiB input file (time and 3 inputs of a lone Actuator, 18 significant
  digits) driving a run of 10 steps: the peak resident size of ``orchestrate run``.
* ``compare``: two result CSVs of ``--rows`` rows and ``--columns`` signals (the second within the
  first's tubes), on the same uniform grid or (``--grids different``) the result's times halfway
  between the baseline's (interpolated): the peak resident size of ``orchestrate compare``, and
  for 1/10 of the rows (beyond a chunk of 65,536 rows), to show what grows with them.

Peak resident sizes are each process's own: its ``VmHWM`` (``/proc/<pid>/status``, the high-water
mark of the process's own memory, reset at exec), read every millisecond until it ends by a small
parent (a fresh interpreter without site packages that only spawns, reads and waits), never a
child of this larger process; ``ru_maxrss`` from ``wait4`` is printed beside it. With ``--before
COMMIT`` the same is measured for that commit's ``orchestrator`` package (``git archive``, put
first on ``PYTHONPATH``, this checkout's ``.venv``), in alternation.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PYTHON = REPO / ".venv" / "bin" / "python"
# the small parent: spawn argv[1:], read its VmHWM every millisecond until it ends, print its exit
# status, the last VmHWM and ru_maxrss (KiB)
WAITER = """
import os, sys, time
pid = os.posix_spawnp(sys.argv[1], sys.argv[1:], os.environ)
hwm = 0
while True:
    try:
        with open(f"/proc/{pid}/status") as f:
            hwm = max([hwm] + [int(line.split()[1]) for line in f if line.startswith("VmHWM:")])
    except OSError:
        pass
    done, status, usage = os.wait4(pid, os.WNOHANG)
    if done:
        break
    time.sleep(0.001)
print(os.waitstatus_to_exitcode(status), hwm, usage.ru_maxrss, file=sys.stderr)
"""
INPUT_FMU = "Actuator.fmu"
INPUTS = ("v", "x1", "x2")


def orchestrate(before: Path | None) -> tuple[list[str], dict[str, str]]:
    """The command that runs ``orchestrate`` of this checkout or of ``before`` (an exported tree)."""
    env = dict(os.environ)
    if before is not None:
        env["PYTHONPATH"] = str(before)
    return [str(PYTHON), "-P", "-m", "orchestrator"], env


def export(commit: str, dest: Path) -> Path:
    """The tree of ``commit`` (its ``orchestrator`` package and the rest) under ``dest``."""
    archive = subprocess.run(["git", "-C", str(REPO), "archive", commit], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    return dest


def peak(command: Sequence[str], env: dict[str, str]) -> tuple[int, float, float]:
    """Exit status, peak resident size (VmHWM) and ru_maxrss (MiB) of ``command``, spawned by a small
    parent."""
    r = subprocess.run([sys.executable, "-S", "-c", WAITER, *command], env=env, stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE, text=True)
    status, hwm, maxrss = r.stderr.splitlines()[-1].split()
    return int(status), int(hwm) / 1024, int(maxrss) / 1024


# -- interrupt ----------------------------------------------------------------------------------------
def interrupt_latency(command: list[str], env: dict[str, str], archive: Path, master: str, delay: float,
                      out: Path) -> tuple[float, str]:
    """Seconds from a SIGINT ``delay`` s after the start of a run of ``archive`` to its end; its last line."""
    process = subprocess.Popen([*command, "run", str(archive), "--master", master, "--stop-time", "1e5",
                                "--no-plot", "--output", str(out)], env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    sent = time.monotonic()
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate()
    return time.monotonic() - sent, (stderr.strip().splitlines() or [""])[-1]


def interrupt(args: argparse.Namespace, builds: dict[str, Path | None], tmp: Path) -> None:
    sys.path.insert(0, str(REPO / "benchmarks"))
    from many_copies import copies

    source = REPO / "build" / "ssp" / "example1.ssp"
    if not source.is_file():
        raise SystemExit(f"{source} does not exist: run 'make build' first")
    archive = copies(source, args.copies, tmp)
    print(f"example1 x {args.copies} ({4 * args.copies} components), --master {args.master}: seconds from "
          "SIGINT to the end of the process")
    worst = dict.fromkeys(builds, 0.0)
    for delay in args.delays:
        for who, before in builds.items():
            command, env = orchestrate(before)
            seconds, line = interrupt_latency(command, env, archive, args.master, delay, tmp / "r.csv")
            worst[who] = max(worst[who], seconds)
            text = line.split(": ", 1)[-1][:70]
            print(f"  {who:7s} SIGINT at {delay:4.1f} s: {seconds:6.2f} s  ({text})")
    print("worst: " + ", ".join(f"{who} {s:.2f} s" for who, s in worst.items()))


# -- input-file ---------------------------------------------------------------------------------------
MAKE_INPUT = """
import sys
from pathlib import Path
import numpy as np
from orchestrator.ssp import Experiment, SystemStructure, component, pack_ssp, write_ssd
folder, fmu, mib = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
actuator = component("actuator", "Actuator.fmu", [("v", "input", "Real"), ("x1", "input", "Real"),
                                                 ("x2", "input", "Real"), ("uf", "output", "Real")])
write_ssd(folder / "one", SystemStructure("one", (actuator,), (), Experiment(0.0, 0.01, 0.001)))
pack_ssp(folder / "one", {"Actuator.fmu": fmu}, folder / "one.ssp")
rng = np.random.default_rng(44)
with open(folder / "u.csv", "w") as f:
    f.write("time,actuator.v,actuator.x1,actuator.x2\\n")
    row = 0
    while f.tell() < mib << 20:
        block = rng.standard_normal((100_000, 4))
        block[:, 0] = (row + np.arange(100_000)) * 1e-5
        row += 100_000
        f.write("\\n".join(",".join(repr(float(x)) for x in r) for r in block) + "\\n")
"""


def input_file(args: argparse.Namespace, builds: dict[str, Path | None], tmp: Path) -> None:
    fmu = REPO / "build" / "fmus" / INPUT_FMU
    if not fmu.is_file():
        raise SystemExit(f"{fmu} does not exist: run 'make build' first")
    subprocess.run([str(PYTHON), "-c", MAKE_INPUT, str(tmp), str(fmu), str(args.mib)], check=True)
    size = (tmp / "u.csv").stat().st_size / (1 << 20)
    print(f"--input-file of {size:.0f} MiB (4 columns), a run of 10 steps: peak resident size of the process")
    run = [str(tmp / "one.ssp"), "--no-plot", "--output", str(tmp / "r.csv")]
    for who, before in builds.items():
        command, env = orchestrate(before)
        status, mib, maxrss = peak([*command, "run", *run, "--input-file", str(tmp / "u.csv")], env)
        _, alone, _ = peak([*command, "run", *run], env)
        print(f"  {who:7s} {mib:7.0f} MiB ({mib / size:.2f} x the file; without it {alone:.0f} MiB; "
              f"ru_maxrss {maxrss:.0f} MiB), exit status {status}")


# -- compare ------------------------------------------------------------------------------------------
MAKE_COMPARED = """
import sys
import numpy as np
folder, rows, columns, grids = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
rng = np.random.default_rng(44)
for name, wobble in (("baseline.csv", 0.0), ("result.csv", 1e-6)):
    t = np.arange(rows) * 1e-3
    if name == "result.csv" and grids == "different":  # halfway between the baseline's, same span
        t[1:-1] += 0.5e-3
    with open(f"{folder}/{name}", "w") as f:
        f.write(",".join(["time", *(f"plant.x{i}" for i in range(columns))]) + "\\n")
        for s in range(0, rows, 100_000):
            u = t[s:s + 100_000]
            block = [u, *(np.sin(u * (i + 1)) + wobble * rng.standard_normal(len(u)) for i in range(columns))]
            f.write("\\n".join(",".join(map(repr, r)) for r in np.column_stack(block).tolist()) + "\\n")
"""


def compare(args: argparse.Namespace, builds: dict[str, Path | None], tmp: Path) -> None:
    print(f"orchestrate compare of two CSVs of {args.columns} signals, grids {args.grids}: peak resident "
          "size of the process (VmHWM)")
    for rows in (args.rows // 10, args.rows):
        made = [str(PYTHON), "-c", MAKE_COMPARED, str(tmp), str(rows), str(args.columns), args.grids]
        subprocess.run(made, check=True)
        size = (tmp / "result.csv").stat().st_size / (1 << 20)
        for who, before in builds.items():
            command, env = orchestrate(before)
            files = [str(tmp / "result.csv"), str(tmp / "baseline.csv")]
            status, mib, maxrss = peak([*command, "compare", *files], env)
            print(f"  {who:7s} {rows:>9d} rows ({size:4.0f} MiB each): {mib:5.0f} MiB "
                  f"(ru_maxrss {maxrss:.0f} MiB), exit status {status}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("interrupt")
    p.add_argument("--copies", type=int, default=50)
    p.add_argument("--master", default="jacobi")
    p.add_argument("--delays", type=float, nargs="+", default=[1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0])
    p = sub.add_parser("input-file")
    p.add_argument("--mib", type=int, default=250)
    p = sub.add_parser("compare")
    p.add_argument("--rows", type=int, default=1_000_000)
    p.add_argument("--columns", type=int, default=8)
    p.add_argument("--grids", choices=("same", "different"), default="same")
    for p in sub.choices.values():
        p.add_argument("--before", metavar="COMMIT")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        builds: dict[str, Path | None] = {"now": None}
        if args.before:
            builds["before"] = export(args.before, Path(tempfile.mkdtemp(prefix="before.", dir=tmp)))
        {"interrupt": interrupt, "input-file": input_file, "compare": compare}[args.what](args, builds, tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
