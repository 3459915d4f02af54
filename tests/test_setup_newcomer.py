# SPDX-License-Identifier: BSD-2-Clause
"""The README's first command as a newcomer meets it (issue 42): ``make run`` in a fresh clone, as a
user without root, with only the machine's stock interpreter (``/usr/bin/python3``: Debian 12's
3.11.2) on ``PATH=/usr/bin:/bin`` and nothing else of this session's environment; then ``make
run`` again, which must reuse the build. Before: the first ``make run`` stopped at pip on Debian's
3.11.2 (a docs pin needing 3.11.5), and on any interpreter every ``make run`` exited 2 ('build/ssp/
pendulum.ssp is older than controller/_fmath.abi3.so'), while CI, which never ran it, was green.

Oracle: the commands' exit status, the second run's build lines, and the newcomer's result against
the checkout's run of its own full build of the same scenario, to the bit."""

from __future__ import annotations

import os
import pwd
import re
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv

from orchestrator.cli import main

pytestmark = pytest.mark.system

REPO = Path(__file__).resolve().parents[1]
STOCK = Path("/usr/bin/python3")
USER = "ftc-newcomer"
FMUSIM = REPO.parent / "shared" / "tools" / "fmusim" / "bin" / "fmusim"


def tour() -> tuple[list[list[str]], list[str]]:
    """The README's "30-second tour": its shell lines after ``make run`` (comments dropped), and the
    fmusim command it gives for the exported FMU."""
    text = (REPO / "README.md").read_text()
    section = text.split("## A 30-second tour", 1)[1]
    block = section.split("```sh\n", 1)[1].split("```", 1)[0]
    lines = [shlex.split(line, comments=True) for line in block.splitlines()]
    found = re.search(r"`(fmusim [^`]+)`", section)
    assert found, "the tour names an fmusim command"
    return [words for words in lines if words and words != ["make", "run"]], shlex.split(found.group(1))


def _the_tour(clone: Path, user: list[str]) -> None:
    """Each line of the README's tour, in order, as the newcomer types it after ``make run``
    (before: two of its lines ran example1, which ``make run`` does not build)."""
    commands, fmusim = tour()
    assert [words[0] for words in commands] == ["orchestrate"] * len(commands)
    for words in commands:
        done = subprocess.run([*user, str(clone / ".venv" / "bin" / "orchestrate"), *words[1:]], cwd=clone,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, f"{shlex.join(words)}:\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
    if FMUSIM.is_file():  # the exported loop, in the Modelica Association's importer, without Python
        done = subprocess.run([str(FMUSIM), *fmusim[1:-1], str(clone / fmusim[-1])], capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-2000:]


def _newcomer() -> tuple[list[str], str]:
    """The command prefix that runs as a user without root (created here when root may), and its
    home; skips with the reason where there is none."""
    if os.geteuid() != 0:
        return [], str(Path.home())
    try:
        entry = pwd.getpwnam(USER)
    except KeyError:
        if shutil.which("useradd") is None:
            pytest.skip("running as root without useradd: no user without root to run 'make run' as")
        subprocess.run(["useradd", "--create-home", "--shell", "/bin/sh", USER], check=True,
                       capture_output=True, timeout=60)
        entry = pwd.getpwnam(USER)
    runner = shutil.which("runuser") or shutil.which("setpriv")
    if runner is None:
        pytest.skip("no runuser or setpriv to run 'make run' as a user without root")
    if runner.endswith("runuser"):
        return [runner, "-u", USER, "--"], entry.pw_dir
    return [runner, f"--reuid={entry.pw_uid}", f"--regid={entry.pw_gid}", "--init-groups"], entry.pw_dir


def test_make_run_twice_in_a_fresh_clone_as_a_new_user_with_stock_python(built: Path, tmp_path: Path) -> None:
    if not STOCK.is_file():
        pytest.skip(f"no {STOCK} on this machine: the stock interpreter's run cannot be made")
    if shutil.which("git") is None or shutil.which("make") is None:
        pytest.skip("no git or make")
    prefix, home = _newcomer()
    where = Path(tempfile.mkdtemp(prefix="ftc-newcomer-", dir="/tmp"))  # the user's own, not root's 0700 tree
    try:
        clone = where / "fixed-time-cosim"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(clone)], check=True,
                       capture_output=True, timeout=300)
        if prefix:
            user = pwd.getpwnam(USER)
            for path in (where, *where.rglob("*")):
                os.lchown(path, user.pw_uid, user.pw_gid)
        environment = ["env", "-i", "PATH=/usr/bin:/bin", f"HOME={home}", "LANG=C.UTF-8"]
        logs = []
        for attempt in (1, 2):
            done = subprocess.run([*prefix, *environment, "make", "run"], cwd=clone, capture_output=True,
                                  text=True, timeout=1500)
            logs.append(done.stdout + done.stderr)
            (REPO / "results").mkdir(exist_ok=True)
            (REPO / "results" / f"newcomer-make-run-{attempt}.log").write_text(logs[-1])
            assert done.returncode == 0, f"make run #{attempt} failed:\n{logs[-1][-4000:]}"
        code = "import sys; print(sys._base_executable)"
        venv = clone / ".venv" / "bin" / "python"
        base = subprocess.run([venv, "-c", code], capture_output=True, text=True, timeout=60).stdout.strip()
        assert Path(base).resolve() == STOCK.resolve(), base  # the stock interpreter's venv
        # the second run built nothing: every FMU up to date, the archive reused
        assert "4 of 4 FMUs up to date" in logs[1] and ": built" not in logs[1], logs[1]
        assert (clone / "results" / "pendulum.png").is_file()
        _the_tour(clone, [*prefix, *environment])
        # the same numbers as the checkout's run of its own full build (linux64 and win64, FMI 3.0 too)
        ours = tmp_path / "pendulum.csv"
        argv = ["run", str(built / "ssp" / "pendulum.ssp"), "--quiet", "--no-plot", "--output", str(ours)]
        assert main(argv) == 0
        theirs = read_csv(clone / "results" / "pendulum.csv")
        mine = read_csv(ours)
        assert theirs.dtype.names == mine.dtype.names
        for name in mine.dtype.names:
            assert np.array_equal(theirs[name], mine[name]), name
    finally:
        shutil.rmtree(where, ignore_errors=True)
