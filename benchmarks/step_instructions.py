# SPDX-License-Identifier: BSD-2-Clause
"""Instructions per communication step, ``orchestrate run`` against libcosim, split by who runs them.

    python benchmarks/step_instructions.py [--scenarios example1 pendulum] [--steps 5000]

CPU seconds per step swing with the machine's load (``end_to_end.py`` measured example1's ratio
anywhere from 0.61 to 1.2 on this shared 2-core machine). Instructions do not:
``valgrind --tool=callgrind`` counts the same total for the same binary and inputs whatever else
runs, as long as nothing a process does per second enters the count (so the counted processes run
one at a time). For each built scenario (``build/ssp/<name>.ssp``, run ``make build`` first), both
hosts run the archive for ``--steps`` and for twice as many steps under callgrind:

* ours: ``python -m orchestrator run`` writing a CSV of two rows (``--output-interval`` the stop
  time: the rows not asked for are never formatted), the compiled executor;
* libcosim (libcosimpy) reading the archive's own algorithm with no observer, as
  ``end_to_end.py`` runs it.

Per step is ``(instructions of the longer run - of the shorter) / steps``: start-up cancels, but a
one-off event that falls in one run's extra steps and not in the other's (a collection of the
cyclic garbage collector, an arena allocated) does not, and where it falls moves with the process's
environment: at 1 000 steps example1's ours read 40 449 alone and 41 758 under ``make`` (its
variables in the environment), at 5 000 steps 40 725 and 40 760. Hence 5 000 by default. Each
ELF object's own instructions are summed from callgrind's output and put in one of four groups:
the interpreter (the FMUs' models in Python; for ours also the engine between blocks of steps),
the models' compiled extensions, the FMUs' binaries (the project's shim and pythonfmu's), and the
host (our executor, NumPy, ctypes/libffi; libcosim's library and the C++ runtime); libc and the
loader are shown apart. Both hosts load the same FMUs.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
from end_to_end import LIBCOSIM, as_a_user_runs, step_of  # noqa: E402 - the benchmarks share these

GROUPS = (
    ("interpreter (the models' Python)", re.compile(r"libpython")),
    ("the models' compiled extensions", re.compile(r"/resources/.*\.so$")),
    ("FMU binaries (shims, pythonfmu)", re.compile(r"/binaries/linux64/")),
    ("host (executor, NumPy, ctypes / libcosim, C++)",
     re.compile(r"executor|numpy|libffi|_ctypes|libcosim|libstdc\+\+|libgcc|libfmilib|libboost")),
    ("libc, loader, other", re.compile(r"")),
)


def object_costs(path: Path) -> Counter[str]:
    """Each ELF object's own instruction count (the ``Ir`` of its functions' lines, not of their
    calls) in the callgrind output ``path``."""
    names: dict[str, str] = {}
    costs: Counter[str] = Counter()
    current, after_call = "", False
    with path.open() as f:
        for line in f:
            if line.startswith(("ob=", "cob=")):
                match = re.match(r"c?ob=\((\d+)\)(?: (.*))?", line.strip())
                if match:
                    if match.group(2):
                        names[match.group(1)] = match.group(2)
                    if line.startswith("ob="):
                        current = names.get(match.group(1), "?")
            elif line.startswith("calls="):
                after_call = True  # the next cost line is the call's inclusive cost
            elif line[:1].isdigit() or line[:1] in "+-*":
                if after_call:
                    after_call = False
                    continue
                fields = line.split()
                if len(fields) >= 2:
                    costs[current] += int(fields[1])
    return costs


def grouped(costs: Counter[str]) -> dict[str, int]:
    """``costs`` summed into :data:`GROUPS` (the first whose pattern matches the object's path)."""
    out = dict.fromkeys((label for label, _ in GROUPS), 0)
    for name, cost in costs.items():
        label = next(label for label, pattern in GROUPS if pattern.search(name))
        out[label] += cost
    return out


def counted(commands: dict[str, list[str]], folder: Path) -> dict[str, Counter[str]]:
    """Each command run under callgrind, one after the other (after one run of each without it:
    the FMU caches filled, so that no counted run unpacks an FMU); their object costs. Run side by
    side, four processes on two cores stretched each run's wall time by the others', and what a
    process does per second rather than per step went into the difference of the two lengths:
    pendulum's ours read 45 982 and 47 838 instructions per step in two runs (commits apart, none
    changing the step); one at a time, 46 509."""
    env = {**os.environ, "PYTHONHASHSEED": "0"}  # the same hashes, so the same instructions, every run
    for command in commands.values():
        subprocess.run(command, stdout=subprocess.DEVNULL, check=True, cwd=folder, env=env)
    costs = {}
    for label, command in commands.items():
        out = folder / f"{label}.callgrind"
        counting = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *command]
        done = subprocess.run(counting, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              cwd=folder, env=env)
        if done.returncode != 0:
            raise SystemExit(f"{label}: exit status {done.returncode}\n{done.stderr[-2000:]}")
        costs[label] = object_costs(out)
    return costs


def measure(archive: Path, steps: int, folder: Path) -> dict[str, dict[str, float]]:
    """Per-step instructions by group for ``ours`` and ``libcosim``."""
    h = step_of(archive)
    lengths = {"short": steps * h, "long": 2 * steps * h}
    commands = {}
    for length, stop in lengths.items():
        commands[f"ours {length}"] = [sys.executable, "-m", "orchestrator", "run", str(archive), "--quiet",
                                      "--no-plot", "--stop-time", repr(stop), "--output-interval", repr(stop),
                                      "--output", str(folder / f"{length}.csv")]
        commands[f"libcosim {length}"] = [sys.executable, "-c", LIBCOSIM, str(archive), repr(stop), ""]
    costs = counted(commands, folder)
    per_step = {}
    for who in ("ours", "libcosim"):
        short, long = grouped(costs[f"{who} short"]), grouped(costs[f"{who} long"])
        per_step[who] = {label: (long[label] - short[label]) / steps for label in short}
    return per_step


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=["example1", "pendulum"])
    parser.add_argument("--steps", type=int, default=5000, help="steps of the shorter run (default 5000)")
    args = parser.parse_args(argv)
    as_a_user_runs()
    if shutil.which("valgrind") is None:
        raise SystemExit("valgrind is not installed (Debian: apt-get install valgrind)")
    for name in args.scenarios:
        archive = REPO / "build" / "ssp" / f"{name}.ssp"
        if not archive.is_file():
            raise SystemExit(f"{archive} does not exist: run 'make build' first")
        with tempfile.TemporaryDirectory() as tmp:
            figures = measure(archive, args.steps, Path(tmp))
        ours, theirs = sum(figures["ours"].values()), sum(figures["libcosim"].values())
        print(f"\n{name}: instructions per step ({args.steps} and {2 * args.steps} steps under callgrind)")
        print(f"  {'':48s} {'ours':>9s} {'libcosim':>9s}")
        for label, _ in GROUPS:
            print(f"  {label:48s} {figures['ours'][label]:9.0f} {figures['libcosim'][label]:9.0f}")
        print(f"  {'whole process':48s} {ours:9.0f} {theirs:9.0f}   ours / libcosim {ours / theirs:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
