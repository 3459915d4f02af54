# SPDX-License-Identifier: BSD-2-Clause
"""The build reuses what it built from the same inputs (issue 34): before, touching one model file
rebuilt every FMU, its FMI 3.0 variant and every archive (21.7 s CPU, as a cold build).

Oracle: the files themselves (one reused keeps its bytes and modification time; one rebuilt is
written again) and the rebuilt FMU's own bundled source (the edit is in it)."""

from __future__ import annotations

import ast
import os
import shutil
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain.build import BUILD_CODE, REPO_ROOT, build_fmu
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
                   if n.startswith("resources/_ftc_reference_") and n.endswith("/fmu_src/reference.py")]
        assert len(bundled) == 1 and b"# the reference's edit" in archive.read(bundled[0])
    # a damaged or missing record of the inputs: rebuilt, never trusted
    (fmus / ".Reference.fmu.inputs").write_text("not a record\n")
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


def test_a_run_is_stale_only_when_a_source_it_was_built_from_changed(tmp_path: Path, monkeypatch,
                                                                       capsys) -> None:
    """Issue 42: 'make run' failed on every fresh clone: the build compiled controller/_fmath.abi3.so
    after the archives, and the stale check counted every file under controller/ (that .so too) by
    its time; 'orchestrate build', as advised, found nothing to rebuild. Now one record of the
    sources (fmu_src/toolchain/stamps.py) serves the build and the check: a build product or a
    touched file is no change, an edited model is, and rebuilding as advised rebuilds only the FMU
    that bundles it. A copy of the sources, built for linux64 without FMI 3.0 (what 'make run' builds)."""
    from orchestrator.cli import main
    from orchestrator.experiments.scenarios import build_scenarios

    root = _source_copy(tmp_path / "src")
    shutil.copytree(REPO_ROOT / "ssp" / "pendulum", root / "ssp" / "pendulum")
    monkeypatch.chdir(root)

    def build() -> dict[str, tuple[int, bytes]]:
        build_scenarios(["pendulum"], "build", "ssp", fmi3=False, platforms=("linux64",), root=root)
        return {p.name: written(p)[0] for p in sorted(Path("build", "fmus").glob("*.fmu"))}

    first = build()
    assert len(first) == 4
    argv = ["run", "pendulum", "--stop-time", "0.01", "--quiet", "--no-plot", "--output", "r.csv"]
    assert main(argv) == 0
    (root / "controller" / "_fmath.abi3.so").write_bytes(b"a build product, newer than the archive")
    for source in (root / "fmu_src" / "models").glob("*.py"):
        os.utime(source)  # touched, not changed
    assert main(argv) == 0
    with (root / "fmu_src" / "models" / "plants.py").open("a") as plants:
        plants.write("\n# a plant's edit\n")
    capsys.readouterr()
    assert main(argv) == 1
    assert ("build/ssp/pendulum.ssp is stale: fmu_src/models/plants.py changed since it was built: "
            "run 'orchestrate build pendulum'") in capsys.readouterr().err
    again = build()  # as the message advises
    assert main(argv) == 0
    assert [name for name in first if again[name] != first[name]] == ["PendulumPlant.fmu"]
    # An edit that rebuilds every FMU to the same bytes (a comment in the shim): the archive is not
    # packed again, and its record now names the FMUs' sources as they are. Before, the run stayed
    # stale after the advised build, for ever (3 Dec: build.py's own changes did that to build/).
    with (root / "fmu_src" / "toolchain" / "shim" / "log.c").open("a") as shim:
        shim.write("\n/* a comment: the objects keep their bytes */\n")
    capsys.readouterr()
    assert main(argv) == 1
    assert "fmu_src/toolchain/shim/log.c changed since it was built" in capsys.readouterr().err
    archive = written(Path("build", "ssp", "pendulum.ssp"))
    build()
    assert written(Path("build", "ssp", "pendulum.ssp")) == archive
    assert main(argv) == 0


def test_without_mingw_the_fmus_are_built_for_linux64_saying_why(tmp_path: Path, monkeypatch) -> None:
    """Issue 42: without mingw-w64 nothing was built, not even the Linux FMUs. Now the build makes
    linux64 alone and says in one line what was skipped and how to get it; the FMU then runs."""
    from fmu_src.toolchain.build import buildable_platforms
    from orchestrator.experiments.scenarios import build_scenarios

    monkeypatch.setenv("MINGW_CC", str(tmp_path / "no-such-x86_64-w64-mingw32-gcc"))
    platforms, note = buildable_platforms()
    assert platforms == ("linux64",)
    assert note.startswith("win64 skipped: no ")
    assert "apt-get install gcc-mingw-w64-x86-64 osslsigncode" in note
    lines: list[str] = []
    root = _source_copy(tmp_path / "src")
    shutil.copytree(REPO_ROOT / "ssp" / "pendulum", root / "ssp" / "pendulum")
    archives = build_scenarios(["pendulum"], tmp_path / "build", root / "ssp", fmi3=False,
                               progress=lines.append, root=root)
    assert lines[0] == note and len(lines) == 5  # the note, then a line per FMU
    for fmu in (tmp_path / "build" / "fmus").glob("*.fmu"):
        with zipfile.ZipFile(fmu) as archive:
            platforms_inside = {n.split("/")[1] for n in archive.namelist() if n.startswith("binaries/")}
        assert platforms_inside == {"linux64"}, fmu
    from orchestrator import RunOptions, run

    result = run(archives["pendulum"], RunOptions(stop_time=0.01))
    assert result.count == 21


def test_every_toolchain_module_a_build_runs_is_one_of_its_inputs() -> None:
    """Editing any module the build imports rebuilds the FMUs: before, ``controller_doc.py`` (which
    writes each controller's documentation page) and ``clocked.py`` were read by every build but were
    not among its inputs, so a changed page shipped only after ``rm -rf build``. ``stamps.py`` records
    the inputs and makes nothing that ships."""
    toolchain = REPO_ROOT / "fmu_src" / "toolchain"
    imported = set()
    for name in BUILD_CODE:
        if name.endswith(".py"):
            for node in ast.walk(ast.parse((toolchain / name).read_text())):
                if isinstance(node, ast.ImportFrom) and node.level == 1:
                    imported |= {node.module} if node.module else {a.name for a in node.names}
    missing = sorted(f"{m}.py" for m in imported - {"stamps"} if f"{m}.py" not in BUILD_CODE)
    assert not missing, f"imported by the build but not among its inputs: {missing}"
