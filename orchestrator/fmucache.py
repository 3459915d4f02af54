# SPDX-License-Identifier: BSD-2-Clause
"""Unpacked FMUs, kept between runs: an FMU is unpacked once per content digest and reused.

Unpacking is the largest part of starting a short run: an FMU that carries its own runtime holds
about 10 MB to inflate (0.05 s per FMU, 0.2 s for example1's four), and a Python FMU's sources,
freshly unpacked, are compiled again on every import (0.06 s). libcosim keeps a cache of unpacked
FMUs for the same reason. Here the folder of an FMU is ``<cache>/fmus/<sha256 of the .fmu>``:

* the key is the digest of the FMU's bytes, so what runs is exactly what the scenario holds (a
  changed FMU is a new entry; the digest costs about 3 ms per 5 MB);
* an entry is unpacked into a temporary folder and renamed into place with a ``.complete`` marker,
  so readers never see a half-unpacked entry and concurrent runs unpacking the same FMU both
  succeed (the second rename loses and its copy is dropped);
* the cache is bounded: after adding an entry, the least recently used ones beyond
  ``MAX_ENTRIES`` are removed, except those used in the last ``IN_USE`` seconds;
* instances share an entry: every component using one FMU (and every run in one process) loads
  the same folder and library, as FMI allows unless the FMU says
  ``canBeInstantiatedOnlyOncePerProcess`` (then a second instance gets its own copy in the run's
  temporary folder); with the cache off, instances of one run share one copy in the run's folder;
* a scenario archive's FMU whose entry is complete is not even extracted (:func:`defer`): a run
  reads its model description and loads it from the entry; :func:`materialize` extracts it when
  something needs the file itself;
* ``ORCHESTRATE_CACHE`` sets the folder (default ``$XDG_CACHE_HOME/orchestrate``, else
  ``~/.cache/orchestrate``); ``ORCHESTRATE_CACHE=off`` unpacks every FMU into the run's own
  temporary folder, as before; so does a cache folder that cannot be made or written;
* a cache that fails while an FMU is unpacked into it (a full disk, a quota) costs the run
  nothing: the FMU, and every later one of this process, is unpacked into the run's folder
  instead, with one CacheWarning naming the folder and the reason;
* an entry's ``.complete`` marker lists every file with its size and modification time as
  unpacked (a manifest, checked by ``stat`` on every use, 1 ms for 180 files): an entry whose
  file was deleted, truncated or rewritten is damaged, removed and unpacked again, with one
  CacheWarning (it made every later run fail until deleted by hand).

FMUs are unpacked by fmpy within the limits the scenario's checks applied to each FMU
(:func:`orchestrator.ssp.check_zip`), wherever they go.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import threading
import time
import warnings
import zipfile
from pathlib import Path

import fmpy

from . import files
from .errors import CacheWarning, UnpackError

__all__ = ["IN_USE", "MAX_ENTRIES", "cache_folder", "defer", "deferred", "entry_of", "forget", "materialize",
           "member_digest", "member_sha256", "release", "sha256", "unpack_fmu"]

MAX_ENTRIES = 64  # unpacked FMUs kept (about 11 MB each for an FMU with its own Python)
MAX_NOTES = 4096  # remembered digests (a small file each); the older half goes beyond that
IN_USE = 3600.0  # s: an entry used more recently than this is never removed
COMPLETE = ".complete"

_digests: dict[tuple[int, ...], str] = {}
_in_use: dict[str, int] = {}  # folders instances of this process have loaded: how many instances
_deferred: dict[str, tuple[str, str, str]] = {}  # FMU not extracted -> (archive, member, digest)
_failed: list[str] = []  # why the cache failed in this process (then it is not used again)
_lock = threading.RLock()


def _stat_key(path: str | os.PathLike) -> tuple[int, ...]:
    """What identifies a file's bytes without reading them, as git's index does: device, inode,
    size, modification and change times (the change time cannot be set back by a user)."""
    info = os.stat(path)
    return info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns


def sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes, read once per file: remembered in this process and in the cache
    folder (``digests/``) for a file unchanged since (:func:`_stat_key`). Hashing example1's archive
    and FMUs (40 MB) took 27 ms of every run."""
    if os.fspath(path) in _deferred:
        return _deferred[os.fspath(path)][2]
    key = _stat_key(path)
    if key in _digests:
        return _digests[key]
    folder = cache_folder()
    note = None if folder is None else _note(folder, f"{os.path.realpath(path)}\0{key}")
    digest = _read_note(note) or _hash(path, note)
    _digests[key] = digest
    return digest


def member_sha256(path: str | os.PathLike, archive: str | os.PathLike, member: str) -> str:
    """SHA-256 of ``path``, just unpacked from ``member`` of the zip ``archive``: remembered per
    archive digest and member name (a member of given bytes always unpacks to the same bytes), so
    that the FMUs unpacked from a scenario archive are not hashed on every run."""
    folder = cache_folder()
    note = None if folder is None else _note(folder, f"{sha256(archive)}\0{member}")
    digest = _read_note(note) or _hash(path, note)
    _digests[_stat_key(path)] = digest
    return digest


def _hash(path: str | os.PathLike, note: Path | None) -> str:
    """SHA-256 of the file's bytes, read in blocks, and remembered in ``note``."""
    h = files.bulk_sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            h.update(block)
    _write_note(note, h.hexdigest())
    return h.hexdigest()


def _note(folder: Path, key: str) -> Path:
    return folder.parent / "digests" / files.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()


def _read_note(note: Path | None) -> str | None:
    """The digest a note holds (None: no note, or not a digest)."""
    if note is None:
        return None
    try:
        text = note.read_text(encoding="ascii").strip()
    except (OSError, ValueError):
        return None
    return text if re.fullmatch(r"[0-9a-f]{64}", text) else None


def _write_note(note: Path | None, digest: str) -> None:
    """Remember ``digest`` (written whole under a temporary name, then renamed); never raises."""
    if note is None:
        return
    try:
        note.parent.mkdir(exist_ok=True)
        notes = list(os.scandir(note.parent))
        if len(notes) >= MAX_NOTES:
            notes.sort(key=lambda e: e.stat(follow_symlinks=False).st_mtime)
            for old in notes[:len(notes) // 2]:
                os.unlink(old.path)
        files.write_text(note, digest + "\n")
    except OSError:
        pass


def cache_folder() -> Path | None:
    """The cache's folder (made if needed), or None when the cache is off or cannot be made."""
    setting = os.environ.get("ORCHESTRATE_CACHE")
    if setting == "off":
        return None
    if setting:
        root = Path(setting)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = Path(base) / "orchestrate"
    folder = root / "fmus"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return folder if os.access(folder, os.W_OK | os.X_OK) else None


def unpack_fmu(fmu: str | os.PathLike, fallback: str | os.PathLike, shared: bool = True) -> str:
    """The folder holding the unpacked ``fmu``: its cache entry (unpacked now if missing), or, with
    no usable cache, a folder beside ``fallback`` (a fresh folder of the run, which the caller
    removes) with the FMU unpacked into it. Instances share the folder; with ``shared`` False (the
    FMU can be instantiated only once per process) a second instance gets its own copy in
    ``fallback``. The folder is held for the caller until :func:`release`. A cache that fails
    (a full disk, a quota) is left for the run's folder, with one CacheWarning. Raises what fmpy and
    zipfile raise for an FMU that cannot be unpacked, UnpackError for a full disk."""
    folder = None if _failed else cache_folder()
    digest = sha256(fmu)
    own = Path(fallback).parent / f"fmu-{digest}"  # the run's shared copy when there is no cache
    entry = folder / digest if folder is not None else own
    with _lock:
        if str(entry) in _in_use and not shared:
            return _extract(materialize(fmu), fallback)
        if str(entry) in _in_use:
            _in_use[str(entry)] += 1
            return str(entry)
        _in_use[str(entry)] = 1
        try:
            if folder is None:
                return _extract(materialize(fmu), entry)
            return _entry(fmu, folder, entry)
        except OSError as exc:  # the cache's disk is full, a quota, ...: the run's own folder will do
            release(str(entry))
            if folder is None:
                raise
            _failed.append(_reason(exc))
            warnings.warn(f"FMU cache {folder}: cannot unpack {os.path.basename(fmu)} ({_reason(exc)}); "
                          "FMUs are unpacked into the run's folder instead", CacheWarning, stacklevel=2)
        except BaseException:
            release(str(entry))
            raise
    return unpack_fmu(fmu, fallback, shared)


def _reason(exc: OSError) -> str:
    return " ".join(str(exc.strerror or exc).split()) + (f": {exc.filename}" if exc.filename else "")


def _extract(fmu: str | os.PathLike, folder: str | os.PathLike) -> str:
    """fmpy's extraction into ``folder``; UnpackError naming FMU, folder and reason (a full disk)."""
    try:
        return str(fmpy.extract(str(fmu), unzipdir=str(folder)))
    except OSError as exc:
        raise UnpackError(f"cannot unpack FMU {os.path.basename(fmu)} into {folder}: {_reason(exc)}") from exc


def release(folder: str) -> None:
    """An instance that loaded ``folder`` (a result of :func:`unpack_fmu`) is freed."""
    with _lock:
        if _in_use.get(folder, 0) > 1:
            _in_use[folder] -= 1
        else:
            _in_use.pop(folder, None)


def member_digest(archive: str | os.PathLike, member: str) -> str | None:
    """The digest of ``member`` of the zip ``archive`` when an earlier extraction remembered it."""
    folder = cache_folder()
    return None if folder is None else _read_note(_note(folder, f"{sha256(archive)}\0{member}"))


def entry_of(fmu: str | os.PathLike) -> Path | None:
    """The complete cache entry of ``fmu`` when it was deferred (not extracted), else None."""
    found = _deferred.get(os.fspath(fmu))
    folder = cache_folder()
    if found is None or folder is None or not (folder / found[2] / COMPLETE).is_file():
        return None
    return folder / found[2]


def defer(fmu: str | os.PathLike, archive: str | os.PathLike, member: str) -> bool:
    """Leave ``member`` of ``archive`` unextracted at ``fmu`` when its digest is remembered and its
    cache entry is complete (then True): reads go to the entry, :func:`materialize` extracts it."""
    digest = member_digest(archive, member)
    folder = cache_folder()
    if digest is None or folder is None or not (folder / digest / COMPLETE).is_file():
        return False
    _deferred[os.fspath(fmu)] = (os.fspath(archive), member, digest)
    return True


def deferred(fmu: str | os.PathLike) -> bool:
    """Whether ``fmu`` is an FMU of an archive left unextracted (:func:`defer`)."""
    return os.fspath(fmu) in _deferred


def materialize(fmu: str | os.PathLike) -> Path:
    """``fmu`` as a file: a deferred member is extracted now (its bytes checked against the digest
    remembered for it); any other path is returned as it is."""
    with _lock:
        found = _deferred.get(os.fspath(fmu))
        if found is not None:
            archive, member, digest = found
            Path(fmu).parent.mkdir(parents=True, exist_ok=True)
            with zipfile.ZipFile(archive) as zf, zf.open(member) as source, open(fmu, "wb") as target:
                shutil.copyfileobj(source, target, 1 << 20)
            if _hash(fmu, None) != digest:
                raise OSError(f"{archive}: member '{member}' changed since it was first unpacked")
            del _deferred[os.fspath(fmu)]
            _digests[_stat_key(fmu)] = digest
    return Path(fmu)


def forget(folder: str | os.PathLike) -> None:
    """Forget the deferred FMUs below ``folder`` (the scenario's temporary folder is removed)."""
    prefix = os.path.join(os.fspath(folder), "")
    with _lock:
        for path in [p for p in _deferred if p.startswith(prefix)]:
            del _deferred[path]


def _manifest(folder: Path) -> dict[str, list[int]]:
    """Every file under ``folder`` (but the marker): relative path -> [size, modification time ns]."""
    found = {}
    for root, _, names in os.walk(folder):
        for name in names:
            path = os.path.join(root, name)
            relative = os.path.relpath(path, folder)
            if relative != COMPLETE:
                info = os.stat(path, follow_symlinks=False)
                found[relative] = [info.st_size, info.st_mtime_ns]
    return found


def _damage(entry: Path) -> str | None:
    """Why the complete entry ``entry`` cannot be used as it is ('' : no manifest, an entry of an
    earlier version, unpacked again without a word), None when every file is as unpacked."""
    try:
        listed = json.loads((entry / COMPLETE).read_text(encoding="utf-8")).get("files")
    except (OSError, ValueError, AttributeError):
        listed = None
    if not isinstance(listed, dict):
        return ""
    for relative, expected in listed.items():
        try:
            info = os.stat(entry / relative, follow_symlinks=False)
        except OSError:
            return f"{relative} is missing"
        if [info.st_size, info.st_mtime_ns] != expected:
            return f"{relative} changed ({info.st_size} bytes, {expected[0]} when unpacked)"
    return None


def _entry(fmu: str | os.PathLike, folder: Path, entry: Path) -> str:
    """The cache entry ``entry`` of ``fmu``, unpacked first when missing or damaged."""
    if (entry / COMPLETE).is_file():
        damage = _damage(entry)
        if damage is None:
            _touch(entry)
            return str(entry)
        if damage:
            warnings.warn(f"FMU cache entry {entry} ({os.path.basename(fmu)}) was damaged ({damage}): "
                          "unpacked again", CacheWarning, stacklevel=3)
        _remove(entry, folder)
    files.remove_stale(folder, rf"\.(?:new|old)-{files.HOST}-(?P<pid>\d+)-[0-9a-f]+", files.QUIET)
    new = folder / f".new-{files.HOST}-{os.getpid()}-{os.urandom(4).hex()}"
    try:
        fmpy.extract(str(materialize(fmu)), unzipdir=str(new))
        marker = {"fmu": os.path.basename(fmu), "files": _manifest(new)}
        (new / COMPLETE).write_text(json.dumps(marker) + "\n", encoding="utf-8")
        try:
            new.rename(entry)
        except OSError:  # another process renamed its copy first (or a broken entry is in the way)
            if not (entry / COMPLETE).is_file():
                _remove(entry, folder)
                new.rename(entry)
    finally:
        shutil.rmtree(new, ignore_errors=True)
    _evict(folder, keep=entry)
    return str(entry)


def _touch(entry: Path) -> None:
    """Mark ``entry`` as just used (its modification time orders the evictions)."""
    try:
        os.utime(entry)
    except OSError:
        pass


def _remove(entry: Path, folder: Path) -> None:
    """Remove ``entry``: renamed out of the way first, so that no reader finds it half removed."""
    old = folder / f".old-{files.HOST}-{os.getpid()}-{os.urandom(4).hex()}"
    try:
        entry.rename(old)
    except OSError:
        return
    shutil.rmtree(old, ignore_errors=True)


def _evict(folder: Path, keep: Path) -> None:
    """Remove the least recently used entries beyond ``MAX_ENTRIES`` (not ``keep``, none used in the
    last ``IN_USE`` seconds)."""
    digest = re.compile(r"[0-9a-f]{64}")
    try:
        entries = [e for e in os.scandir(folder)
                   if digest.fullmatch(e.name) and e.is_dir(follow_symlinks=False)]
        entries.sort(key=lambda e: e.stat(follow_symlinks=False).st_mtime)
    except OSError:
        return
    now = time.time()
    for e in entries[:max(0, len(entries) - MAX_ENTRIES)]:
        try:
            used = e.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        if Path(e.path) != keep and now - used > IN_USE:
            _remove(Path(e.path), folder)
