# SPDX-License-Identifier: BSD-2-Clause
"""Every FMU carries only the standard-library modules its model imports when it runs (issue 46:
measured in the bundled interpreter, fmu_src/toolchain/runtime.py ``measured_imports``), and that
is enough: the Reference FMUs' fmusim, a host with no Python, runs each FMU on its own runtime.

Oracles: fmusim (a host nobody here wrote) and the runtime's own ImportError: the same FMU with one
module it imports taken out of its zip fails in fmusim, naming that module, so a pass means the
FMU needs nothing the zip lacks. Before (646b056): the zip held the import closure found by
modulefinder, 172 modules (2.0 MB of each 10.2 MB FMU), pythonfmu's builder with argparse,
zipfile, tarfile, urllib.request among them; 57 for the controller at the last stop, 45 now (no
module that only writes a model description)."""

from __future__ import annotations

import io
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import pythonfmu

from fmu_src.toolchain.build import FMU_SCRIPTS, runtime_pythonfmu

pytestmark = pytest.mark.system
FMUSIM = Path(__file__).resolve().parents[2] / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
STDLIB = "binaries/linux64/python/python311.zip"
# what only pythonfmu's builder (FmuBuilder, its command line) imports: in no FMU
BUILDER_ONLY = {"argparse.pyc", "zipfile.pyc", "tarfile.pyc", "tempfile.pyc", "xml/dom/minidom.pyc",
                "urllib/request.pyc", "_pydecimal.pyc"}
# what only writing a model description imports (pythonfmu's to_xml, fmu_support's extension), and
# pathlib, which pythonfmu imported unused: in no FMU since issue 46 (27 modules fewer)
DESCRIPTION_ONLY = {"xml/etree/ElementTree.pyc", "datetime.pyc", "uuid.pyc", "platform.pyc", "pathlib.pyc",
                    "ipaddress.pyc"}
# A slave of each variable kind, its model description printed without what differs per call.
SLAVE = """
import sys
from xml.etree.ElementTree import tostring
from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Integer, Real, String

class Model(Fmi2Slave):
    author = "someone"
    description = "every kind"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x, self.n, self.b, self.s = 1.5, 2, True, "text"
        self.register_variable(Real("x", causality=Fmi2Causality.output))
        self.register_variable(Integer("n", causality=Fmi2Causality.parameter, variability="tunable"))
        self.register_variable(Boolean("b", causality=Fmi2Causality.input))
        self.register_variable(String("s", causality=Fmi2Causality.parameter, variability="tunable"))

    def do_step(self, t, dt):
        return True

root = Model(instance_name="m", resources=".").to_xml()
root.attrib.pop("generationDateAndTime")
root.attrib.pop("guid")
print(sys.modules["pythonfmu"].__file__)
print(tostring(root).decode())
"""


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
    assert not carried & DESCRIPTION_ONLY
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


def test_the_fmus_copy_of_pythonfmu_writes_pythonfmus_model_description(tmp_path: Path) -> None:
    """The lines the build replaces in the FMU's copy (build.PYTHONFMU_LINES: lazy xml.etree and
    datetime, no uuid and pathlib) change no byte of what to_xml writes. Oracle: the installed
    pythonfmu on the same slave."""
    installed = Path(pythonfmu.__file__).parent
    copy = tmp_path / "pythonfmu"
    copy.mkdir()
    for name, data in runtime_pythonfmu({p.name: p.read_bytes() for p in installed.glob("*.py")}).items():
        (copy / name).write_bytes(data)
    printed = {}
    for where, root in (("copy", tmp_path), ("installed", installed.parent)):
        script = f"import sys; sys.path.insert(0, {str(root)!r})\n{SLAVE}"
        done = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True,
                              check=True, cwd=tmp_path)
        printed[where] = done.stdout.splitlines()
    assert printed["copy"][0] == str(copy / "__init__.py")
    assert printed["installed"][0] == str(installed / "__init__.py")
    assert printed["copy"][1] == printed["installed"][1]
    assert 'name="x"' in printed["copy"][1] and "<String" in printed["copy"][1]
