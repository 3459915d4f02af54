"""Writing a file so that readers and concurrent writers never see half of it.

Every file the engine and its applications write whole (a provenance sidecar, a baseline, a
campaign table, an SSP archive) is written under a temporary name beside its target and renamed
onto it. The temporary name is unique to the call (:func:`reserve`): two processes writing the same
target each rename their own complete file, the last rename wins, and neither fails. A fixed
``<target>.part`` name did not have that property: the first rename took the second writer's file
away (a CI failure of two ``orchestrate run`` writing one CSV, stop 17).
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["replacing", "reserve", "write_text"]


def reserve(target: str | os.PathLike) -> Path:
    """Create an empty temporary file beside ``target`` (``.<name>.<pid>.<random>.part``), with the
    mode ``open()`` gives (0666 less the umask); ``O_EXCL``: never a file another call has."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.part")
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
