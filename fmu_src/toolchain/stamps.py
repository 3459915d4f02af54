# SPDX-License-Identifier: BSD-2-Clause
"""What a build product was made from: the one definition of a build's inputs.

Every product of ``orchestrate build`` (an FMU, its FMI 3.0 variant, a scenario archive) records,
in a hidden file beside it (``.<name>.inputs``, JSON), the digest of everything it was made from
(:func:`digest`: sources, flags, compiler versions, the FMUs it packs) and, among those, the
source files with a digest each. Three users read it, so that they cannot disagree:

* ``orchestrate build`` rebuilds a product whose digest differs (:func:`up_to_date`);
* the run's stale check (``orchestrator/experiments/builds.py``) names the recorded source files
  whose bytes differ now (:func:`changed_sources`): a touched but unchanged file is no change;
* the Makefile asks ``orchestrate build`` itself (about 0.6 s of CPU when nothing changed).

Only files the build reads are inputs: tracked sources, never a build product such as
``controller/_fmath.abi3.so``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path

try:  # CPython's own SHA-256, chosen once (3.12+: _sha2, 3.11: _sha256); see file_digest
    from _sha2 import sha256 as _sha256  # type: ignore[import-not-found]
except ImportError:
    try:
        from _sha256 import sha256 as _sha256  # type: ignore[import-not-found]
    except ImportError:  # another Python
        from hashlib import sha256 as _sha256

__all__ = ["changed_sources", "digest", "file_digest", "forget", "record", "recorded_platforms",
           "recorded_sources", "source_digests", "up_to_date"]

FORMAT = 2  # of the record; a record of another format is never trusted


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes (of a source file: the run's stale check calls it, and hashlib
    would load OpenSSL's libcrypto, 3.5 MB of every run's memory: CPython's own where it has one,
    as orchestrator/files.py's sha256)."""
    return _sha256(path.read_bytes()).hexdigest()


def digest(*parts: str | bytes | Path) -> str:
    """A digest of what a build step reads: texts, bytes, and files (name and bytes)."""
    import hashlib  # here: OpenSSL's (fast for the FMUs an archive packs); a run does not need it

    h = hashlib.sha256()
    for part in parts:
        data = (part.name.encode() + b"\0" + part.read_bytes()) if isinstance(part, Path) else \
            part if isinstance(part, bytes) else part.encode()
        h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


def _label(path: Path, root: Path) -> str:
    """``path`` relative to ``root`` where it lies inside, else absolute (as messages name it)."""
    path = path.resolve()
    return path.relative_to(root).as_posix() if path.is_relative_to(root) else path.as_posix()


def source_digests(files: Iterable[Path], root: Path) -> dict[str, str]:
    """Each source file (named relative to ``root``) with its digest: what :func:`record` keeps."""
    return {_label(f, root.resolve()): file_digest(f) for f in files}


def _record_path(target: Path) -> Path:
    return target.with_name(f".{target.name}.inputs")


def _read(target: Path) -> dict | None:
    try:
        data = json.loads(_record_path(target).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("format") == FORMAT else None


def up_to_date(target: Path, key: str, platforms: Iterable[str] = ()) -> bool:
    """Whether ``target`` exists, was built from the inputs ``key`` and holds at least
    ``platforms`` (a product with more platforms than asked for serves too)."""
    data = _read(target)
    return (target.is_file() and data is not None and data.get("key") == key
            and set(platforms) <= set(data.get("platforms", ())))


def forget(target: Path) -> None:
    """Drop ``target``'s record before it is written again: a build that fails half-way leaves no
    record that a later build could trust."""
    _record_path(target).unlink(missing_ok=True)


def recorded_platforms(target: Path) -> tuple[str, ...]:
    """The platforms ``target`` was built for ('()' where it has no record)."""
    data = _read(target)
    return tuple(data.get("platforms", ())) if data else ()


def record(target: Path, key: str, sources: Mapping[str, str], root: Path,
           platforms: Iterable[str] = ()) -> None:
    """Record that ``target`` (just written) was made from ``key``, from ``sources`` (label ->
    digest, :func:`source_digests`) under ``root``, for ``platforms``."""
    data = {"format": FORMAT, "key": key, "root": str(root.resolve()), "platforms": list(platforms),
            "sources": dict(sorted(sources.items()))}
    partial = _record_path(target).with_suffix(".part")
    partial.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    partial.replace(_record_path(target))


def recorded_sources(target: Path) -> dict[str, str]:
    """The source files ``target`` records (label -> digest; empty without a record)."""
    data = _read(target)
    return dict(data.get("sources", {})) if data else {}


def changed_sources(target: Path, folders: Iterable[str] = ()) -> list[str]:
    """The recorded source files of ``target`` whose bytes differ now or that are gone, then the
    files of the recorded source ``folders`` (labels, e.g. ``ssp/pendulum``) that the record does
    not hold (added since); labels as recorded. Empty where nothing changed or ``target`` has no
    record (nothing to judge by)."""
    data = _read(target)
    if data is None:
        return []
    root = Path(data.get("root", "."))
    sources: dict[str, str] = data.get("sources", {})
    changed = []
    for label, sha in sources.items():
        try:
            if file_digest(root / label) != sha:
                changed.append(label)
        except OSError:
            changed.append(label)
    for folder in folders:
        changed += sorted(label for label in (_label(f, root) for f in (root / folder).rglob("*")
                                              if f.is_file() and not f.name.startswith("."))
                          if label not in sources)
    return changed
