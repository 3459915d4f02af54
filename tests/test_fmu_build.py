"""fmu_src.build: reproducible archives, deterministic GUIDs, requirements, bundling checks."""

from __future__ import annotations

import ast
import importlib.metadata
import shutil
import sys
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import pytest
import pythonfmu
from fmu_helpers import MODELS

from fmu_src.build import CLASS_LINE, REPO_ROOT, BuildError, build_all, build_fmu, main

pytestmark = pytest.mark.system


def source_copy(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    for package in ("fmu_src", "controller"):
        shutil.copytree(REPO_ROOT / package, root / package, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def test_rebuild_gives_identical_bytes(fmus: dict, tmp_path: Path) -> None:
    again = build_all(tmp_path)
    assert [p.name for p in again] == [f"{m}.fmu" for m in MODELS]
    for path in again:
        assert path.read_bytes() == fmus[path.stem].read_bytes(), path.name
        with zipfile.ZipFile(path) as archive:
            assert {info.date_time for info in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}


def test_guid_is_deterministic_per_source(fmus: dict, tmp_path: Path) -> None:
    guids = {m: fmpy.read_model_description(str(fmus[m])).guid for m in MODELS}
    assert len(set(guids.values())) == len(MODELS)
    root = source_copy(tmp_path)
    (root / "fmu_src" / "models" / "checks.py").write_text(
        (root / "fmu_src" / "models" / "checks.py").read_text() + "\n# changed\n"
    )
    changed = build_fmu("Reference", tmp_path / "out", root=root)
    assert fmpy.read_model_description(str(changed)).guid != guids["Reference"]


@pytest.mark.parametrize("model", MODELS)
def test_bundle_layout_and_requirements(fmus: dict, model: str) -> None:
    with zipfile.ZipFile(fmus[model]) as archive:
        names = archive.namelist()
        module = archive.read("resources/slavemodule.txt").decode().strip()
        script = archive.read(f"resources/{module}.py").decode()
        requirements = archive.read("resources/requirements.txt").decode()
        sources = {n: archive.read(n).decode() for n in names if n.endswith(".py") and "/pythonfmu/" not in n}
    digest = module.rsplit("_", 1)[1]
    package = f"_ftc_{model.lower()}_{digest}"
    assert module == f"ftc_{model.lower()}_{digest}"
    assert CLASS_LINE.findall(script) == [model]
    # nothing bundled imports the repository's packages by their own names
    for name, text in sources.items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                assert node.module.split(".")[0] not in ("fmu_src", "controller"), name
            if (
                isinstance(node, ast.ImportFrom)
                and name.endswith(module + ".py")
                and "fmu_src" in (node.module or "")
            ):
                assert node.module.startswith(package + ".fmu_src"), name
    assert all(n.startswith(f"resources/{package}/") for n in sources if n != f"resources/{module}.py")
    pinned = [line for line in requirements.splitlines() if line and not line.startswith("#")]
    if model == "FixedTimeController":  # controller.rbf imports numpy
        assert pinned == [f"numpy=={importlib.metadata.version('numpy')}"]
    else:
        assert pinned == []


def test_absolute_import_in_a_bundled_module_is_refused(tmp_path: Path) -> None:
    root = source_copy(tmp_path)
    law = root / "controller" / "law.py"
    law.write_text(law.read_text().replace("from .params import", "from controller.params import"))
    with pytest.raises(
        BuildError, match=r"law\.py:\d+: bundled modules must import controller\.params relatively"
    ):
        build_fmu("FixedTimeController", tmp_path / "out", root=root)


def test_class_line_the_loader_cannot_find_is_refused(tmp_path: Path) -> None:
    root = source_copy(tmp_path)
    script = root / "fmu_src" / "reference.py"
    script.write_text(
        script.read_text().replace("class Reference(Fmi2Slave):", "class Reference(Fmi2Slave, object):")
    )
    with pytest.raises(
        BuildError, match=r"reference\.py: expected exactly one line 'class Reference\(Fmi2Slave\):'"
    ):
        build_fmu("Reference", tmp_path / "out", root=root)


def test_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path), "--model", "Actuator"]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "Actuator.fmu")
    assert (tmp_path / "Actuator.fmu").is_file()


def test_linux64_binary_is_the_shim_with_pythonfmus_binary_beside_it(fmus: dict) -> None:
    """linux64: the shim, pythonfmu's own binary unchanged under <model>_pythonfmu.so and the
    building interpreter's Python; win64: pythonfmu's DLL unchanged."""
    shipped = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
    paths = sysconfig.get_paths()
    for model, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as archive:
            linux = {n for n in archive.namelist() if n.startswith("binaries/linux64/")}
            expected = (f"{model}.so", f"{model}_pythonfmu.so", "python_env.txt")
            assert linux == {f"binaries/linux64/{name}" for name in expected}
            inner = archive.read(f"binaries/linux64/{model}_pythonfmu.so")
            assert inner == (shipped / "linux64" / "libpythonfmu-export.so").read_bytes()
            assert archive.read(f"binaries/linux64/{model}.so") != inner
            dll = (shipped / "win64" / "pythonfmu-export.dll").read_bytes()
            assert archive.read(f"binaries/win64/{model}.dll") == dll
            record = archive.read("binaries/linux64/python_env.txt").decode().splitlines()
        values = [line.split("=", 1) for line in record if not line.startswith("#")]
        assert ["version", f"{sys.version_info.major}.{sys.version_info.minor}"] in values
        assert ["library", str(Path(libdir, soname))] in values and Path(libdir, soname).is_file()
        assert ["home", sys.base_prefix] in values
        site = list(dict.fromkeys((paths["purelib"], paths["platlib"])))
        assert [v for k, v in values if k == "path"] == site


def test_shim_source_is_part_of_the_guid(fmus: dict, tmp_path: Path) -> None:
    root = source_copy(tmp_path)
    shim = root / "fmu_src" / "shim" / "fmi2_shim.c"
    shim.write_text(shim.read_text() + "\n/* changed */\n")
    changed = build_fmu("Reference", tmp_path / "out", root=root)
    guid = fmpy.read_model_description(str(fmus["Reference"])).guid
    assert fmpy.read_model_description(str(changed)).guid != guid


def test_no_c_compiler_is_a_build_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty folder: no cc, no gcc
    with pytest.raises(BuildError, match=r"no C compiler \(CC, cc or gcc on PATH\) to build the FMI shim"):
        build_fmu("Reference", tmp_path / "out")
    assert not (tmp_path / "out" / "Reference.fmu").exists()
