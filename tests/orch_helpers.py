# SPDX-License-Identifier: BSD-2-Clause
"""Helpers for the orchestrator tests: build small pythonfmu FMUs and SSP scenarios around them."""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

FMU_SCRIPTS = Path(__file__).parent / "fmus"
BASELINE_DIR = Path(__file__).parent / "baselines"  # this project's regression baselines and tubes
PYTHONFMU = Path(sys.executable).with_name("pythonfmu")

# ModelStructure dependencies pythonfmu does not write: output -> inputs it depends on (by name)
DEPENDENCIES = {"Source": {"y": []}, "Gain": {"y": ["u"]}, "Integrator": {"x": []}, "Faulty": {"y": []}}


def build_test_fmu(name: str, dest: Path) -> Path:
    """Build tests/fmus/<name>.py into dest/<name>.fmu and add its output dependencies."""
    dest.mkdir(parents=True, exist_ok=True)
    subprocess.run([str(PYTHONFMU), "build", "-f", str(FMU_SCRIPTS / f"{name}.py"), "--handle-state",
                    "-d", str(dest)], check=True, capture_output=True)
    fmu = dest / f"{name}.fmu"
    with zipfile.ZipFile(fmu) as zf:
        files = {i.filename: zf.read(i) for i in zf.infolist()}
    xml = files["modelDescription.xml"].decode()
    index = {m.group(1): str(n + 1) for n, m in enumerate(re.finditer(r'<ScalarVariable name="(\w+)"', xml))}
    for output, inputs in DEPENDENCIES[name].items():
        deps = " ".join(index[i] for i in inputs)
        xml = xml.replace(f'<Unknown index="{index[output]}"/>',
                          f'<Unknown index="{index[output]}" dependencies="{deps}"/>')
    files["modelDescription.xml"] = xml.encode()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        for filename, data in files.items():
            zf.writestr(filename, data)
    return fmu


def loop_scenario(folder: Path, fmus: dict[str, Path], gain: float = -2.0, x0: float = 1.0,
                  factor: float | None = None, offset: float | None = None, fail_at: float = 1e300,
                  stop: float = 1.0, step: float | None = 0.01, pack: bool = True) -> Path:
    """integrator.x -> gain.u, gain.y -> integrator.u (x' = gain * x), plus a free sine source.

    Returns the packed .ssp (or the folder when ``pack`` is False; the FMUs are then copied in).
    """
    components = (
        component("source", "Source.fmu", [("y", "output", "Real")], {"amplitude": 2.0, "omega": 3.0}),
        component("gain", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": gain}),
        component("integrator", "Integrator.fmu", [("u", "input", "Real"), ("x", "output", "Real")],
                  {"x0": x0, "fail_at": fail_at}),
    )
    connections = (Connection.between("integrator.x", "gain.u"),
                   Connection.between("gain.y", "integrator.u", 1.0 if factor is None else factor,
                                      0.0 if offset is None else offset))
    write_ssd(folder, SystemStructure("loop", components, connections, Experiment(0.0, stop, step)))
    files = {f"{n}.fmu": fmus[n] for n in ("Source", "Gain", "Integrator")}
    if not pack:
        (folder / "resources").mkdir(exist_ok=True)
        for name, path in files.items():
            (folder / "resources" / name).write_bytes(path.read_bytes())
        return folder
    return pack_ssp(folder, files, folder.parent / f"{folder.name}.ssp")


def without_start(fmu: Path, variable: str, dest: Path) -> Path:
    """Copy of ``fmu`` whose variable has no start value (not FMI-compliant for an input: for tests
    of the 'input neither connected nor started' check)."""
    with zipfile.ZipFile(fmu) as zf:
        files = {i.filename: zf.read(i) for i in zf.infolist()}
    xml = files["modelDescription.xml"].decode()
    pattern = rf'(<ScalarVariable name="{variable}"[^>]*>\s*<Real) start="[^"]*"'
    files["modelDescription.xml"] = re.sub(pattern, r"\1", xml).encode()
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
        for filename, data in files.items():
            zf.writestr(filename, data)
    return dest


def zip_members(archive: Path) -> dict[str, bytes]:
    """Every member of a zip file (an SSP, an FMU), name -> bytes."""
    with zipfile.ZipFile(archive) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


def write_zip(path: Path, members: dict[str, bytes]) -> Path:
    """A zip file of ``members`` (name -> bytes), deflated."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path
