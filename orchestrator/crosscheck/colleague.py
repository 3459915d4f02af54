# SPDX-License-Identifier: BSD-2-Clause
"""A colleague's machine on this one, for the FMUs' hosts: a private mount namespace in which every
Python of the machine (interpreters, libpython, standard libraries, site-packages, virtual environments, the
build's unpacked runtime) is covered by an empty tmpfs or an empty file, entered with
``env -i PATH=/usr/bin:/bin``. What runs inside sees a Linux with no Python at all.

Needs root and a kernel that allows mount namespaces (``unshare -m``); :func:`refusal` says why
not where it cannot be had, for one clear skip reason."""

from __future__ import annotations

import atexit
import glob
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["PYTHON_PROBE", "hidden", "refusal"]

REPO = Path(__file__).resolve().parents[2]
CLEAN_PATH = "/usr/bin:/bin"
DIRECTORY_PATTERNS = (
    "/usr/lib/python*",
    "/usr/local/lib/python*",
    "/usr/share/python*",
    "/root/.pyenv",
    "/root/.local/lib/python*",
    "/opt/python*",
    "/work/*/.venv*",
    "/work/*/build/runtime",
)
FILE_PATTERNS = (
    "/usr/lib/x86_64-linux-gnu/libpython*",
    "/usr/local/lib/libpython*",
    "/usr/bin/python*",
    "/usr/local/bin/python*",
)
# Run inside: prints every Python still usable (nothing, on a colleague's machine).
PYTHON_PROBE = (
    "for f in $(/sbin/ldconfig -p | awk '/libpython/ {print $NF}') /usr/bin/python* /usr/local/bin/python*; "
    "do "
    '[ -s "$f" ] && echo "$f"; done; '
    "command -v python3 >/dev/null 2>&1 && python3 -c 'print(\"python3 runs\")' 2>/dev/null; true"
)


def _covered() -> tuple[list[str], list[str]]:
    """Existing directories and files to cover (this interpreter's prefixes and the repository's
    virtual environment and runtime cache included, wherever they are)."""
    dirs = _covered_directories()
    found = (Path(p) for pattern in FILE_PATTERNS for p in glob.glob(pattern))
    files = {str(p.resolve()) for p in found if p.is_file()}
    files = {f for f in files if not any(Path(f).is_relative_to(d) for d in dirs)}  # under a tmpfs already
    return sorted(dirs), sorted(files)


def _covered_directories() -> set[str]:
    """The outermost existing directories that hold a Python (never /, /usr, /usr/local themselves)."""
    dirs = {p for pattern in DIRECTORY_PATTERNS for p in glob.glob(pattern) if Path(p).is_dir()}
    dirs |= {sys.prefix, sys.base_prefix, str(REPO / ".venv"), str(REPO / "build" / "runtime")}
    dirs = {d for d in dirs if Path(d).is_dir() and d not in ("/usr", "/usr/local", "/")}
    return {d for d in dirs if not any(Path(d).is_relative_to(o) and d != o for o in dirs)}  # outermost


_EMPTY: list[Path] = []


def _empty_file() -> Path:
    """An empty file to bind over files (removed at exit), made again when its temporary folder
    went (a crosscheck tool run's TMPDIR is removed after the run)."""
    if not (_EMPTY and _EMPTY[-1].is_file()):
        folder = tempfile.mkdtemp(prefix="colleague_")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        _EMPTY.append(Path(folder, "empty"))
        _EMPTY[-1].write_bytes(b"")
    return _EMPTY[-1]


def refusal() -> str | None:
    """Why a colleague's machine cannot be made here, or None."""
    if not shutil.which("unshare"):
        return "needs unshare (util-linux) for a private mount namespace"
    result = subprocess.run(
        ["unshare", "-m", "--propagation", "private", "sh", "-c", "mount -t tmpfs none /mnt"],
        capture_output=True,
        text=True,
    )
    if result.returncode != 0:
        return f"the kernel refuses a private mount namespace here: {result.stderr.strip()}"
    return None


def hidden(argv: list[str], extra_env: dict[str, str] | None = None, also: tuple[str, ...] = ()) -> list[str]:
    """The command that runs ``argv`` on a colleague's machine (every Python hidden, clean
    environment plus ``extra_env``; the files ``also`` hidden too)."""
    dirs, files = _covered()
    files = sorted(set(files) | {str(Path(f).resolve()) for f in also if Path(f).exists()})
    empty = _empty_file()
    mounts = [f"mount -t tmpfs -o size=64k,mode=755 none {shlex.quote(d)}" for d in dirs]
    mounts += [f"mount --bind {shlex.quote(str(empty))} {shlex.quote(f)}" for f in files]
    env = [f"{k}={v}" for k, v in (extra_env or {}).items()]
    script = "set -e; " + "; ".join(mounts) + '; exec env -i PATH=' + CLEAN_PATH + ' "$@"'
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", script, "colleague", *env, *argv]
