# SPDX-License-Identifier: BSD-2-Clause
"""The cache of unpacked FMUs and remembered digests (orchestrator.fmucache, issue 21).

Oracles: hashlib over the bytes (digests), the FMU's own members (what an entry holds), and a run
with the cache off (``ORCHESTRATE_CACHE=off``: every FMU unpacked into the run's folder, as before)
whose CSV must be byte for byte the CSV of a run from the cache.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from orchestrator import fmucache

ORCHESTRATE = Path(__file__).resolve().parent.parent / ".venv" / "bin" / "orchestrate"


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    folder = tmp_path / "cache"
    monkeypatch.setenv("ORCHESTRATE_CACHE", str(folder))
    return folder


def test_an_fmu_is_unpacked_once_and_served_from_its_digest(cache, tmp_path, test_fmus):
    fmu = test_fmus["Gain"]
    first = Path(fmucache.unpack_fmu(fmu, tmp_path / "fallback"))
    assert first == cache / "fmus" / hashlib.sha256(fmu.read_bytes()).hexdigest()
    with zipfile.ZipFile(fmu) as archive:
        members = {n for n in archive.namelist() if not n.endswith("/")}
    assert members <= {p.relative_to(first).as_posix() for p in first.rglob("*") if p.is_file()}
    inode = (first / "modelDescription.xml").stat().st_ino
    # a second instance while the first is loaded shares the folder (issue 34: FMI allows it) ...
    assert Path(fmucache.unpack_fmu(fmu, tmp_path / "fallback")) == first
    # ... unless the FMU can be instantiated only once per process: its own copy
    alone = Path(fmucache.unpack_fmu(fmu, tmp_path / "fallback", shared=False))
    assert alone == tmp_path / "fallback" and (alone / "modelDescription.xml").is_file()
    fmucache.release(str(first))
    fmucache.release(str(first))
    again = Path(fmucache.unpack_fmu(fmu, tmp_path / "other"))
    fmucache.release(str(again))
    assert again == first and (first / "modelDescription.xml").stat().st_ino == inode  # not unpacked again
    assert not list((cache / "fmus").glob(".new-*"))
    assert str(first) not in fmucache._in_use


def test_an_entry_without_its_marker_is_replaced(cache, tmp_path, test_fmus):
    """A half-unpacked entry (no .complete: a process killed while renaming) is never used."""
    fmu = test_fmus["Source"]
    entry = cache / "fmus" / hashlib.sha256(fmu.read_bytes()).hexdigest()
    entry.mkdir(parents=True)
    (entry / "junk").write_text("left by a killed process")
    got = Path(fmucache.unpack_fmu(fmu, tmp_path / "fallback"))
    fmucache.release(str(got))
    assert got == entry and (entry / fmucache.COMPLETE).is_file() and not (entry / "junk").exists()


def test_off_and_unusable_cache_unpack_into_the_runs_folder(tmp_path, monkeypatch, test_fmus):
    monkeypatch.setenv("ORCHESTRATE_CACHE", "off")
    digest = hashlib.sha256(test_fmus["Gain"].read_bytes()).hexdigest()
    shared = tmp_path / f"fmu-{digest}"  # one copy in the run's folder for every instance of the run
    assert fmucache.unpack_fmu(test_fmus["Gain"], tmp_path / "a") == str(shared)
    assert fmucache.unpack_fmu(test_fmus["Gain"], tmp_path / "b") == str(shared)
    assert (shared / "modelDescription.xml").is_file() and not (tmp_path / "a").exists()
    fmucache.release(str(shared))
    fmucache.release(str(shared))
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("ORCHESTRATE_CACHE", str(blocker))
    assert fmucache.cache_folder() is None
    shared = str(tmp_path / "sub" / f"fmu-{digest}")
    assert fmucache.unpack_fmu(test_fmus["Gain"], tmp_path / "sub" / "b") == shared


def test_least_recently_used_entries_beyond_the_bound_go(cache, tmp_path, monkeypatch, test_fmus):
    monkeypatch.setattr(fmucache, "MAX_ENTRIES", 3)
    folder = cache / "fmus"
    folder.mkdir(parents=True)
    old = time.time() - 2 * fmucache.IN_USE
    for i, used in enumerate((old, old + 100, old + 10)):  # entry 1 used last of the old ones
        entry = folder / f"{i:064x}"
        entry.mkdir()
        (entry / fmucache.COMPLETE).write_text("x")
        os.utime(entry, (used, used))
    recent = folder / f"{9:064x}"
    recent.mkdir()  # used a moment ago
    got = Path(fmucache.unpack_fmu(test_fmus["Integrator"], tmp_path / "fallback"))
    fmucache.release(str(got))
    # five entries, three kept: the new one, the recent one and the most recently used old one
    assert sorted(p.name for p in folder.iterdir()) == sorted([got.name, recent.name, f"{1:064x}"])


def test_a_remembered_digest_follows_the_files_bytes(cache, tmp_path):
    path = tmp_path / "f.bin"
    path.write_bytes(b"a" * 1000)
    assert fmucache.sha256(path) == hashlib.sha256(b"a" * 1000).hexdigest()
    fmucache._digests.clear()  # a new process: the note in the cache folder answers
    assert fmucache.sha256(path) == hashlib.sha256(b"a" * 1000).hexdigest()
    assert len(list((cache / "digests").iterdir())) == 1
    path.write_bytes(b"b" * 1000)  # same size, same second: the change time still differs
    assert fmucache.sha256(path) == hashlib.sha256(b"b" * 1000).hexdigest()


@pytest.mark.system
def test_a_run_from_the_cache_writes_the_csv_a_run_without_it_writes(built, tmp_path):
    """The whole example1 scenario (0.2 s): cache cold, cache warm and cache off give the same
    bytes; the warm run unpacks nothing."""
    scenario = built / "ssp" / "example1.ssp"
    outputs = {}
    for label, setting in (("cold", str(tmp_path / "cache")), ("warm", str(tmp_path / "cache")),
                           ("off", "off")):
        out = tmp_path / f"{label}.csv"
        subprocess.run([str(ORCHESTRATE), "run", str(scenario), "--stop-time", "0.2", "--quiet", "--no-plot",
                        "--output", str(out)], check=True, env={**os.environ, "ORCHESTRATE_CACHE": setting})
        outputs[label] = out.read_bytes()
        if label == "cold":
            entries = sorted((tmp_path / "cache" / "fmus").iterdir())
            stamps = [(e / "modelDescription.xml").stat().st_mtime_ns for e in entries]
    assert outputs["cold"] == outputs["warm"] == outputs["off"]
    assert len(entries) == 4  # reference, controller, actuator, plant
    assert [(e / "modelDescription.xml").stat().st_mtime_ns for e in entries] == stamps


SHARED_RUN = """
import sys
from pathlib import Path
import orchestrator
from orchestrator import RunOptions
orchestrator.run(sys.argv[1], RunOptions(executor=sys.argv[2]))
maps = Path("/proc/self/maps").read_text().splitlines()
print(len({line.split(None, 5)[5] for line in maps if line.endswith("binaries/linux64/Gain.so")
           or "binaries/linux64/Gain.so (deleted)" in line}))
"""


@pytest.mark.parametrize("setting", ["cache", "off"])
def test_components_of_one_fmu_share_its_folder_and_library(test_fmus, tmp_path, setting):
    """Three gains in series, one Gain.fmu: the process maps one copy of its library (pythonfmu's
    binary stays mapped after the run), where each instance after the first unpacked and loaded
    its own copy before issue 34 (three files mapped)."""
    from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

    folder = tmp_path / "chain"
    gains = [component(f"g{i}", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": 2.0})
             for i in range(3)]
    write_ssd(folder, SystemStructure("chain", tuple(gains), (Connection.between("g0.y", "g1.u"),
                                                               Connection.between("g1.y", "g2.u")),
                                      Experiment(0.0, 0.1, 0.01)))
    archive = pack_ssp(folder, {"Gain.fmu": test_fmus["Gain"]}, tmp_path / "chain.ssp")
    env = {**os.environ, "ORCHESTRATE_CACHE": str(tmp_path / "c") if setting == "cache" else "off"}
    for executor in ("compiled", "python"):
        mapped = subprocess.run([sys.executable, "-c", SHARED_RUN, str(archive), executor], env=env,
                                check=True, capture_output=True, text=True).stdout
        assert mapped.strip() == "1", (executor, mapped)


@pytest.mark.system
def test_a_run_extracts_no_fmu_the_cache_holds(built, cache, tmp_path):
    """The second opening of an archive leaves its FMUs in it (the cache holds them unpacked): the
    same System and the same rows, bit for bit; an FMU needed as a file is extracted on demand,
    the member's own bytes."""
    import orchestrator
    from orchestrator import RunOptions

    scenario = built / "ssp" / "pendulum.ssp"
    first = orchestrator.run(scenario, RunOptions(stop_time=0.1))
    with orchestrator.open_system(scenario) as system:
        fmus = [c.fmu for c in system.components.values()]
        assert fmus and not any(f.exists() for f in fmus)  # left in the archive
        assert all(fmucache.deferred(f) for f in fmus)
        schedule = [(op.kind, op.component, op.inputs) for op in system.schedule]
        plant = system.components["plant"].fmu
        with zipfile.ZipFile(scenario) as archive:
            member = archive.read(f"resources/{plant.name}")
        assert fmucache.materialize(plant).read_bytes() == member and not fmucache.deferred(plant)
    second = orchestrator.run(scenario, RunOptions(stop_time=0.1))
    assert second.rows.tobytes() == first.rows.tobytes()
    assert second.provenance["fmus"] == first.provenance["fmus"]
    with orchestrator.open_system(scenario) as again:
        assert [(op.kind, op.component, op.inputs) for op in again.schedule] == schedule
