# SPDX-License-Identifier: BSD-2-Clause
"""Every FMU and exported container may be redistributed: it carries the project's licence
beside the third-party ones, the FMI entry point ``documentation/licenses/license.txt`` naming
every licence file, an honest ``generationTool``, and ``documentation/externalDependencies.txt``
naming every shared library its binaries need that the archive does not hold (checked against
the binaries' own DT_NEEDED entries, read with objdump, and the win64 DLLs' import tables, read
with mingw-w64's objdump)."""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest

from orchestrator.export import export

REPO = Path(__file__).resolve().parents[1]
OBJDUMP_PE = shutil.which("x86_64-w64-mingw32-objdump") or "x86_64-w64-mingw32-objdump"
GLIBC = {"libc.so.6", "libm.so.6", "libdl.so.2", "libpthread.so.0", "librt.so.1", "ld-linux-x86-64.so.2"}

pytestmark = pytest.mark.system


def _archives(built: Path) -> list[Path]:
    return sorted((built / "fmus").glob("*.fmu")) + sorted((built / "fmus3").glob("*.fmu"))


def _needed(data: bytes, tmp: Path) -> set[str]:
    binary = tmp / "lib.so"
    binary.write_bytes(data)
    dump = subprocess.run(["objdump", "-p", str(binary)], capture_output=True, text=True, check=True).stdout
    return set(re.findall(r"NEEDED\s+(\S+)", dump))


def _imports(data: bytes, tmp: Path) -> set[str]:
    """The DLL names a PE file imports (mingw-w64's objdump: the build needs mingw-w64 anyway)."""
    binary = tmp / "lib.dll"
    binary.write_bytes(data)
    dump = subprocess.run([OBJDUMP_PE, "-p", str(binary)], capture_output=True, text=True, check=True).stdout
    return set(re.findall(r"DLL Name: (\S+)", dump))


def _check(archive: Path, tmp: Path) -> None:
    with zipfile.ZipFile(archive) as z:
        names = set(z.namelist())
        licences = {n.rsplit("/", 1)[1] for n in names if n.startswith("documentation/licenses/")}
        project = z.read("documentation/licenses/fixed-time-cosim-LICENSE.txt")
        assert project == (REPO / "LICENSE").read_bytes()
        entry = z.read("documentation/licenses/license.txt").decode()
        for name in licences - {"license.txt"}:
            assert name in entry, f"{archive.name}: license.txt does not name {name}"
        assert "see the file" not in entry, f"{archive.name}: a licence file whose coverage is not said"
        assert "BSD-2-Clause" in entry
        external = z.read("documentation/externalDependencies.txt").decode()
        description = z.read("modelDescription.xml").decode()
        tool = re.search(r'generationTool="([^"]*)"', description).group(1)
        assert tool.startswith("fixed-time-cosim "), f"{archive.name}: generationTool {tool!r}"
        bundled = {n.rsplit("/", 1)[-1] for n in names}
        for member in sorted(n for n in names if n.startswith("binaries/") and n.endswith(".so")
                             and n.count("/") == 2):  # the binaries a host loads, not the runtime's own
            for library in _needed(z.read(member), tmp) - GLIBC:
                assert library in bundled or library in external, \
                    f"{archive.name}: {member} needs {library}, neither bundled nor declared"
        bundled_lower = {n.lower() for n in bundled}
        for member in sorted(n for n in names if n.startswith("binaries/") and n.endswith(".dll")
                             and n.count("/") == 2):  # the DLLs a Windows host loads
            for library in _imports(z.read(member), tmp):
                crt = library.lower().startswith("api-ms-win-crt-") and "api-ms-win-crt-*.dll" in external
                assert library.lower() in bundled_lower or library in external or crt, \
                    f"{archive.name}: {member} imports {library}, neither bundled nor declared"


def test_every_fmu_declares_licences_and_dependencies(built: Path, tmp_path: Path) -> None:
    if shutil.which("objdump") is None:
        pytest.skip("objdump (binutils) is not installed")
    archives = _archives(built)
    assert len(archives) >= 10
    for archive in archives:
        _check(archive, tmp_path)
    fmi3 = zipfile.ZipFile(built / "fmus3" / "Reference.fmu").read("modelDescription.xml").decode()
    assert "PythonFMU 0.7.0\"" not in fmi3  # pythonfmu makes no FMI 3.0 FMU: the layer is ours


@pytest.mark.parametrize("fmi", ["2", "3"])
def test_an_exported_container_declares_its_licences(built: Path, tmp_path: Path, fmi: str) -> None:
    target = tmp_path / f"example1_{fmi}.fmu"
    export(built / "ssp" / "example1.ssp", target, fmi=fmi)
    _check(target, tmp_path)
    with zipfile.ZipFile(target) as z:
        assert "resources/fmus/" in z.read("documentation/licenses/license.txt").decode()
        inner = [n for n in z.namelist() if n.startswith("resources/fmus/") and n.endswith("/license.txt")]
        assert len(inner) == 4  # each embedded FMU keeps its own entry point
