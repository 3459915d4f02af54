# SPDX-License-Identifier: BSD-2-Clause
"""The build reuses what it built from the same inputs (issue 34): before, touching one model file
rebuilt every FMU, its FMI 3.0 variant and every archive (21.7 s CPU, as a cold build).

Oracle: the files themselves (one reused keeps its bytes and modification time; one rebuilt is
written again) and the rebuilt FMU's own bundled source (the edit is in it)."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain.build import REPO_ROOT, build_fmu
from fmu_src.toolchain.fmi3 import build_fmu3

pytestmark = pytest.mark.system


def written(*paths: Path) -> list[tuple[int, bytes]]:
    """When each file was last written, and its bytes."""
    return [(p.stat().st_mtime_ns, p.read_bytes()) for p in paths]


def _source_copy(dest: Path) -> Path:
    for name in ("controller", "fmu_src"):
        shutil.copytree(REPO_ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__"))
    return dest


def test_an_fmu_is_rebuilt_only_when_what_it_bundles_changes(tmp_path: Path) -> None:
    root = _source_copy(tmp_path / "src")
    fmus, fmus3 = tmp_path / "fmus", tmp_path / "fmus3"
    first = build_fmu("Reference", fmus, root)
    variant = build_fmu3(first, fmus3, root)
    before = written(first, variant)
    # the same inputs: nothing is written again
    assert build_fmu("Reference", fmus, root) == first and build_fmu3(first, fmus3, root) == variant
    assert written(first, variant) == before
    # a model file the Reference FMU does not bundle: still nothing
    with (root / "fmu_src" / "models" / "plants.py").open("a") as plants:
        plants.write("\n# a plant's edit\n")
    build_fmu("Reference", fmus, root)
    build_fmu3(first, fmus3, root)
    assert written(first, variant) == before
    # its own script: rebuilt, with the edit inside, and so is its FMI 3.0 variant
    with (root / "fmu_src" / "reference.py").open("a") as script:
        script.write("\n# the reference's edit\n")
    again = build_fmu("Reference", fmus, root)
    build_fmu3(again, fmus3, root)
    after = written(again, variant)
    assert after[0][1] != before[0][1] and after[1][1] != before[1][1]
    with zipfile.ZipFile(again) as archive:
        bundled = [n for n in archive.namelist()
                   if n.startswith("resources/ftc_reference_") and n.endswith(".py")]
        assert len(bundled) == 1 and b"# the reference's edit" in archive.read(bundled[0])
    # a damaged or missing record of the inputs: rebuilt, never trusted
    (fmus / ".Reference.fmu.inputs").write_text("not a digest\n")
    assert written(build_fmu("Reference", fmus, root))[0][0] != after[0][0]


def test_an_archive_is_packed_again_only_when_its_files_change(built: Path, tmp_path: Path) -> None:
    """build_scenarios' packing: the same scenario folder and FMUs keep the archive; an edited
    parameter file repacks it (and the archive then holds the edit)."""
    from orchestrator.experiments.scenarios import SCENARIO_DIR, _pack

    sources = tmp_path / "ssp"
    shutil.copytree(SCENARIO_DIR / "example1", sources / "example1")
    fmus = {p.name: p for p in (built / "fmus").glob("*.fmu")}
    target = _pack("example1", sources, fmus, tmp_path / "example1.ssp")
    before = written(target)
    assert written(_pack("example1", sources, fmus, target)) == before
    ssv = sources / "example1" / "plant.ssv"
    ssv.write_text(ssv.read_text().replace("</ssv:ParameterSet>", "<!-- edited --></ssv:ParameterSet>"))
    repacked = _pack("example1", sources, fmus, target)
    assert written(repacked) != before
    with zipfile.ZipFile(repacked) as archive:
        assert b"<!-- edited -->" in archive.read("plant.ssv")
