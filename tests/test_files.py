# SPDX-License-Identifier: BSD-2-Clause
"""Whole-file writes (``orchestrator.files``): concurrent writers of one target and failed writes.

The oracle is the file system: after any number of concurrent complete writes the target holds
one writer's complete content, and a write that fails leaves the target as it was and no
temporary file behind. The concurrency test failed with the fixed ``<target>.part`` name the
provenance sidecar used before (``FileNotFoundError`` on the rename; CI of stop 17).
"""

from __future__ import annotations

import json
import os
import stat
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from orchestrator import files
from orchestrator.provenance import read_provenance, sidecar, write_provenance

WRITES = 300


def write_many(result: str, writer: int) -> int:
    """Write the sidecar of ``result`` WRITES times with a record naming ``writer``."""
    for i in range(WRITES):
        write_provenance(result, {"writer": writer, "i": i, "pad": "x" * 4096})
    return writer


def test_two_processes_writing_one_sidecar_both_succeed_and_leave_one_complete_file(tmp_path: Path) -> None:
    result = tmp_path / "r.csv"
    with ProcessPoolExecutor(2) as pool:
        done = list(pool.map(write_many, [str(result)] * 2, [1, 2]))
    assert done == [1, 2]
    record = read_provenance(result)
    assert record is not None and record["writer"] in (1, 2) and record["i"] == WRITES - 1
    assert json.loads(sidecar(result).read_text()) == record
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv.json"]


def test_a_failed_write_leaves_the_target_as_it_was_and_no_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "baseline.csv"
    target.write_text("old\n")
    with pytest.raises(RuntimeError, match="disk full"), files.replacing(target) as partial:
        partial.write_text("half")
        raise RuntimeError("disk full")
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["baseline.csv"]


def test_the_written_file_gets_the_mode_open_gives(tmp_path: Path) -> None:
    umask = os.umask(0o022)
    try:
        files.write_text(tmp_path / "a.txt", "a\n")
    finally:
        os.umask(umask)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644  # 0o666 less the umask 0o022
    assert (tmp_path / "a.txt").read_bytes() == b"a\n"


@pytest.mark.parametrize("hashlib_loaded", [True, False])
def test_bulk_sha256_is_sha256_whichever_implementation_it_takes(hashlib_loaded: bool,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """OpenSSL's where the process has imported hashlib, else CPython's own: the same digest."""
    import hashlib

    expected_type = type(hashlib.sha256()) if hashlib_loaded else type(files.sha256())
    if not hashlib_loaded:
        monkeypatch.delitem(sys.modules, "hashlib")
    data = os.urandom(3 << 20)
    h = files.bulk_sha256()
    h.update(data)
    assert type(h) is expected_type
    assert h.hexdigest() == hashlib.sha256(data).hexdigest()
