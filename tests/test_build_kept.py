# SPDX-License-Identifier: BSD-2-Clause
"""The build's kept bytes (the runtime cache's objects, members, deflated and xz folders) are
bounded: :func:`~fmu_src.toolchain.build.prune_kept` removes the least recently used beyond its
budget, never what was used within the grace period, and the half-written files of builds that
died; reading a kept file marks it used. What every compile shares (the Windows headers, the
import libraries) is made once per digest, a standard-library zip once per set of modules. The
oracle is the file system's sizes, times and bytes, and an interpreter that is not there."""

from __future__ import annotations

import io
import os
import time
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain.build import (
    KEPT_FOLDERS,
    _made_once,
    _win_headers,
    bundled_python,
    prune_kept,
)
from fmu_src.toolchain.runtime import _stdlib_zip, ensure_runtime, keep, read_kept

HOUR = 3600.0


def kept(cache: Path, folder: str, name: str, size: int, age: float) -> Path:
    """A kept file of ``size`` bytes last used ``age`` seconds ago."""
    path = cache / folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x" * size)
    then = time.time() - age
    os.utime(path, (then, then))
    return path


def test_the_least_recently_used_go_beyond_the_budget(tmp_path: Path) -> None:
    fresh = kept(tmp_path, "xz", "e", 1000, 60.0)  # beyond the budget alone, but used a minute ago
    newer = kept(tmp_path, "members", "b.zip", 300, 2 * HOUR)
    older = kept(tmp_path, "members", "a.zip", 400, 3 * HOUR)  # 1700 bytes with the two above: over
    oldest = kept(tmp_path, "objects", "c", 200, 5 * HOUR)  # 1500: within
    dead = kept(tmp_path, "deflated", ".d.12345", 10, 2 * HOUR)  # a build killed while writing it
    young = kept(tmp_path, "deflated", ".f.12346", 0, 10.0)  # a build writing it now
    assert prune_kept(tmp_path, budget=1500, grace=HOUR) == (2, 1500)
    survivors = [p.exists() for p in (fresh, newer, older, oldest, dead, young)]
    assert survivors == [True, True, False, True, False, True]
    assert prune_kept(tmp_path, budget=1500, grace=HOUR) == (0, 1500)  # nothing more to do


def test_reading_a_kept_file_marks_it_used(tmp_path: Path) -> None:
    path = kept(tmp_path, KEPT_FOLDERS[0], "k", 5, 5 * HOUR)
    assert read_kept(path) == b"xxxxx"
    assert time.time() - path.stat().st_mtime < 60.0
    assert prune_kept(tmp_path, budget=0, grace=HOUR) == (0, 5)  # used now: it stays
    assert read_kept(tmp_path / "missing") is None


def test_a_kept_file_is_written_whole_or_not_at_all(tmp_path: Path) -> None:
    path = tmp_path / "objects" / "k"
    keep(path, b"first")
    keep(path, b"second")
    assert path.read_bytes() == b"second"
    assert sorted(p.name for p in path.parent.iterdir()) == ["k"]  # no half-written file left


def test_what_every_compile_shares_is_made_once_per_digest(tmp_path: Path) -> None:
    made: list[Path] = []

    def make(folder: Path) -> None:
        folder.mkdir()
        (folder / "lib.a").write_bytes(b"archive")
        made.append(folder)

    cache = tmp_path / "win64-imports"
    cache.mkdir()
    (cache / f".{'a' * 32}.999999").mkdir()  # half made by a build that died
    dead = cache / f".{'c' * 32}.999998"  # half made hours ago: left behind by a killed build
    dead.mkdir()
    then = time.time() - 3 * HOUR
    os.utime(dead, (then, then))
    first = _made_once(cache, "a" * 64, make)
    assert _made_once(cache, "a" * 64, make) == first and len(made) == 1
    assert (first / "lib.a").read_bytes() == b"archive"
    newer = _made_once(cache, "b" * 64, make)  # another runtime, or other imports
    assert len(made) == 2 and newer != first and not first.exists()
    assert sorted(p.name for p in cache.iterdir() if not p.name.startswith(".")) == [newer.name]
    assert not dead.exists() and (cache / f".{'a' * 32}.999999").exists()  # a young one may be made now


def test_the_windows_headers_are_the_runtimes_with_the_windows_pyconfig(tmp_path: Path) -> None:
    include = tmp_path / "python3.11"
    (include / "cpython").mkdir(parents=True)
    (include / "Python.h").write_text('#include "pyconfig.h"\n')
    (include / "pyconfig.h").write_text("#error unknown multiarch location for pyconfig.h\n")  # Debian's
    (include / "cpython" / "object.h").write_text("/* one */\n")
    windows = tmp_path / "pyconfig-win64.h"
    windows.write_text("#define MS_WIN64\n")
    folder, digest = _win_headers.__wrapped__(include, windows, tmp_path / "cache")
    assert (folder / "pyconfig.h").read_text() == "#define MS_WIN64\n"
    assert (folder / "Python.h").read_bytes() == (include / "Python.h").read_bytes()
    assert (folder / "cpython" / "object.h").read_text() == "/* one */\n"
    (include / "cpython" / "object.h").write_text("/* two */\n")  # a runtime with other headers
    other, other_digest = _win_headers.__wrapped__(include, windows, tmp_path / "cache")
    assert other_digest != digest and (other / "cpython" / "object.h").read_text() == "/* two */\n"
    assert not folder.exists()


def test_a_standard_library_zip_is_compiled_once_per_set_of_modules(tmp_path: Path) -> None:
    runtime = ensure_runtime()
    launcher = bundled_python(runtime)
    modules = {"colorsys": runtime.stdlib / "colorsys.py", "this": runtime.stdlib / "this.py"}
    first = _stdlib_zip(runtime, launcher, modules)  # compiled now, or kept by an earlier run
    absent = tmp_path / launcher.name  # the same interpreter's name, nothing to run there
    assert _stdlib_zip(runtime, absent, modules) == first  # kept: no interpreter ran
    with zipfile.ZipFile(io.BytesIO(first)) as archive:
        assert sorted(archive.namelist()) == ["colorsys.pyc", "this.pyc"]
    with pytest.raises(OSError):  # another set is compiled: by the interpreter named, absent
        _stdlib_zip(runtime, absent, {"this": runtime.stdlib / "this.py"})
