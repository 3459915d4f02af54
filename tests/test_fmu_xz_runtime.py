# SPDX-License-Identifier: BSD-2-Clause
"""The runtime's interpreter carried xz-compressed (issue 46, item 3): the shim decodes
libpython3.11.so.1.0.xz only when it must load the bundled interpreter, into the user's cache once
(fmu_src/cbase/platform.c, ftc_decoded_file; fmu_src/toolchain/shim/unpack.c).

Oracles: fmusim (the Reference FMUs' host, no Python in its process) runs the FMU; the decoded file
is compared with the runtime's own libpython3.11.so.1.0 from Debian's package (SHA-256), its cache
folder's name with a 64-bit FNV-1a of the .xz member's bytes computed here; a corrupted member
is reported by the shim, not by a signal. The Windows decode (ftc_cached_copy_decoded) is
tests/test_fmu_windows.py's."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain.runtime import ensure_runtime

FMUSIM = Path(__file__).resolve().parents[2] / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
MEMBER = "binaries/linux64/python/lib/libpython3.11.so.1.0.xz"
MODEL = "FixedTimeController"
pytestmark = pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")


def fnv1a64(data: bytes) -> str:
    h = 14695981039346656037
    for byte in data:
        h = ((h ^ byte) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return f"{h:016x}"


def command(fmu: Path, out: Path) -> list[str]:
    return [str(FMUSIM), "--interface-type", "cs", "--stop-time", "0.01", "--output-interval", "0.005",
            "--output-file", str(out), str(fmu)]


def fmusim(fmu: Path, out: Path, env: dict[str, str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(command(fmu, out), env=env, capture_output=True, text=True, timeout=300, cwd=cwd)


def environment(tmp: Path, **changes: str | None) -> dict[str, str]:
    """The environment with an empty TMPDIR of the test and ``changes`` (None: unset)."""
    env = {**os.environ, "TMPDIR": str(tmp / "tmpdir")}
    (tmp / "tmpdir").mkdir(exist_ok=True)
    for name, value in changes.items():
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    return env


def decoded(cache: Path) -> list[Path]:
    return sorted(cache.glob("fixed-time-cosim/runtime/*/*libpython*"))


def raw_libpython() -> bytes:
    return ensure_runtime().libpython.read_bytes()


def test_a_first_run_decodes_into_an_empty_cache(fmus: dict[str, Path], tmp_path: Path) -> None:
    """(a) An empty $XDG_CACHE_HOME: the run succeeds, the cache then holds the runtime's own
    libpython byte for byte under the hash of the .xz bytes, and nothing else; a second run finds
    it (the same file, not decoded again)."""
    cache = tmp_path / "cache"
    env = environment(tmp_path, XDG_CACHE_HOME=str(cache))
    result = fmusim(fmus[MODEL], tmp_path / "out.csv", env)
    assert result.returncode == 0, result.stdout + result.stderr
    assert len((tmp_path / "out.csv").read_text().splitlines()) == 1 + 3
    with zipfile.ZipFile(fmus[MODEL]) as archive:
        packed = archive.read(MEMBER)
    [file] = decoded(cache)
    assert file == cache / "fixed-time-cosim" / "runtime" / fnv1a64(packed) / "libpython3.11.so.1.0"
    assert hashlib.sha256(file.read_bytes()).hexdigest() == hashlib.sha256(raw_libpython()).hexdigest()
    assert not list((tmp_path / "tmpdir").iterdir())
    before = file.stat()
    again = fmusim(fmus[MODEL], tmp_path / "out2.csv", env)
    assert again.returncode == 0, again.stdout + again.stderr
    assert decoded(cache) == [file]
    assert (file.stat().st_ino, file.stat().st_mtime_ns) == (before.st_ino, before.st_mtime_ns)


def test_without_a_cache_nothing_is_left_in_tmpdir(fmus: dict[str, Path], tmp_path: Path) -> None:
    """(b) No HOME and no XDG_CACHE_HOME: decoded into a private folder of TMPDIR, removed once
    loaded; the run succeeds and TMPDIR is left empty."""
    env = environment(tmp_path, HOME=None, XDG_CACHE_HOME=None)
    result = fmusim(fmus[MODEL], tmp_path / "out.csv", env, cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert len((tmp_path / "out.csv").read_text().splitlines()) == 1 + 3
    assert not list((tmp_path / "tmpdir").iterdir())


def test_what_killed_decodes_left_is_taken_back(fmus: dict[str, Path], tmp_path: Path) -> None:
    """A process killed while it decoded leaves its private folder of TMPDIR, or its temporary file
    in the cache (7.7 MB each). The next decode there removes those unchanged for ten minutes and
    leaves younger ones (another process may be decoding) and anything else alone."""
    hour_ago = os.stat(tmp_path).st_mtime - 3600

    def leftover(path: Path, age: float | None = hour_ago) -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"part of a libpython")
        if age is not None:
            os.utime(path, (age, age))
            os.utime(path.parent, (age, age))
        return path

    tmpdir = tmp_path / "tmpdir"
    old = leftover(tmpdir / "ftc-runtime-AAAAAA" / "libpython3.11.so.1.0")
    young = leftover(tmpdir / "ftc-runtime-BBBBBB" / "libpython3.11.so.1.0", age=None)
    other = leftover(tmpdir / "ftc-runtime-CCCCCC" / "notes.txt")
    env = environment(tmp_path, HOME=None, XDG_CACHE_HOME=None)
    result = fmusim(fmus[MODEL], tmp_path / "out.csv", env, cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr
    assert sorted(p.name for p in tmpdir.iterdir()) == ["ftc-runtime-BBBBBB", "ftc-runtime-CCCCCC"]
    assert not old.parent.exists() and young.is_file() and other.is_file()

    cache = tmp_path / "cache"
    with zipfile.ZipFile(fmus[MODEL]) as archive:
        folder = cache / "fixed-time-cosim" / "runtime" / fnv1a64(archive.read(MEMBER))
    stale = leftover(folder / ".libpython3.11.so.1.0.DDDDDD")
    fresh = leftover(folder / ".libpython3.11.so.1.0.EEEEEE", age=None)
    result = fmusim(fmus[MODEL], tmp_path / "out2.csv", environment(tmp_path, XDG_CACHE_HOME=str(cache)))
    assert result.returncode == 0, result.stdout + result.stderr
    assert not stale.exists() and fresh.is_file()
    assert sorted(p.name for p in folder.iterdir()) == [fresh.name, "libpython3.11.so.1.0"]


def test_a_read_only_cache_falls_back_to_tmpdir(fmus: dict[str, Path], tmp_path: Path) -> None:
    """A cache folder that cannot be written (XDG_CACHE_HOME a file): the same private folder."""
    (tmp_path / "not-a-folder").write_text("")
    env = environment(tmp_path, XDG_CACHE_HOME=str(tmp_path / "not-a-folder"))
    result = fmusim(fmus[MODEL], tmp_path / "out.csv", env)
    assert result.returncode == 0, result.stdout + result.stderr
    assert not list((tmp_path / "tmpdir").iterdir())


def test_two_processes_on_an_empty_cache_both_succeed(fmus: dict[str, Path], tmp_path: Path) -> None:
    """(c) Two fmusim processes started together on one empty cache: both decode, one file is
    linked into place, both run, and no temporary file is left."""
    cache = tmp_path / "cache"
    env = environment(tmp_path, XDG_CACHE_HOME=str(cache))
    processes = [subprocess.Popen(command(fmus[MODEL], tmp_path / f"out{k}.csv"), env=env, text=True,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT) for k in range(2)]
    outputs = [p.communicate(timeout=300)[0] for p in processes]
    assert [p.returncode for p in processes] == [0, 0], outputs
    [file] = decoded(cache)
    assert file.name == "libpython3.11.so.1.0"
    assert hashlib.sha256(file.read_bytes()).digest() == hashlib.sha256(raw_libpython()).digest()
    assert [p.name for p in file.parent.iterdir()] == [file.name]


def test_a_corrupted_member_is_one_message_not_a_crash(fmus: dict[str, Path], tmp_path: Path) -> None:
    """(d) One byte of the .xz member flipped: fmusim exits with an error status (no signal), the
    shim's message names the file and says the data is corrupt, and nothing is cached."""
    broken = tmp_path / f"{MODEL}.fmu"
    with zipfile.ZipFile(fmus[MODEL]) as source, zipfile.ZipFile(broken, "w") as copy:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == MEMBER:
                changed = bytearray(data)
                changed[len(changed) // 2] ^= 0x01
                data = bytes(changed)
            copy.writestr(info, data)
    cache = tmp_path / "cache"
    env = environment(tmp_path, XDG_CACHE_HOME=str(cache))
    result = fmusim(broken, tmp_path / "out.csv", env)
    assert result.returncode > 0, (result.returncode, result.stdout + result.stderr)
    text = result.stdout + result.stderr
    assert f"{MODEL}: cannot decode the bundled libpython3.11.so.1.0: " in text, text
    assert "libpython3.11.so.1.0.xz: corrupt xz data" in text, text
    assert decoded(cache) == []
    assert not list((tmp_path / "tmpdir").iterdir())


def test_a_python_host_decodes_nothing(fmus: dict[str, Path], tmp_path: Path) -> None:
    """FMPy runs the FMU on its own interpreter: the shim finds Python in the process and never
    touches the .xz (no cache folder made, nothing in TMPDIR)."""
    cache = tmp_path / "cache"
    env = environment(tmp_path, XDG_CACHE_HOME=str(cache))
    code = ("import sys, fmpy; r = fmpy.simulate_fmu(sys.argv[1], stop_time=0.01, output_interval=0.005); "
            "print(len(r))")
    result = subprocess.run([sys.executable, "-c", code, str(fmus[MODEL])], env=env, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.split()[-1] == "3"
    assert not cache.exists()
    assert not list((tmp_path / "tmpdir").glob("ftc-runtime-*"))
