# SPDX-License-Identifier: BSD-2-Clause
"""Wall time of the set-up and of the test suite on fresh clones of two revisions, measured back to
back in one run (issue 14: the restructured suite against the one before it).

    python benchmarks/suite_time.py [--before 1b18f86] [--after HEAD] [--keep DIR]

Each revision is cloned (``git clone`` of this repository, then ``git checkout``) into a
folder beside this checkout (so that ``../shared`` resolves as it does here and in CI).
There, as ``.ci/run`` does, with no stdin: ``make build`` (the set-up: a new ``.venv``, the FMU
build, the scenarios), then ``make test`` (with the build up to date: the suite alone).

The later suite holds tests the earlier one did not have (the conformance matrix of issue 8,
the faults of issue 13, ...), so both suites are also run on their common tests only: the tests
of the earlier revision that the later one still has, under the same id or, when their file was
renamed, under the only id with the same test name. Each side runs them with its own
``make test`` pytest command (``make -n test``). Prints the wall times, pytest's summary lines
and the ratios.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BEFORE = "1b18f86"  # the last commit before issue 14's restructuring of the tests


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


def measure(revision: str, parent: Path) -> tuple[Path, list[Timing]]:
    """Clone ``revision`` beside this checkout (``<parent>-<revision>``, so that ``../shared`` is
    the same folder); time the set-up and the suite there."""
    clone = parent.with_name(f"{parent.name}-{revision}")
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "--quiet", revision], check=True)
    return clone, [timed(f"{revision} make build (set-up)", ["make", "build"], clone),
                   timed(f"{revision} make test", ["make", "test"], clone)]


def test_ids(clone: Path) -> list[str]:
    """The node ids of a clone's suite (``pytest --collect-only -q``)."""
    listed = subprocess.run([str(clone / ".venv" / "bin" / "python"), "-m", "pytest", "--collect-only", "-q",
                             "-p", "no:cacheprovider"], cwd=clone, capture_output=True, text=True, check=True)
    return [line for line in listed.stdout.splitlines() if line.startswith("tests/") and "::" in line]


def common_tests(old: list[str], new: list[str]) -> tuple[list[str], list[str]]:
    """The old ids the new suite still has (same id, or the only new id of the same test name in
    another file) and their new ids, in the same order."""
    present = set(new)
    by_name: dict[str, list[str]] = {}
    for node in new:
        by_name.setdefault(node.split("::", 1)[1], []).append(node)
    pairs = []
    for node in old:
        same_name = by_name.get(node.split("::", 1)[1], [])
        if node in present:
            pairs.append((node, node))
        elif len(same_name) == 1:
            pairs.append((node, same_name[0]))
    return [a for a, _ in pairs], [b for _, b in pairs]


def pytest_command(clone: Path) -> list[str]:
    """The pytest command of the clone's ``make test`` (``make -n test``; the build is up to date)."""
    # The recipe line, e.g. "CROSSCHECK_OUTPUT=results/crosscheck .venv/bin/python -m pytest -q -n 2".
    lines = subprocess.run(["make", "-n", "test"], cwd=clone, capture_output=True, text=True,
                           check=True).stdout.splitlines()
    line = next(line for line in lines if "pytest" in line)
    return shlex.split(line)


def main(argv: list[str] | None = None) -> int:
    """Time both revisions, one after the other, and print the figures and their ratios."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", default=BEFORE)
    parser.add_argument("--after", default="HEAD")
    parser.add_argument("--keep", type=Path, help="keep the clones, named KEEP-<revision> (default: removed)")
    args = parser.parse_args(argv)
    after = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", args.after], check=True,
                           capture_output=True, text=True).stdout.strip()
    parent = args.keep or Path(tempfile.mkdtemp(prefix="suite-time-", dir=REPO.parent))
    parent.mkdir(parents=True, exist_ok=True)
    clones = [parent.with_name(f"{parent.name}-{r}") for r in (args.before, after)]
    try:
        old_clone, old = measure(args.before, parent)
        new_clone, new = measure(after, parent)
        old_ids, new_ids = common_tests(test_ids(old_clone), test_ids(new_clone))
        for clone, revision, ids, runs in ((old_clone, args.before, old_ids, old),
                                           (new_clone, after, new_ids, new)):
            # "env" takes the VAR=value words a make recipe may start with.
            runs.append(timed(f"{revision} its make test on the {len(ids)} common tests",
                              ["env", *pytest_command(clone), *ids], clone))
    finally:
        if args.keep is None:
            for folder in (parent, *clones):
                shutil.rmtree(folder, ignore_errors=True)
    print(f"fresh clones, back to back, finished {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
          f"(load average {os.getloadavg()[0]:.2f}):")
    for run in old + new:
        print(f"  {run.label:62s} {run.wall:7.1f} s  exit {run.status}  {run.summary}")
    for a, b in zip(old, new, strict=True):
        print(f"  ratio {after} / {args.before}, {a.label.split(' ', 1)[1]}: {b.wall / a.wall:.2f}")
    return max(run.status for run in old + new)


if __name__ == "__main__":
    raise SystemExit(main())
