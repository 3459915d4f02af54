"""Wall time of the set-up and of the test suite on fresh clones of two revisions, measured back to
back in one run (issue 14: the restructured suite against the one before it).

    python benchmarks/suite_time.py [--before 1b18f86] [--after HEAD] [--keep DIR]

Each revision is cloned (``git clone`` of this repository, then ``git checkout``) into a
temporary folder beside this checkout (so that ``../shared`` resolves as it does here and in CI).
There, as ``.ci/run`` does, with no stdin: ``make build`` (the set-up: a new ``.venv``, the FMU
build, the scenarios), then ``make test`` (with the build up to date: the suite alone). The later
revision's suite runs twice: whole, and without the test of the conformance matrix
(``tests/test_crosscheck_system.py``: every scenario in six other SSP tools, added after
1b18f86 by issue 8), so that the same tests can be compared. Prints the wall times, pytest's
summary lines and the ratios.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BEFORE = "1b18f86"  # the last commit before issue 14's restructuring of the tests
MATRIX_TEST = "tests/test_crosscheck_system.py"


@dataclass
class Timing:
    """One timed command in one clone."""

    label: str
    wall: float
    status: int
    summary: str


def timed(label: str, command: list[str], clone: Path, addopts: str = "") -> Timing:
    """Run ``command`` in ``clone`` as CI would and time it (wall clock)."""
    env = dict(os.environ, CI="true", PYTEST_ADDOPTS=addopts)
    start = time.monotonic()
    done = subprocess.run(command, cwd=clone, env=env, stdin=subprocess.DEVNULL, capture_output=True,
                          text=True)
    wall = time.monotonic() - start
    lines = (done.stdout + done.stderr).splitlines()
    summary = next((line.strip("= ") for line in reversed(lines) if re.search(r"\d+ (passed|failed)", line)),
                   lines[-1] if lines else "")
    return Timing(label, wall, done.returncode, summary)


def measure(revision: str, parent: Path, without_matrix: bool) -> list[Timing]:
    """Clone ``revision`` into ``parent``; time the set-up and the suite there."""
    clone = parent / f"suite-{revision}"
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", revision], check=True)
    runs = [timed(f"{revision} make build (set-up)", ["make", "build"], clone),
            timed(f"{revision} make test", ["make", "test"], clone)]
    if without_matrix:
        runs.append(timed(f"{revision} make test without {MATRIX_TEST}", ["make", "test"], clone,
                          f"--ignore={MATRIX_TEST}"))
    return runs


def main(argv: list[str] | None = None) -> int:
    """Time both revisions, one after the other, and print the figures and their ratios."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", default=BEFORE)
    parser.add_argument("--after", default="HEAD")
    parser.add_argument("--keep", type=Path, help="keep the clones in this folder (default: removed)")
    args = parser.parse_args(argv)
    after = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", args.after], check=True,
                           capture_output=True, text=True).stdout.strip()
    parent = args.keep or Path(tempfile.mkdtemp(prefix="suite-time-", dir=REPO.parent))
    parent.mkdir(parents=True, exist_ok=True)
    try:
        old = measure(args.before, parent, without_matrix=False)
        new = measure(after, parent, without_matrix=True)
    finally:
        if args.keep is None:
            shutil.rmtree(parent, ignore_errors=True)
    print(f"fresh clones, back to back, finished {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
          f"(load average {os.getloadavg()[0]:.2f}):")
    for run in old + new:
        print(f"  {run.label:62s} {run.wall:7.1f} s  exit {run.status}  {run.summary}")
    base = old[1].wall
    for run in new[1:]:
        print(f"  ratio ({run.label}) / ({old[1].label}): {run.wall / base:.2f}")
    print(f"  set-up ratio: {new[0].wall / old[0].wall:.2f}")
    return max(run.status for run in old + new)


if __name__ == "__main__":
    raise SystemExit(main())
