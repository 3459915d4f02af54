# SPDX-License-Identifier: BSD-2-Clause
"""Every FMU carries only the standard-library modules its model imports when it runs (issue 46:
measured in the bundled interpreter, fmu_src/toolchain/runtime.py ``measured_imports``), and that
is enough: the Reference FMUs' fmusim, a host with no Python, runs each FMU on its own runtime.

Oracles: fmusim (a host nobody here wrote) and the runtime's own ImportError: the same FMU with one
module it imports taken out of its zip fails in fmusim, naming that module, so a pass means the
FMU needs nothing the zip lacks. Before (646b056): the zip held the import closure found by
modulefinder, 172 modules (2.0 MB of each 10.2 MB FMU), pythonfmu's builder with argparse,
zipfile, tarfile, urllib.request among them; now 57 for the controller."""

from __future__ import annotations

import io
import subprocess
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain.build import FMU_SCRIPTS

pytestmark = pytest.mark.system
FMUSIM = Path(__file__).resolve().parents[2] / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
STDLIB = "binaries/linux64/python/python311.zip"
# what only pythonfmu's builder (FmuBuilder, its command line) imports: in no FMU
BUILDER_ONLY = {"argparse.pyc", "zipfile.pyc", "tarfile.pyc", "tempfile.pyc", "xml/dom/minidom.pyc",
                "urllib/request.pyc", "_pydecimal.pyc"}


def fmusim(fmu: Path, out: Path) -> subprocess.CompletedProcess:
    command = [str(FMUSIM), "--interface-type", "cs", "--logging-on", "--stop-time", "0.05",
               "--output-interval", "0.01", "--output-file", str(out), str(fmu)]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def without(fmu: Path, module: str, target: Path) -> Path:
    """A copy of ``fmu`` whose standard-library zip lacks ``module`` (e.g. ``json/__init__.pyc``)."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as copy:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == STDLIB:
                inner, buffer = zipfile.ZipFile(io.BytesIO(data)), io.BytesIO()
                with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as stripped:
                    for name in inner.namelist():
                        if name != module:
                            stripped.writestr(name, inner.read(name))
                data = buffer.getvalue()
            copy.writestr(info, data)
    return target


@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
@pytest.mark.parametrize("model", list(FMU_SCRIPTS))
def test_the_fmu_runs_on_the_standard_library_it_carries(fmus: dict[str, Path], model: str,
                                                         tmp_path: Path) -> None:
    with zipfile.ZipFile(fmus[model]) as archive:
        carried = set(zipfile.ZipFile(io.BytesIO(archive.read(STDLIB))).namelist())
    assert not carried & BUILDER_ONLY
    assert "json/__init__.pyc" in carried  # pythonfmu's slave imports it
    result = fmusim(fmus[model], tmp_path / "out.csv")
    assert result.returncode == 0, result.stdout + result.stderr
    rows = (tmp_path / "out.csv").read_text().splitlines()
    assert len(rows) == 1 + 6, rows  # header, t = 0, 0.01, ..., 0.05


@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
def test_a_module_the_fmu_imports_missing_from_its_zip_fails_naming_it(fmus: dict[str, Path],
                                                                      tmp_path: Path) -> None:
    """The runtime reads its zip, not a Python of the machine: without json the FMU cannot start."""
    broken = without(fmus["Actuator"], "json/__init__.pyc", tmp_path / "Actuator.fmu")
    result = fmusim(broken, tmp_path / "out.csv")
    assert result.returncode != 0
    assert "No module named 'json'" in result.stdout + result.stderr
