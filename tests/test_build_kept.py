# SPDX-License-Identifier: BSD-2-Clause
"""The build's kept bytes (the runtime cache's objects, members, deflated and xz folders) are
bounded: :func:`~fmu_src.toolchain.build.prune_kept` removes the least recently used beyond its
budget, never what was used within the grace period, and the half-written files of builds that
died; reading a kept file marks it used. The oracle is the file system's sizes and times."""

from __future__ import annotations

import os
import time
from pathlib import Path

from fmu_src.toolchain.build import KEPT_FOLDERS, _kept_bytes, prune_kept

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
    assert _kept_bytes(path) == b"xxxxx"
    assert time.time() - path.stat().st_mtime < 60.0
    assert prune_kept(tmp_path, budget=0, grace=HOUR) == (0, 5)  # used now: it stays
    assert _kept_bytes(tmp_path / "missing") is None
