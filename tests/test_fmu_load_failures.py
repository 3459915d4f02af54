# SPDX-License-Identifier: BSD-2-Clause
"""An FMU whose binary the loader refuses: one line naming FMU, file and reason, in run and validate.

Each case puts a real, broken shared library in place of the Reference FMU Feedthrough's
``binaries/linux64/Feedthrough.so``, built here with the system's compilers: a library needing a
symbol nothing defines, one needing a symbol version its dependency lacks (what a binary built
against a newer libstdc++ meets on Debian 12: ``GLIBCXX_3.4.32' not found``), a 32-bit ELF, a
Windows DLL, and a library without the FMI functions. The oracle for the reason is the loader's
own message (glibc's dlerror, as ``ctypes`` reports it). Before issue 43, ``validate`` said ok and
``run`` printed two chained Python tracebacks (52 lines).
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from ssd_text import feedthrough

from orchestrator.validate import validate

REFERENCE_FMUS = Path(__file__).resolve().parents[2] / "shared" / "tools" / "reference-fmus" / "2.0"
ORCHESTRATE = Path(sys.executable).parent / "orchestrate"
LIBRARY = "binaries/linux64/Feedthrough.so"
pytestmark = [pytest.mark.system,
              pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("gcc") is None
                                 or not (REFERENCE_FMUS / "Feedthrough.fmu").is_file(),
                                 reason="needs Linux, gcc and the Modelica Reference FMUs")]

SSD = feedthrough("broken", 0.02)


def compile_library(folder: Path, source: str, *flags: str, compiler: str = "gcc") -> Path:
    """``source`` compiled into a shared library in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "lib.c").write_text(source)
    out = folder / "lib.so"
    subprocess.run([compiler, "-shared", "-fPIC" if compiler == "gcc" else "-O0", "-o", str(out),
                    str(folder / "lib.c"), *flags], check=True, capture_output=True)
    return out


def undefined_symbol(folder: Path) -> dict[str, bytes]:
    lib = compile_library(folder, "extern int missing_function(void);\n"
                                  "int fmi2Instantiate(void) { return missing_function(); }\n")
    return {LIBRARY: lib.read_bytes()}


def missing_version(folder: Path) -> dict[str, bytes]:
    """A library linked against libstub.so.1 version STUB_2.0, shipped with a libstub.so.1 that has
    only STUB_1.0 (found through RPATH $ORIGIN), as a newer libstdc++'s GLIBCXX_3.4.32 is missing."""
    stub = folder / "stub"
    stub.mkdir(parents=True)
    (stub / "stub.c").write_text("int stub(void) { return 1; }\n")

    def build_stub(version: str) -> None:
        (stub / "map").write_text(f"{version} {{ global: stub; local: *; }};\n")
        subprocess.run(["gcc", "-shared", "-fPIC", "-Wl,-soname,libstub.so.1",
                        f"-Wl,--version-script={stub / 'map'}", "-o", str(stub / "libstub.so.1"),
                        str(stub / "stub.c")], check=True, capture_output=True)
    build_stub("STUB_2.0")
    (stub / "libstub.so").symlink_to("libstub.so.1")
    lib = compile_library(folder, "extern int stub(void);\nint fmi2Instantiate(void) { return stub(); }\n",
                          f"-L{stub}", "-lstub", "-Wl,-rpath,$ORIGIN")
    build_stub("STUB_1.0")
    return {LIBRARY: lib.read_bytes(), "binaries/linux64/libstub.so.1": (stub / "libstub.so.1").read_bytes()}


def wrong_class(folder: Path) -> dict[str, bytes]:
    """The real Feedthrough.so with its ELF header saying 32-bit (EI_CLASS = ELFCLASS32)."""
    with zipfile.ZipFile(REFERENCE_FMUS / "Feedthrough.fmu") as zf:
        data = bytearray(zf.read(LIBRARY))
    data[4] = 1
    return {LIBRARY: bytes(data)}


def windows_dll(folder: Path) -> dict[str, bytes]:
    if shutil.which("x86_64-w64-mingw32-gcc") is None:
        pytest.skip("no x86_64-w64-mingw32-gcc")
    lib = compile_library(folder, "int fmi2Instantiate(void) { return 0; }\n",
                          compiler="x86_64-w64-mingw32-gcc")
    return {LIBRARY: lib.read_bytes()}


def no_fmi_functions(folder: Path) -> dict[str, bytes]:
    lib = compile_library(folder, "int something_else(void) { return 0; }\n")
    return {LIBRARY: lib.read_bytes()}


CASES = {  # case -> (how to build it, the loader's words the message must carry)
    "undefined-symbol": (undefined_symbol, f"{LIBRARY}: undefined symbol: missing_function"),
    "missing-version": (missing_version, f"version `STUB_2.0' not found (required by {LIBRARY})"),
    "elf-class": (wrong_class, f"{LIBRARY}: wrong ELF class: ELFCLASS32"),
    "windows-dll": (windows_dll, f"{LIBRARY}: invalid ELF header"),
    "no-fmi-functions": (no_fmi_functions, f"{LIBRARY}: "),
}


def broken_scenario(tmp_path: Path, case: str) -> Path:
    """A scenario folder whose one FMU carries the broken library of ``case``."""
    members = CASES[case][0](tmp_path / "build")
    folder = tmp_path / "scenario"
    (folder / "resources").mkdir(parents=True)
    (folder / "SystemStructure.ssd").write_text(SSD)
    with zipfile.ZipFile(REFERENCE_FMUS / "Feedthrough.fmu") as src, \
            zipfile.ZipFile(folder / "resources" / "Feedthrough.fmu", "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            if info.filename not in members:
                dst.writestr(info, src.read(info))
        for name, data in members.items():
            dst.writestr(name, data)
    return folder


def loader_says(library: bytes, tmp_path: Path) -> str:
    """The second implementation: glibc's own message for loading ``library`` (via ctypes)."""
    path = tmp_path / "probe" / "Feedthrough.so"
    path.parent.mkdir()
    path.write_bytes(library)
    try:
        ctypes.CDLL(str(path))
    except OSError as exc:
        return str(exc).replace(str(path.parent) + "/", "binaries/linux64/")
    return ""


@pytest.mark.parametrize("case", CASES)
def test_validate_and_run_name_fmu_file_and_reason_in_one_line(tmp_path: Path, case: str) -> None:
    scenario = broken_scenario(tmp_path, case)
    reason = CASES[case][1]
    found = [p.message for p in validate(scenario).errors]
    assert len(found) == 1, found
    assert "component 'f': FMU 'Feedthrough.fmu': cannot load " in found[0] and reason in found[0], found
    if case == "no-fmi-functions":
        assert "exports no fmi2Instantiate, fmi2DoStep, fmi2GetReal, fmi2SetReal" in found[0]
    for command in ("validate", "run"):
        extra = ["--output", str(tmp_path / "out.csv")] if command == "run" else []
        done = subprocess.run([str(ORCHESTRATE), command, str(scenario), *extra], capture_output=True,
                              text=True, timeout=120, cwd=tmp_path)
        assert done.returncode != 0, (command, done.stdout, done.stderr)
        said = done.stdout + done.stderr
        errors = [line for line in said.splitlines() if "cannot load" in line]
        assert "Traceback" not in said and len(errors) == 1, (command, said)
        assert "Feedthrough.fmu" in errors[0] and reason in errors[0], (command, said)


def test_reason_is_the_loaders(tmp_path: Path) -> None:
    """The message carries glibc's words for the library, not a paraphrase."""
    members = undefined_symbol(tmp_path / "build")
    said = loader_says(members[LIBRARY], tmp_path)
    assert said == CASES["undefined-symbol"][1]
    scenario = broken_scenario(tmp_path / "s", "undefined-symbol")
    assert [p.message for p in validate(scenario).errors][0].endswith(said)
