# SPDX-License-Identifier: BSD-2-Clause
"""Windows under wine64 for the tests: a fresh prefix (a Windows colleague's machine: no Python),
the C plan host cross-compiled (console and GUI subsystem) and built for Linux, plans of FMUs
unpacked where a Windows user keeps them (a folder with spaces and non-ASCII characters), and the
comparison of a Windows run with the Linux run of the same plan.

Used by tests/test_fmu_windows.py; ``make windows-matrix`` runs every FMU x host and every scenario
through it and writes docs/fmus/windows-matrix.md."""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

import fmu_src.cbase as cbase

HERE = Path(__file__).resolve().parent
HOST_SOURCE = HERE.parent / "fmu_plan_host.c"
HOSTILE_SOURCES = (HERE.parent / "fmu_hostile_host.c", HERE.parent / "fmu_hostile_nonsense.c")
MINGW = shutil.which("x86_64-w64-mingw32-gcc")
WINE = shutil.which("wine64") or next((p for p in ("/usr/lib/wine/wine64",) if os.access(p, os.X_OK)), None)
WINESERVER = shutil.which("wineserver") or next(
    (p for p in ("/usr/lib/wine/wineserver64", "/usr/lib/wine/wineserver") if os.access(p, os.X_OK)), None)
USER_FOLDER = "users/Jürgen Müller/FMUs für Windows"  # under drive_c: spaces and non-ASCII
TIMEOUT = 600.0  # seconds for one wine process
TOLERANCE = 0.0  # relative: bit-equal (controller/fmath gives exp, sin, cos and pow, not either libm)


def missing() -> str | None:
    """Why the wine tests cannot run here (one reason), or None."""
    if WINE is None or WINESERVER is None:
        return "wine64 is not installed ('make windows-tools' installs Debian's wine64 as root)"
    if MINGW is None:
        return "mingw-w64 is not installed ('make windows-tools' installs gcc-mingw-w64-x86-64 as root)"
    return None


@dataclass
class Wine:
    """One wine prefix, made once per test session, and the hosts compiled into it."""

    prefix: Path
    linux_host: Path
    env: dict[str, str] = field(default_factory=dict)

    @property
    def drive_c(self) -> Path:
        return self.prefix / "drive_c"

    def windows_path(self, path: Path) -> str:
        """C:/... of a path under drive_c."""
        return "C:/" + path.relative_to(self.drive_c).as_posix()

    def run(self, program: str, *args: str, timeout: float = TIMEOUT, files: bool = False
            ) -> subprocess.CompletedProcess[str]:
        """Run a Windows program (a C:/ path) under wine, no standard input, output captured
        through pipes, or (``files``) written to files: under wine a program's redirected files
        lack the right to read their attributes, where CPython's own start stops."""
        if files:
            return run_wine(self.env, self.prefix.parent, [program, *args], timeout)
        return subprocess.run([str(WINE), program, *args], env=self.env, stdin=subprocess.DEVNULL,
                              capture_output=True, text=True, errors="replace", timeout=timeout)


def run_wine(env: dict[str, str], root: Path, args: list[str],
             timeout: float) -> subprocess.CompletedProcess[str]:
    """``wine64 args`` with its standard output and error in files under ``root`` (so for wineboot:
    the services it starts would hold pipes open for the whole session)."""
    out, err = root / "wine.stdout", root / "wine.stderr"
    with out.open("wb") as stdout, err.open("wb") as stderr:
        process = subprocess.run([str(WINE), *args], env=env, stdin=subprocess.DEVNULL, stdout=stdout,
                                 stderr=stderr, timeout=timeout)
    return subprocess.CompletedProcess(process.args, process.returncode, out.read_text(errors="replace"),
                                       err.read_text(errors="replace"))


def make_prefix(root: Path) -> Wine:
    """A new wine prefix under ``root`` (wineboot, no Mono or Gecko), with the plan host
    cross-compiled into C:/hosts/ (console.exe, gui.exe) and built for Linux, and the hostile host
    (tests/fmu_hostile_host.c) into C:/hosts/hostile.exe."""
    prefix = root / "prefix"
    # winedbg disabled: a crashing process then ends at once with its exception code (as on Windows
    # without a debugger) instead of waiting 15 s for wine's debugger to dump it
    # TMPDIR: wine makes its server's folder (wine-XXXXXX) there and leaves it after wineserver -k
    env = {**os.environ, "WINEPREFIX": str(prefix), "WINEDEBUG": "-all", "TMPDIR": str(root / "tmp"),
           "WINEDLLOVERRIDES": "mscoree,mshtml=;winedbg.exe=d", "WINEARCH": "win64"}
    env.pop("DISPLAY", None)
    prefix.mkdir(parents=True)
    (root / "tmp").mkdir()
    # the server first, kept for the session: every wine process then connects to it instead of
    # starting one that would hold the caller's pipes open
    subprocess.run([str(WINESERVER), "-p"], env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, timeout=60, check=True)
    boot = run_wine(env, root, ["wineboot", "-i"], TIMEOUT)
    if boot.returncode != 0:
        raise RuntimeError(f"wineboot failed: {boot.stderr[-2000:]}")
    hosts = prefix / "drive_c" / "hosts"
    hosts.mkdir(parents=True, exist_ok=True)
    common = ["-std=c11", "-O2", "-Wall", "-Wextra", "-municode", f"-I{cbase.FMI_HEADERS}", str(HOST_SOURCE)]
    subprocess.run([str(MINGW), *common, "-o", str(hosts / "console.exe")], check=True, capture_output=True)
    subprocess.run([str(MINGW), *common, "-mwindows", "-DGUI_HOST", "-o", str(hosts / "gui.exe")], check=True,
                   capture_output=True)
    subprocess.run([str(MINGW), "-std=c11", "-O1", "-Wall", "-Wextra", "-municode", f"-I{cbase.FMI_HEADERS}",
                    *map(str, HOSTILE_SOURCES), "-o", str(hosts / "hostile.exe"), "-lpsapi"], check=True,
                   capture_output=True)
    cc = shutil.which("cc") or shutil.which("gcc") or "cc"
    linux_host = root / "linux_host"
    subprocess.run([cc, "-std=c11", "-O2", "-Wall", f"-I{cbase.FMI_HEADERS}", "-o", str(linux_host),
                    str(HOST_SOURCE), "-ldl"],
                   check=True, capture_output=True)
    return Wine(prefix, linux_host, env)


def stop(wine: Wine) -> None:
    """End the session's wineserver (and with it every wine process of the prefix)."""
    subprocess.run([str(WINESERVER), "-k"], env=wine.env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, timeout=60)


def unpack(fmu: Path, folder: Path) -> Path:
    """``fmu`` unpacked into ``folder`` (made anew)."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    return folder


@dataclass(frozen=True)
class Item:
    """One FMU of a plan: label, FMI version, unpacked folder, model identifier, token, steps,
    step size, values set (vr -> value) and value references read."""

    label: str
    fmi: str
    folder: Path
    model: str
    token: str
    steps: int
    step: float
    sets: tuple[tuple[int, float], ...]
    gets: tuple[int, ...]


def item(label: str, folder: Path, steps: int, step: float, set_inputs: bool = True) -> Item:
    """A plan item for the FMU unpacked in ``folder``: every real input set to a fixed value
    (0.1, 0.2, ... in the description's order; none for an exported scenario, whose unconnected
    inputs keep their start values), every real output read."""
    root = ElementTree.parse(folder / "modelDescription.xml").getroot()
    fmi = "3" if root.get("fmiVersion", "").startswith("3") else "2"
    if fmi == "3":
        listed = root.find("ModelVariables")
        assert listed is not None
        variables = [(v.get("causality"), int(v.get("valueReference", "0")))
                     for v in listed if v.tag == "Float64"]
        cosim = root.find("CoSimulation")
        token = root.get("instantiationToken", "")
    else:
        variables = [(v.get("causality"), int(v.get("valueReference", "0")))
                     for v in root.iter("ScalarVariable") if v.find("Real") is not None]
        cosim = root.find("CoSimulation")
        token = root.get("guid", "")
    assert cosim is not None
    inputs = [vr for causality, vr in variables if causality == "input"] if set_inputs else []
    outputs = [vr for causality, vr in variables if causality == "output"]
    sets = tuple((vr, round(0.1 * (k + 1), 1)) for k, vr in enumerate(inputs))
    model = cosim.get("modelIdentifier", "")
    return Item(label, fmi, folder, model, token, steps, step, sets, tuple(outputs))


def plan_text(items: list[Item], path_of: object, python: str | None = None) -> str:
    """The plan host's plan (``path_of``: folder -> the path the host sees)."""
    lines = [f"python\t{python}"] if python else []
    for i in items:
        sets = " ".join(f"{vr}={value!r}" for vr, value in i.sets)
        gets = " ".join(str(vr) for vr in i.gets)
        folder = path_of(i.folder)  # type: ignore[operator]
        lines.append(f"fmu\t{i.label}\t{i.fmi}\t{folder}\t{i.model}\t{i.token}\t{i.steps}\t{i.step!r}\t{sets}\t{gets}")
    return "\n".join(lines) + "\n"


@dataclass
class Run:
    """A plan host's run: exit status, rows (label -> list of (time, values)), messages."""

    status: int
    rows: dict[str, list[list[float]]]
    messages: list[str]
    done: bool

    def problem(self) -> str:
        return f"exit status {self.status}, done {self.done}; messages: {self.messages[-5:]}"


def parse(status: int, text: str) -> Run:
    rows: dict[str, list[list[float]]] = {}
    messages, done = [], False
    for line in text.splitlines():
        if line.startswith("#"):
            messages.append(line)
        elif line == "done":
            done = True
        elif line:
            label, *values = line.split(" ")
            rows.setdefault(label, []).append([float(v) for v in values])
    return Run(status, rows, messages, done)


def run_windows(wine: Wine, items: list[Item], gui: bool = False, python: str | None = None,
                name: str = "plan", files: bool = False) -> Run:
    """The plan run by the console or GUI host under wine (``files``: its standard output and
    error redirected to files, see :meth:`Wine.run`)."""
    plan, out = wine.drive_c / f"{name}.txt", wine.drive_c / f"{name}.out"
    plan.write_text(plan_text(items, wine.windows_path, python), encoding="utf-8")
    out.unlink(missing_ok=True)
    host = "C:/hosts/gui.exe" if gui else "C:/hosts/console.exe"
    result = wine.run(host, wine.windows_path(plan), wine.windows_path(out), files=files)
    text = (out.read_text(encoding="utf-8", errors="replace") if out.is_file()
            else result.stdout + result.stderr)
    return parse(result.returncode, text)


def run_linux(wine: Wine, items: list[Item], where: Path) -> Run:
    """The same plan run by the Linux build of the host on the Linux copies of the FMUs
    (``item.folder`` mapped to ``where``/<label>)."""
    plan, out = where / "plan.txt", where / "plan.out"
    plan.write_text(plan_text(items, lambda folder: str(where / folder.name)), encoding="utf-8")
    result = subprocess.run([str(wine.linux_host), str(plan), str(out)], capture_output=True, text=True,
                            timeout=TIMEOUT)
    text = out.read_text(encoding="utf-8") if out.is_file() else result.stdout + result.stderr
    return parse(result.returncode, text)


@dataclass(frozen=True)
class Difference:
    """Windows against Linux: values compared, how many equal to the bit, the largest difference
    relative to the output's magnitude over the run (max |value| of that output) and where (label
    or output, time), and the largest pointwise relative difference (which a value near a zero
    crossing inflates)."""

    values: int
    equal: int
    largest: float
    where: str
    pointwise: float = 0.0

    def text(self) -> str:
        if self.equal == self.values:
            return f"bit-equal ({self.values} values)"
        return (f"{self.equal}/{self.values} bit-equal; largest difference {self.largest:.1e} of the "
                f"output's magnitude ({self.where}; pointwise {self.pointwise:.1e})")


def difference(names: list[str], times: np.ndarray, windows: np.ndarray, linux: np.ndarray) -> Difference:
    """The :class:`Difference` of two equally shaped tables (rows: times; columns: ``names``)."""
    assert windows.shape == linux.shape, (windows.shape, linux.shape)
    equal = (windows == linux) | (np.isnan(windows) & np.isnan(linux))
    gap = np.where(equal, 0.0, np.abs(windows - linux))
    magnitude = np.maximum(np.nanmax(np.abs(windows), axis=0, initial=0.0), np.nanmax(np.abs(linux), axis=0,
                                                                                    initial=0.0))
    scaled = gap / np.where(magnitude > 0, magnitude, 1.0)
    point = np.maximum(np.abs(windows), np.abs(linux))
    pointwise = gap / np.where(point > 0, point, 1.0)
    worst = np.unravel_index(int(np.argmax(scaled)), scaled.shape) if scaled.size else (0, 0)
    where = f"{names[worst[1]]} t={times[worst[0]]:g}" if scaled.size else ""
    return Difference(int(windows.size), int(equal.sum()), float(scaled.max(initial=0.0)), where,
                      float(pointwise.max(initial=0.0)))


def compare(windows: Run, linux: Run) -> Difference:
    """Every value of every row of the two runs; AssertionError when their shapes differ."""
    assert windows.rows.keys() == linux.rows.keys(), (windows.rows.keys(), linux.rows.keys())
    parts = []
    for label, rows in windows.rows.items():
        w, lin = np.array(rows, dtype=float), np.array(linux.rows[label], dtype=float)
        assert w.shape == lin.shape and (w[:, 0] == lin[:, 0]).all(), label
        names = [f"{label} output {k}" for k in range(1, w.shape[1])]
        parts.append(difference(names, w[:, 0], w[:, 1:], lin[:, 1:]))
    worst = max(parts, key=lambda d: d.largest)
    return Difference(sum(d.values for d in parts), sum(d.equal for d in parts), worst.largest, worst.where,
                      max(d.pointwise for d in parts))
