# SPDX-License-Identifier: BSD-2-Clause
"""Writing a file so that readers and concurrent writers never see half of it.

Every file the engine and its applications write whole (a provenance sidecar, a baseline, a
campaign table, an SSP archive) is written under a temporary name beside its target and renamed
onto it. The temporary name is unique to the call (:func:`reserve`): two processes writing the same
target each rename their own complete file, the last rename wins, and neither fails. A fixed
``<target>.part`` name did not have that property: the first rename took the second writer's file
away (a CI failure of two ``orchestrate run`` writing one CSV, stop 17).

Temporary files and folders carry the id of the process that made them (and a digest of its host
name), so those a killed process (``kill -9``) left behind are recognised and removed by the next
process that makes one of the same kind (:func:`remove_stale`).
"""

from __future__ import annotations

import os
import re
import shutil
import stat
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = ["HOST", "alive", "bulk_sha256", "not_regular", "remove_stale", "replacing", "reserve", "sha256",
           "temporary_folder", "write_text"]

try:  # CPython's own SHA-256 (3.12+: _sha2, 3.11: _sha256): hashlib loads OpenSSL's libcrypto, which
    from _sha2 import sha256  # type: ignore[import-not-found]  # held 3.5 MB of every run's memory
except ImportError:  # (issue 46); it hashes at 0.4 GB/s, and a run hashes an FMU only the first time
    try:
        from _sha256 import sha256  # type: ignore[import-not-found]
    except ImportError:  # another Python
        from hashlib import sha256

HOST = sha256(os.uname().nodename.encode()).hexdigest()[:8]  # in temporary names: whose pid


def bulk_sha256() -> Any:
    """A SHA-256 object for megabytes (an FMU's bytes): OpenSSL's, 4x faster with the CPU's SHA
    instructions, where this process has imported hashlib anyway (a build packing 24 scenarios
    spent 2.2 s in CPython's), else CPython's own (:data:`sha256`: a run loads no libcrypto)."""
    hashlib = sys.modules.get("hashlib")
    return hashlib.sha256() if hashlib is not None else sha256()
QUIET = 60.0  # s without a change after which a dead process's temporary file is certainly abandoned


def not_regular(path: str | os.PathLike) -> str:
    """Why an output ``path`` that exists cannot be written as a file ('' when it can, or does not
    exist): a folder, a FIFO (the writer would wait for a reader), a device or a socket;
    ``os.devnull`` is allowed (written in place)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return ""  # a new file (an unwritable place is reported when it is written)
    if stat.S_ISREG(mode) or os.fspath(path) == os.devnull:
        return ""
    kind = ("Is a directory" if stat.S_ISDIR(mode)
            else "is a FIFO (named pipe: the run would wait for a reader)" if stat.S_ISFIFO(mode)
            else "is a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "is a socket")
    return f"{kind}, not a regular file"


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists (on this host)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def remove_stale(folder: str | os.PathLike, pattern: str, quiet: float = 0.0) -> int:
    """Remove the entries of ``folder`` whose name matches ``pattern`` (a regular expression whose
    group ``pid`` is the id of the process that made it, on this host), when that process is gone
    and the entry has not changed for ``quiet`` seconds; only the current user's. Returns how many
    were removed; never raises."""
    removed = 0
    try:
        entries = list(os.scandir(str(folder)))
    except OSError:
        return 0
    regex = re.compile(pattern)
    now = time.time()
    for entry in entries:
        match = regex.fullmatch(entry.name)
        if match is None:  # before stat: a folder of many files (the FMU cache's notes) is scanned often
            continue
        try:
            info = entry.stat(follow_symlinks=False)
            if info.st_uid != os.getuid() or now - info.st_mtime < quiet or alive(int(match["pid"])):
                continue
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path)
            else:
                os.unlink(entry.path)
            removed += 1
        except (OSError, ValueError):
            continue
    return removed


def temporary_folder(prefix: str) -> Path:
    """A new folder in the system's temporary folder (``TMPDIR``), named ``<prefix><host>-<pid>-...``;
    the folders of this kind that dead processes left behind are removed first. OSError when it
    cannot be made (a missing or full ``TMPDIR``)."""
    base = tempfile.gettempdir()
    remove_stale(base, rf"{re.escape(prefix)}{HOST}-(?P<pid>\d+)-\w+")
    return Path(tempfile.mkdtemp(prefix=f"{prefix}{HOST}-{os.getpid()}-", dir=base))


def reserve(target: str | os.PathLike) -> Path:
    """Create an empty temporary file beside ``target`` (``.<name>.<host>-<pid>.<random>.part``), with
    the mode ``open()`` gives (0666 less the umask); ``O_EXCL``: never a file another call has.
    Those of ``target`` that dead processes left behind are removed first."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(target.parent, rf"\.{re.escape(target.name)}\.{HOST}-(?P<pid>\d+)\.[0-9a-f]+\.part",
                 QUIET)  # a CSV writer renames its file a moment after its parent died
    temporary = target.with_name(f".{target.name}.{HOST}-{os.getpid()}.{os.urandom(4).hex()}.part")
    os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    return temporary


@contextmanager
def replacing(target: str | os.PathLike) -> Iterator[Path]:
    """A fresh temporary path beside ``target`` to write; renamed onto ``target`` when the block
    ends normally, removed when it raises (``target`` is then left as it was)."""
    temporary = reserve(target)
    try:
        yield temporary
        temporary.replace(target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_text(target: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``target`` atomically; returns its path."""
    with replacing(target) as temporary:
        temporary.write_text(text, encoding="utf-8", newline="\n")
    return Path(target)
