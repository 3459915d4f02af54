# SPDX-License-Identifier: BSD-2-Clause
"""fmu_src.toolchain.build: reproducible archives, deterministic GUIDs, requirements, bundling checks."""

from __future__ import annotations

import ast
import hashlib
import io
import lzma
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import fmpy
import pytest
import pythonfmu
from fmu_helpers import MODELS

from fmu_src.toolchain import runtime
from fmu_src.toolchain.__main__ import main
from fmu_src.toolchain.build import CLASS_LINE, FMU_SCRIPTS, REPO_ROOT, XZ_MEMBERS, BuildError, build_fmu
from fmu_src.toolchain.variable_table import variable_table

pytestmark = pytest.mark.system


def source_copy(tmp_path: Path) -> Path:
    root = tmp_path / "src"
    for package in ("fmu_src", "controller"):
        shutil.copytree(REPO_ROOT / package, root / package, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def test_rebuild_gives_identical_bytes(fmus: dict, tmp_path: Path) -> None:
    """A second build in another folder and process gives the same bytes as ``make build``: a
    controller (its compiled law) and a plant (its compiled step) stand for the nine, which share
    every step of the build."""
    again = [build_fmu(m, tmp_path) for m in ("FixedTimeController", "PendulumPlant")]
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
def test_bundle_layout(fmus: dict, model: str) -> None:
    with zipfile.ZipFile(fmus[model]) as archive:
        names = archive.namelist()
        module = archive.read("resources/slavemodule.txt").decode().strip()
        digest = module.rsplit("_", 1)[1]
        package = f"_ftc_{model.lower()}_{digest}"
        entry = archive.read(f"resources/{module}.py").decode()
        script = archive.read(f"resources/{package}/fmu_src/{FMU_SCRIPTS[model]}").decode()
        sources = {n: archive.read(n).decode() for n in names if n.endswith(".py") and "/pythonfmu/" not in n}
    assert module == f"ftc_{model.lower()}_{digest}"
    assert CLASS_LINE.findall(script) == [model]
    # pythonfmu's entry, run again for every instance, only imports the class from the script
    assert CLASS_LINE.findall(entry) == []
    assert f"from {package}.fmu_src.{FMU_SCRIPTS[model][:-3]} import {model}\n" in entry
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
    assert "resources/requirements.txt" not in names  # nothing to install: no third-party package


def test_a_third_party_import_is_refused(tmp_path: Path) -> None:
    """An FMU carries no third-party package: a bundled module importing NumPy is a build error."""
    root = source_copy(tmp_path)
    rbf = root / "controller" / "rbf.py"
    text = rbf.read_text()
    anchor = "from collections.abc import Sequence\n"
    rbf.write_text(text.replace(anchor, f"{anchor}\nimport numpy\n", 1))
    assert rbf.read_text() != text
    with pytest.raises(BuildError, match=r"FixedTimeController imports numpy: an FMU carries no third-party"):
        build_fmu("FixedTimeController", tmp_path / "out", root=root)


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


def debian_md5sums(deb: Path) -> dict[str, str]:
    """Debian's own manifest of a package: file (without the leading /) -> MD5."""
    command = ["dpkg-deb", "-I", str(deb), "md5sums"]
    listing = subprocess.run(command, capture_output=True, text=True, check=True)
    return {path: md5 for md5, path in (line.split(None, 1) for line in listing.stdout.splitlines())}


def test_linux64_is_the_shim_pythonfmus_binary_and_debians_runtime(fmus: dict) -> None:
    """linux64: the shim, pythonfmu's own binary unchanged under <model>_pythonfmu.so, and
    Debian's libpython, expat and zlib byte for byte as Debian's package manifests list them
    (libpython xz-compressed, stored: decoded here by Python's lzma); win64 beside it
    (tests/test_fmu_windows_build.py); the licences beside them."""
    shipped = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    debs = REPO_ROOT / "build" / "runtime" / "debs"
    manifests: dict[str, str] = {}
    for pin in runtime.PACKAGES:
        manifests |= debian_md5sums(debs / pin.file_name)
    for model, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as archive:
            names = archive.namelist()
            platforms = {n.split("/")[1] for n in names if n.startswith("binaries/")}
            assert platforms == {"linux64", "win64"}
            inner = archive.read(f"binaries/linux64/{model}_pythonfmu.so")
            assert inner == (shipped / "linux64" / "libpythonfmu-export.so").read_bytes()
            assert archive.read(f"binaries/linux64/{model}.so") != inner
            for source, bundled in runtime.LIBRARIES:
                name = f"binaries/linux64/python/{bundled}"
                if name in XZ_MEMBERS:
                    assert name not in names
                    assert archive.getinfo(name + ".xz").compress_type == zipfile.ZIP_STORED
                    data = lzma.decompress(archive.read(name + ".xz"), format=lzma.FORMAT_XZ)
                else:
                    data = archive.read(name)
                assert hashlib.md5(data).hexdigest() == manifests[source], bundled
            licences = {n.rsplit("/", 1)[1] for n in names if n.startswith("documentation/licenses/")}
            assert {"Python-LICENSE.txt", "pythonfmu-LICENSE.txt", "expat-debian-copyright.txt",
                    "zlib-debian-copyright.txt", "xz-embedded-COPYING.txt"} <= licences
            assert b"PYTHON SOFTWARE FOUNDATION LICENSE VERSION 2" in archive.read(
                "documentation/licenses/Python-LICENSE.txt")
            description = archive.read("modelDescription.xml").decode()
        assert 'needsExecutionTool="false"' in description


def test_no_member_holds_a_path_of_the_build_machine(fmus: dict) -> None:
    """Nothing of where the FMU was built: not the sources' folder, the interpreter's prefixes, the
    home folder or the build's temporary folders."""
    paths = {str(REPO_ROOT), sys.prefix, sys.base_prefix, str(Path.home()), tempfile.gettempdir() + "/ftc_"}
    for model, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as archive:
            for name in archive.namelist():
                data = archive.read(name)
                if name.endswith(".zip"):  # the standard library: look inside
                    with zipfile.ZipFile(io.BytesIO(data)) as inner:
                        data = b"".join(inner.read(n) for n in inner.namelist())
                found = [p for p in paths if p.encode() in data]
                assert not found, f"{model}: {name} holds {found}"


def test_rebuilt_elsewhere_gives_the_same_bytes(fmus: dict, tmp_path: Path) -> None:
    """The sources copied to another folder build the same FMU, GUID included: the GUID depends
    only on what is bundled."""
    root = source_copy(tmp_path)
    again = build_fmu("Actuator", tmp_path / "out", root=root)
    assert again.read_bytes() == fmus["Actuator"].read_bytes()


def test_the_guid_follows_the_shims_bytes_not_its_comments(fmus: dict, tmp_path: Path) -> None:
    """The GUID is a digest of what is bundled: a changed message in the shim changes it, a
    comment (the same binary) does not."""
    guid = fmpy.read_model_description(str(fmus["Reference"])).guid
    root = source_copy(tmp_path)
    shim = root / "fmu_src" / "toolchain" / "shim" / "fmi2_functions.c"
    shim.write_text(shim.read_text() + "\n/* changed */\n")
    same = build_fmu("Reference", tmp_path / "comment", root=root)
    assert fmpy.read_model_description(str(same)).guid == guid
    shim.write_text(shim.read_text().replace('"fmi2 shim: out of memory"', '"fmi2 shim: no memory"'))
    changed = build_fmu("Reference", tmp_path / "code", root=root)
    assert fmpy.read_model_description(str(changed)).guid != guid


def test_no_c_compiler_is_a_build_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty folder: no cc, no gcc
    with pytest.raises(BuildError, match=r"no C compiler \(CC, cc or gcc on PATH\) to build the FMI shim"):
        build_fmu("Reference", tmp_path / "out")
    assert not (tmp_path / "out" / "Reference.fmu").exists()


def newest_symbol_versions(data: bytes, tmp: Path) -> dict[str, tuple[int, ...]]:
    """The newest GLIBC/GLIBCXX/CXXABI symbol version an ELF object asks for (objdump -T)."""
    path = tmp / "object.so"
    path.write_bytes(data)
    dump = subprocess.run(["objdump", "-T", str(path)], capture_output=True, text=True, check=True).stdout
    newest: dict[str, tuple[int, ...]] = {}
    for family, version in re.findall(r"\b(GLIBC|GLIBCXX|CXXABI)_([0-9.]+)\b", dump):
        newest[family] = max(newest.get(family, ()), tuple(int(p) for p in version.split(".")))
    return newest


@pytest.mark.skipif(shutil.which("objdump") is None, reason="needs objdump (binutils)")
def test_platform_floor_is_glibc_2_35_and_gcc_12s_libstdcxx(fmus: dict, tmp_path: Path) -> None:
    """The README's floor: no bundled object asks for more than glibc 2.35 and GCC 12's
    libstdc++, but the fallback expat (only loaded where the machine has none), which asks for the
    build machine's glibc at most."""
    machine = tuple(int(p) for p in os.confstr("CS_GNU_LIBC_VERSION").split()[1].split("."))
    with zipfile.ZipFile(fmus["FixedTimeController"]) as archive:
        objects = [n for n in archive.namelist() if n.startswith("binaries/") and ".so" in n]
        for name in objects:
            data = archive.read(name)
            if name.endswith(".xz"):  # libpython, as the shim decodes it
                data = lzma.decompress(data, format=lzma.FORMAT_XZ)
            newest = newest_symbol_versions(data, tmp_path)
            limit = machine if "/fallback/" in name else (2, 35)
            assert newest.get("GLIBC", ()) <= limit, (name, newest)
            assert newest.get("GLIBCXX", ()) <= (3, 4, 30), (name, newest)


@pytest.mark.parametrize("model", MODELS)
def test_every_python_source_ships_with_its_unchecked_hash_bytecode(fmus: dict, model: str) -> None:
    """Before: no .pyc in the FMU, so every instantiation compiled its 36 modules again wherever
    bytecode is not written (the bundled runtime; a host with PYTHONDONTWRITEBYTECODE). Oracle:
    importlib's own PEP 552 layout (magic number, flags, source hash) for each source."""
    import importlib.util

    with zipfile.ZipFile(fmus[model]) as archive:
        names = set(archive.namelist())
        sources = sorted(n for n in names if n.startswith("resources/") and n.endswith(".py"))
        assert sources
        for name in sources:
            folder, file = name.rsplit("/", 1)
            pyc = archive.read(f"{folder}/__pycache__/{file[:-3]}.cpython-311.pyc")
            assert pyc[:4] == importlib.util.MAGIC_NUMBER  # this test runs on 3.11, as the runtime
            assert int.from_bytes(pyc[4:8], "little") == 0b01  # hash-based, not checked
            assert pyc[8:16] == importlib.util.source_hash(archive.read(name)), name
        assert not [n for n in names if n.endswith(".pyc") and "/__pycache__/" in n
                    and n.replace("/__pycache__", "").rsplit(".", 2)[0] + ".py" not in names]


def test_the_fmus_python_is_not_compiled_when_bytecode_is_not_written(fmus: dict, tmp_path: Path) -> None:
    """Instantiate the controller FMU in a fresh interpreter with PYTHONDONTWRITEBYTECODE: Python's
    verbose import log shows every module of the FMU loaded from its shipped bytecode."""
    script = (
        "import sys, fmpy\n"
        "from fmpy.fmi2 import FMU2Slave\n"
        "md = fmpy.read_model_description(sys.argv[1])\n"
        "d = fmpy.extract(sys.argv[1], unzipdir=sys.argv[2])\n"
        "s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,"
        " instanceName='c')\n"
        "s.instantiate(); s.freeInstance()\n"
    )
    result = subprocess.run([sys.executable, "-v", "-c", script, str(fmus["FixedTimeController"]),
                             str(tmp_path / "u")], capture_output=True, text=True,
                            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}, check=True)
    unpacked = str(tmp_path / "u")
    loaded = [line for line in result.stderr.splitlines() if line.startswith("# code object from")
              and unpacked in line]
    assert len(loaded) >= 10, result.stderr[-2000:]
    assert all("__pycache__" in line for line in loaded), [x for x in loaded if "__pycache__" not in x]


@pytest.mark.parametrize("variant", ["fmus", "fmus3"])
def test_the_shims_variable_table_is_the_model_descriptions(built: Path, variant: str) -> None:
    """Issue 47: the guard's and the direct path's variable table is generated from the FMU's
    final model description and compiled into the shim (nothing parses XML at instantiation).
    Oracle: fmpy's reading of the same modelDescription.xml (its variables' value references,
    types, causalities and names, the GUID / instantiation token), and the token's bytes in the
    shipped binary; no copy of the description is shipped beside the binary any more."""
    codes = {"Real": "r", "Float64": "r", "Integer": "i", "Int32": "i", "Boolean": "b", "String": "s"}
    causalities = {"parameter": "p", "calculatedParameter": "c", "input": "i", "output": "o", "local": "l",
                   "independent": "t", "structuralParameter": "s"}
    for model in MODELS:
        fmu = built / variant / f"{model}.fmu"
        description = fmpy.read_model_description(str(fmu))
        with zipfile.ZipFile(fmu) as archive:
            table = variable_table(archive.read("modelDescription.xml")).decode()
            binaries = [n for n in archive.namelist() if n.startswith("binaries/")]
            shim = next(n for n in binaries if n.endswith(f"/{model}.so"))
            assert description.guid.encode() in archive.read(shim), (model, shim)
        assert not [n for n in binaries if n.endswith("_modelDescription.xml")], model
        rows = re.findall(r"\{(\d+)u, '(.)', '(.)', .*?, .*?, \"(.*)\"\},", table)
        expected = sorted((v.valueReference, codes.get(v.type, "e"), causalities[v.causality], v.name)
                          for v in description.modelVariables)
        assert [(int(vr), t, c, name) for vr, t, c, name in rows] == expected, model
        assert f'"{description.guid}", {len(expected)}u, variables,' in table, model


def test_kept_deflated_members_give_zipfiles_own_bytes(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """An archive whose large members come deflated from the build's cache (issue 46: deflated once,
    not once per FMU) is byte for byte what zipfile's writestr makes, and Info-ZIP's unzip finds
    every member intact."""
    from fmu_src.toolchain import build

    entries = {"binaries/lib.so": os.urandom(1 << 17) + bytes(1 << 18), "a.txt": b"small",
               "resources/z.bin": bytes(range(256)) * 1024}
    build.write_archive(tmp_path / "kept.fmu", entries, tmp_path / "deflated")
    build.write_archive(tmp_path / "again.fmu", entries, tmp_path / "deflated")  # from the cache
    assert len(list((tmp_path / "deflated").iterdir())) == 2
    monkeypatch.setattr(build, "DEFLATE_KEPT", 1 << 40)  # every member through zipfile's writestr
    build.write_archive(tmp_path / "plain.fmu", entries, tmp_path / "unused")
    plain = (tmp_path / "plain.fmu").read_bytes()
    assert (tmp_path / "kept.fmu").read_bytes() == plain == (tmp_path / "again.fmu").read_bytes()
    if shutil.which("unzip"):
        check = subprocess.run(["unzip", "-t", str(tmp_path / "again.fmu")], capture_output=True, text=True)
        assert check.returncode == 0 and "No errors detected" in check.stdout, check.stdout
