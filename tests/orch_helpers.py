# SPDX-License-Identifier: BSD-2-Clause
"""Helpers for the orchestrator tests: build small pythonfmu FMUs and SSP scenarios around them."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
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


class DaskCluster:
    """A real ``dask scheduler`` and ``workers`` single-threaded ``dask worker`` processes (each with
    its nanny) on localhost, free ports, logging to ``folder/dask.log``; ``stop`` kills them."""

    def __init__(self, folder: Path, workers: int) -> None:
        self.folder = folder
        self.log = open(folder / "dask.log", "a")  # noqa: SIM115 (closed in stop)
        scheduler_file = folder / "scheduler.json"
        scheduler_file.unlink(missing_ok=True)
        self.scheduler = self._start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                     "--scheduler-file", str(scheduler_file))
        self.workers: list[subprocess.Popen] = []
        try:
            self.address = self._address(scheduler_file)
            self.workers = [self._start("worker", self.address, "--nthreads", "1", "--no-dashboard",
                                        "--local-directory", str(folder / f"w{i}")) for i in range(workers)]
            from distributed import Client

            with Client(self.address, timeout="30s") as client:
                client.wait_for_workers(workers, timeout=60)
        except BaseException:
            self.stop()
            raise

    def _start(self, *args: str) -> subprocess.Popen:
        # TMPDIR: the scheduler makes dask-scratch-space there and leaves it
        return subprocess.Popen([str(Path(sys.executable).with_name("dask")), *args], stdout=self.log,
                                stderr=self.log, env={**os.environ, "TMPDIR": str(self.folder)})

    def _address(self, scheduler_file: Path) -> str:
        """The address the scheduler wrote, once the file holds all of its JSON: it appears before
        its content does (seen on a loaded CI machine as an empty file)."""
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and self.scheduler.poll() is None:
            try:
                return str(json.loads(scheduler_file.read_text())["address"])
            except (OSError, ValueError, KeyError):
                time.sleep(0.05)
        raise AssertionError(f"the scheduler wrote no address to {scheduler_file} (exit "
                             f"{self.scheduler.poll()}; log {self.folder / 'dask.log'})")

    def stop(self) -> None:
        """Kill the workers and the scheduler (SIGKILL: a clean close takes seconds) and wait."""
        for p in [*self.workers, self.scheduler]:
            if p.poll() is None:
                p.send_signal(signal.SIGKILL)
            p.wait(timeout=30)
        self.log.close()
