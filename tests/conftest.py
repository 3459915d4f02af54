# SPDX-License-Identifier: BSD-2-Clause
"""Fixtures shared by the system tests: everything is built once per test process (xdist: once
per worker) and shared read-only."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path

import pytest
from orch_helpers import build_test_fmu

from orchestrator.cli import main

REPO = Path(__file__).resolve().parent.parent

# A suite started as a background job of a non-interactive shell (`make test &`, nohup) has SIGINT
# ignored, and an ignored signal stays ignored across exec: every command the Ctrl-C tests start
# would then ignore their SIGINT and run to its end. Handled here, it is the default again in them.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``orchestrate build`` into a temporary folder: the FMUs under fmus/, every scenario of
    ssp/ under ssp/<name>.ssp. The folder starts as a copy of the checkout's build/ where there is
    one (``make test`` makes it first): the build then redoes only what its sources changed, as it
    does for a user (a cold build in an empty folder is tests/test_wheel.py's)."""
    dest = tmp_path_factory.mktemp("build")
    for part in ("fmus", "fmus3", "fmus_clocked", "ssp"):
        if (REPO / "build" / part).is_dir():
            shutil.copytree(REPO / "build" / part, dest / part)
    assert main(["build", "--sources", str(REPO / "ssp"), "--dest", str(dest)]) == 0
    return dest


def checkout_copy(dest: Path) -> Path:
    """The checkout's files (tracked, and new ones git does not ignore) copied into ``dest``."""
    command = ["git", "-C", str(REPO), "ls-files", "-z", "--cached", "--others", "--exclude-standard"]
    listed = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert listed.returncode == 0, f"{REPO} is not a git checkout: {listed.stderr.strip()}"
    for name in filter(None, listed.stdout.split("\0")):
        source = REPO / name
        if source.is_file():  # one deleted but not yet committed is not
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)
    return dest


@pytest.fixture(scope="session")
def dist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An sdist and a wheel of the checkout, as PyPI would serve them (the wheel built from the
    sdist, so the sdist is complete). Built from a copy of the checkout's files: setuptools writes
    its egg-info into the source tree, and two xdist workers building in the checkout at once
    broke each other's sdist ("No such file or directory", fresh-clone CI at ec6ee5e)."""
    out = tmp_path_factory.mktemp("dist")
    source = checkout_copy(tmp_path_factory.mktemp("source"))
    command = [sys.executable, "-m", "build", "--no-isolation", "--outdir", str(out), str(source)]
    proc = subprocess.run(command, cwd=out, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return out


@pytest.fixture(scope="session")
def fmus(built: Path) -> dict[str, Path]:
    """The project's five FMUs, model name -> path."""
    return {path.stem: path for path in sorted((built / "fmus").glob("*.fmu"))}


@pytest.fixture(scope="session")
def test_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The small test FMUs of tests/fmus/ (Source, Gain, Integrator), name -> path."""
    folder = tmp_path_factory.mktemp("test_fmus")
    return {n: build_test_fmu(n, folder) for n in ("Source", "Gain", "Integrator")}


@pytest.fixture(autouse=True)
def _temporary_files_of_the_test(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """What this process puts in temporary files during a test goes to a folder of pytest's (the
    last three sessions kept) instead of TMPDIR: FMPy's simulate_fmu leaves its unpacked FMU behind
    when a simulation raises, as many tests make it do. Programs a test starts keep TMPDIR, where
    ``make test`` finds what they leave."""
    saved = tempfile.tempdir
    tempfile.tempdir = str(tmp_path_factory.mktemp("tmp"))
    try:
        yield
    finally:
        tempfile.tempdir = saved


@pytest.fixture(autouse=True)
def _signals_left_as_found(request: pytest.FixtureRequest) -> Iterator[None]:
    """A test that leaves SIGINT or SIGTERM blocked or ignored in the test process makes every
    command a later test starts inherit it (the launcher hands back only what it blocked itself;
    an ignored signal stays ignored across exec): Ctrl-C tests then time out far from the cause.
    Mask and handlers are put back after each test, and the test that changed them is named in a
    warning and in results/signal-mask-leaks.txt."""
    watched = (signal.SIGINT, signal.SIGTERM)
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    handlers = {s: signal.getsignal(s) for s in watched}
    yield
    after = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    changed = [f"{s.name} blocked" for s in watched if s in after and s not in before]
    changed += [f"{s.name} handler {signal.getsignal(s)!r}" for s in watched
                if signal.getsignal(s) != handlers[s]]
    if changed:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
        for s, handler in handlers.items():
            if handler is not None:
                signal.signal(s, handler)
        line = f"{request.node.nodeid}: left {', '.join(changed)}"
        (REPO / "results").mkdir(exist_ok=True)
        with (REPO / "results" / "signal-mask-leaks.txt").open("a") as log:
            log.write(line + "\n")
        warnings.warn(line, stacklevel=1)
