"""Writing a file so that readers and concurrent writers never see half of it.

Every file the engine and its applications write whole (a provenance sidecar, a baseline, a
campaign table, an SSP archive) is written under a temporary name beside its target and renamed
onto it. The temporary name is unique to the call (``mkstemp``): two processes writing the same
target each rename their own complete file, the last rename wins, and neither fails. A fixed
``<target>.part`` name did not have that property: the first rename took the second writer's file
away (a CI failure of two ``orchestrate run`` writing one CSV, stop 17).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["replacing", "write_text"]


@contextmanager
def replacing(target: str | os.PathLike) -> Iterator[Path]:
    """A fresh temporary path beside ``target`` to write; renamed onto ``target`` when the block
    ends normally, removed when it raises (``target`` is then left as it was)."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    temporary = Path(name)
    try:
        umask = os.umask(0)
        os.umask(umask)
        temporary.chmod(0o666 & ~umask)  # mkstemp creates 0600; give the file the mode open() gives
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
