# SPDX-License-Identifier: BSD-2-Clause
"""The FMUs on Windows: every FMU's binaries/win64 (FMI 3.0: x86_64-windows) run under wine64 in a
fresh prefix with no Python, as a Windows colleague receives them, unpacked in a folder with spaces
and non-ASCII characters, and compared with the Linux binaries of the same FMU driven by the same
calls (the same C host source built for Linux; fmpy on Linux for FMPy on Windows): equal to the
bit, since the FMUs compute exp, sin, cos and pow with controller/fmath, not the C runtime's libm.

Hosts: the C plan host (tests/fmu_plan_host.c) cross-compiled as a console program and as a GUI
program (no console, no standard handles), with every FMU in one process (and a second instance
of one), and with a Python of its own already embedded; FMPy 0.3.32 on python.org's embeddable
CPython 3.11.9 under wine (tests/windows/fmpy-requirements.txt); an exported scenario in both.

``make test`` runs one real case of each kind; ``make windows-matrix`` (FTC_WINDOWS_ALL=1) every
FMU x host and every scenario, and writes docs/fmus/windows-matrix.md. One wine prefix per test
session (one xdist group), made by wineboot."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from xml.etree import ElementTree

import fmpy
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "windows"))
import hostile  # noqa: E402
from wine import (  # noqa: E402
    MINGW,
    TOLERANCE,
    USER_FOLDER,
    WINE,
    Difference,
    Item,
    Run,
    Wine,
    compare,
    difference,
    item,
    make_prefix,
    missing,
    run_linux,
    run_windows,
    stop,
    unpack,
)

from fmu_src.toolchain import runtime_win64
from fmu_src.toolchain.build import FMU_SCRIPTS, buildable_platforms
from orchestrator.export import export  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
ALL = os.environ.get("FTC_WINDOWS_ALL") == "1"
MATRIX = REPO / "docs" / "fmus" / "windows-matrix.md"
MATRIX_STATE = REPO / "build" / "windows" / "matrix.json"  # the results of make windows-matrix so far
FMPY_REQUIREMENTS = REPO / "tests" / "windows" / "fmpy-requirements.txt"
FMPY_TARGET = REPO / "build" / "windows" / "fmpy"  # pip install --target of the Windows wheels
STEPS, H = 200, 1e-3
MODELS = tuple(FMU_SCRIPTS)  # the nine FMUs
WIN64, NO_WIN64 = buildable_platforms()  # without mingw-w64 and osslsigncode the build makes linux64 only
pytestmark = [pytest.mark.system, pytest.mark.xdist_group("wine"),
              pytest.mark.skipif(missing() is not None, reason=missing() or ""),
              pytest.mark.skipif("win64" not in WIN64, reason=NO_WIN64)]

results: dict[tuple[str, str], str] = {}  # (row, column) of the matrix -> cell
scenario_results: dict[str, str] = {}


@pytest.fixture(scope="module")
def wine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Wine]:
    """The session's wine prefix: a Windows machine with no Python installed."""
    made = make_prefix(tmp_path_factory.mktemp("wine"))
    assert not [p for p in made.drive_c.rglob("python*") if p.suffix.lower() in (".exe", ".dll")]
    yield made
    stop(made)
    if ALL:
        write_matrix()


def place(wine: Wine, fmu: Path, name: str, linux_root: Path) -> Path:
    """``fmu`` unpacked for Windows under the user's folder (spaces, non-ASCII) and for Linux under
    ``linux_root``, both as ``name``; the Windows folder."""
    unpack(fmu, linux_root / name)
    return unpack(fmu, wine.drive_c / USER_FOLDER / name)


def plan(wine: Wine, fmus: dict[str, Path], models: tuple[str, ...], linux_root: Path,
         suffix: str = "") -> list[Item]:
    return [item(model, place(wine, fmus[model], model + suffix, linux_root), STEPS, H) for model in models]


def check(found: Difference) -> None:
    print(found.text())
    assert found.values > 0
    assert found.largest <= TOLERANCE, found.text()


def c_host_case(wine: Wine, items: list[Item], linux_root: Path, gui: bool, python: str | None = None,
                files: bool = False) -> Difference:
    windows = run_windows(wine, items, gui=gui, python=python, files=files)
    assert windows.status == 0 and windows.done, windows.problem()
    linux = run_linux(wine, items, linux_root)
    assert linux.status == 0 and linux.done, linux.problem()
    return compare(windows, linux)


def test_console_host_every_fmi2_fmu_in_one_process(wine: Wine, fmus: dict[str, Path],
                                                    tmp_path: Path) -> None:
    """The nine FMI 2.0 FMUs and a second FixedTimeController instance in one console process,
    resources given as file:///C:/users/J%C3%BCrgen%20M%C3%BCller/... URIs, the host's output
    redirected to files (where python.exe itself stops at start under wine)."""
    items = plan(wine, fmus, MODELS, tmp_path)
    first = next(i for i in items if i.label == "FixedTimeController")
    items.append(dataclasses.replace(first, label="FixedTimeController2"))  # a second instance
    found = c_host_case(wine, items, tmp_path, gui=False, files=True)
    check(found)
    results[("every FMU in one process", "C host console, FMI 2.0")] = found.text()


def test_an_fmu_runs_from_an_empty_cache(wine: Wine, fmus: dict[str, Path], tmp_path: Path) -> None:
    """python311.dll travels as python311.dll.xz (issue 46): the shim decodes it while copying the
    runtime into an empty %LOCALAPPDATA%/fixed-time-cosim/runtime/ (ftc_cached_copy_decoded). The
    FMU then runs as its Linux binaries do, and the cache holds python.org's python311.dll byte
    for byte (from the pinned package, not the build's output) and no .xz."""
    local = list(wine.drive_c.glob("users/*/AppData/Local"))
    assert local, "the prefix has no %LOCALAPPDATA%"
    for folder in local:
        shutil.rmtree(folder / "fixed-time-cosim", ignore_errors=True)
    items = plan(wine, fmus, ("FixedTimeController",), tmp_path, suffix="_empty_cache")
    check(c_host_case(wine, items, tmp_path, gui=False, files=True))
    decoded = [p for folder in local for p in folder.glob("fixed-time-cosim/runtime/*/python311.dll")]
    assert len(decoded) == 1, decoded
    assert decoded[0].read_bytes() == (runtime_win64.ensure_runtime().embed / "python311.dll").read_bytes()
    assert not [p for folder in local for p in folder.rglob("*.xz")]


def test_without_a_cache_the_runtime_is_decoded_into_temp(wine: Wine, fmus: dict[str, Path],
                                                          tmp_path: Path) -> None:
    """A cache that cannot be written (a file where its folder would be; wine sets LOCALAPPDATA
    from the profile whatever the environment says): the shim decodes the runtime into a new
    folder of %TEMP% (ftc_temporary_copy), the FMU runs as its Linux binaries do, and that folder
    holds python.org's python311.dll byte for byte (left there: a loaded DLL cannot be deleted).
    The copy an ended process left an hour ago is removed first (all of it, subfolders too); one
    of ten seconds ago stays (its process may still run)."""
    local = list(wine.drive_c.glob("users/*/AppData/Local"))
    temps = temp_folders(wine)
    assert local and temps
    ended, young = temps[0] / "fixed-time-cosim-11-12-13", temps[0] / "fixed-time-cosim-21-22-23"
    for copy, age in ((ended, 3600), (young, 10)):
        for name in ("python311.dll", "python311.zip", "Lib/site-packages/x.pyd"):
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            (copy / name).write_bytes(b"left by an ended process")
        then = time.time() - age
        for path in sorted(copy.rglob("*"), reverse=True) + [copy]:
            os.utime(path, (then, then))
    for folder in local:
        shutil.rmtree(folder / "fixed-time-cosim", ignore_errors=True)
        (folder / "fixed-time-cosim").write_text("not a folder", encoding="utf-8")
    try:
        items = plan(wine, fmus, ("Reference",), tmp_path, suffix="_no_cache")
        check(c_host_case(wine, items, tmp_path, gui=False, files=True))
    finally:
        for folder in local:
            (folder / "fixed-time-cosim").unlink()
    assert not ended.exists() and young.is_dir()
    shutil.rmtree(young)
    copies = [p for temp in temps for p in temp.glob("fixed-time-cosim-*")]
    assert len(copies) == 1, copies
    original = (runtime_win64.ensure_runtime().embed / "python311.dll").read_bytes()
    assert (copies[0] / "python311.dll").read_bytes() == original
    assert not list(copies[0].glob("*.xz"))
    shutil.rmtree(copies[0])  # the process has ended


def test_a_corrupted_python311_dll_xz_is_one_message(wine: Wine, fmus: dict[str, Path],
                                                      tmp_path: Path) -> None:
    """One byte of python311.dll.xz flipped, an empty cache: the instantiation returns NULL after one
    message naming the file (the host exits with 3, no crash), and nothing of it is cached."""
    local = list(wine.drive_c.glob("users/*/AppData/Local"))
    for folder in local:
        shutil.rmtree(folder / "fixed-time-cosim", ignore_errors=True)
    [broken] = plan(wine, fmus, ("Actuator",), tmp_path, suffix="_corrupted")
    packed = broken.folder / "binaries" / "win64" / "python" / "python311.dll.xz"
    data = bytearray(packed.read_bytes())
    data[len(data) // 2] ^= 0x01
    packed.write_bytes(bytes(data))
    run = run_windows(wine, [broken], files=True)
    assert run.status == 3, run.problem()
    text = "\n".join(run.messages)
    assert "Actuator: cannot decode the bundled python311.dll: " in text, text
    assert "python311.dll.xz: corrupt xz data" in text, text
    assert not [p for folder in local for p in folder.rglob("python311.dll")]


def test_gui_host_every_fmi3_fmu(wine: Wine, built: Path, tmp_path: Path) -> None:
    """The nine FMI 3.0 FMUs in one GUI-subsystem process without standard handles (resource
    paths native: C:\\users\\Jürgen Müller\\...)."""
    fmus3 = {p.stem: p for p in (built / "fmus3").glob("*.fmu")}
    items = plan(wine, fmus3, MODELS, tmp_path, suffix="3")
    windows = run_windows(wine, items, gui=True)
    assert any("GUI host: console window none" in m for m in windows.messages), windows.messages
    assert windows.status == 0 and windows.done, windows.problem()
    found = compare(windows, run_linux(wine, items, tmp_path))
    check(found)
    results[("every FMU in one process", "C host GUI, FMI 3.0")] = found.text()


def test_host_with_its_own_python(wine: Wine, fmus: dict[str, Path], tmp_path: Path) -> None:
    """A host that embeds python.org's CPython 3.11 (started before any FMU is loaded): the FMUs
    run on that interpreter (their modules are in its sys.modules), with the same results."""
    embed = REPO / "build" / "runtime" / "win64" / "root" / "embed"
    own = wine.drive_c / "Program Files" / "Host App" / "python"
    shutil.rmtree(own, ignore_errors=True)
    shutil.copytree(embed, own)
    items = plan(wine, fmus, ("Actuator", "PendulumPlant"), tmp_path)
    own_python = wine.windows_path(own / "python311.dll")
    found = c_host_case(wine, items, tmp_path, gui=False, python=own_python)
    check(found)
    imported = (wine.drive_c / "plan.out.python").read_text(encoding="utf-8").split()
    assert any(m.startswith("ftc_actuator_") for m in imported), imported
    assert any(m.startswith("ftc_pendulumplant_") for m in imported), imported
    row = "Actuator, PendulumPlant in a host with its own Python"
    results[(row, "C host console, FMI 2.0")] = found.text()


@pytest.fixture(scope="module")
def windows_python(wine: Wine) -> Path:
    """python.org's embeddable CPython 3.11.9 in the prefix (C:/python), with FMPy and its
    dependencies' Windows wheels (tests/windows/fmpy-requirements.txt) on its path."""
    if not (FMPY_TARGET / "fmpy").is_dir():
        command = [sys.executable, "-m", "pip", "install", "--quiet", "--target", str(FMPY_TARGET),
                   "--platform", "win_amd64", "--python-version", "3.11", "--implementation", "cp",
                   "--only-binary=:all:", "--no-deps", "-r", str(FMPY_REQUIREMENTS)]
        result = subprocess.run(command, capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, result.stderr[-2000:]
    python = wine.drive_c / "python"
    shutil.rmtree(python, ignore_errors=True)
    shutil.copytree(REPO / "build" / "runtime" / "win64" / "root" / "embed", python)
    target = "Z:" + str(FMPY_TARGET).replace("/", "\\")
    (python / "python311._pth").write_text(f"python311.zip\n.\n{target}\n", encoding="utf-8")
    return python


FMPY_SCRIPT = """
import json, sys
import fmpy
jobs, out = json.load(open(sys.argv[1], encoding="utf-8")), {}
for name, path, stop, step in jobs:
    result = fmpy.simulate_fmu(path, stop_time=stop, output_interval=step, step_size=step)
    out[name] = [list(result.dtype.names)] + [[float(v) for v in row] for row in result]
json.dump(out, open(sys.argv[2], "w", encoding="utf-8"))
"""


def temp_folders(wine: Wine) -> list[Path]:
    """The prefix's %TEMP% folders (one per user), where FMPy unpacks each FMU."""
    return list(wine.drive_c.glob("users/*/Temp"))


def size_of(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


def fmpy_case(wine: Wine, python: Path, jobs: list[tuple[str, Path, float, float]]) -> dict[str, Difference]:
    """FMPy under wine on each (name, FMU, stop time, step) against fmpy on Linux: the difference
    per job."""
    folder = wine.drive_c / USER_FOLDER / "fmpy"
    folder.mkdir(parents=True, exist_ok=True)
    listing = []
    for name, fmu, stop_time, step in jobs:
        copy = folder / fmu.name
        shutil.copyfile(fmu, copy)
        listing.append((name, wine.windows_path(copy), stop_time, step))
    (wine.drive_c / "fmpy_jobs.json").write_text(json.dumps(listing), encoding="utf-8")
    (wine.drive_c / "fmpy_run.py").write_text(FMPY_SCRIPT, encoding="utf-8")
    out = wine.drive_c / "fmpy_out.json"
    out.unlink(missing_ok=True)
    for temp in temp_folders(wine):
        shutil.rmtree(temp)
        temp.mkdir()
    result = wine.run(wine.windows_path(python / "python.exe"), "C:/fmpy_run.py", "C:/fmpy_jobs.json",
                      "C:/fmpy_out.json")
    assert result.returncode == 0 and out.is_file(), (result.stdout + result.stderr)[-3000:]
    # fmpy deletes each FMU's folder after its run: the shim loads nothing from it (its runtime,
    # pythonfmu's binary and the model's resources are copies in the user's cache), nor does a
    # container (its embedded FMUs' binaries are copies there too), so no library of an FMU is left
    left = sorted(p.relative_to(temp).as_posix() for temp in temp_folders(wine) for p in temp.rglob("*.dll"))
    assert not left, left
    windows = json.loads(out.read_text(encoding="utf-8"))
    differences = {}
    for name, fmu, stop_time, step in jobs:
        linux = fmpy.simulate_fmu(str(fmu), stop_time=stop_time, output_interval=step, step_size=step)
        assert windows[name][0] == list(linux.dtype.names), name
        w = np.array(windows[name][1:], dtype=float)
        lin = np.array([[float(v) for v in row] for row in linux], dtype=float)
        assert w.shape == lin.shape and (w[:, 0] == lin[:, 0]).all(), name
        differences[name] = difference(windows[name][0][1:], w[:, 0], w[:, 1:], lin[:, 1:])
    return differences


def test_fmpy_on_windows(wine: Wine, windows_python: Path, fmus: dict[str, Path], built: Path,
                         tmp_path: Path) -> None:
    """FMPy on python.org's Python under wine (a Python host: the FMUs run on its interpreter)
    simulates each FMI 2.0 FMU and an exported scenario, as fmpy on Linux does."""
    scenario, _ = export(built / "ssp" / "example1.ssp", tmp_path / "Example1Scenario.fmu")
    jobs = [(m, fmus[m], STEPS * H, H) for m in MODELS] + [("example1 (exported)", scenario, 0.5, 1e-3)]
    for name, found in fmpy_case(wine, windows_python, jobs).items():
        check(found)
        results[(name, "FMPy 0.3.32 on Windows, FMI 2.0")] = found.text()


def test_fmpy_leaves_nothing_behind(wine: Wine, windows_python: Path, fmus: dict[str, Path],
                                    tmp_path: Path) -> None:
    """FMPy's simulate_fmu deletes the folder it unpacked each FMU into after FreeInstance and
    FreeLibrary: ten runs of two FMUs (FMI 2.0, one process) leave 0 bytes in %TEMP%, each run gives
    the Linux result, and the user's cache holds one copy of each set of files (the runtime, each
    pythonfmu binary, each resources folder), reused by every run. Before (main 633067d): 8.5 MB
    left per run (the shim loaded its DLLs from the unpacked folder and kept them undeletable)."""
    cache = next(iter(wine.drive_c.glob("users/*/AppData/Local"))) / "fixed-time-cosim"
    shutil.rmtree(cache, ignore_errors=True)
    jobs = [(f"{m} run {k}", fmus[m], 50 * H, H) for k in range(10) for m in ("Actuator", "PendulumPlant")]
    for name, found in fmpy_case(wine, windows_python, jobs).items():
        assert found.largest <= TOLERANCE, (name, found.text())
    assert [size_of(temp) for temp in temp_folders(wine)] == [0]
    entries = sorted(p.name for p in (cache / "runtime").iterdir())
    assert len(entries) == 5, entries  # one runtime, two pythonfmu binaries, two resources folders
    assert all((cache / "runtime" / e / ".complete").is_file() for e in entries)
    results[("Actuator, PendulumPlant, 10 runs each", "FMPy 0.3.32 on Windows, FMI 2.0")] = \
        "0 bytes left in %TEMP%"


def test_fmpy_leaves_nothing_of_a_container(wine: Wine, windows_python: Path, built: Path,
                                            tmp_path: Path) -> None:
    """An exported scenario (FMI 2.0 container of three FMI 2.0 FMUs) run ten times by FMPy's
    simulate_fmu in one process: 0 bytes left in %TEMP% (FMPy deletes each unpacked folder after
    FreeInstance and FreeLibrary), each run the Linux result. The container loads its embedded FMUs'
    binaries from a copy in the user's cache and keeps them loaded; the copy is made once for all
    ten runs. Before: 0.46 MB left per run (the embedded shims, loaded from the unpacked folder)."""
    cache = next(iter(wine.drive_c.glob("users/*/AppData/Local"))) / "fixed-time-cosim"
    shutil.rmtree(cache, ignore_errors=True)
    scenario, _ = export(built / "ssp" / "example1.ssp", tmp_path / "Example1Scenario.fmu")
    jobs = [(f"example1 (exported) run {k}", scenario, 50 * H, H) for k in range(10)]
    for name, found in fmpy_case(wine, windows_python, jobs).items():
        assert found.values > 0 and found.largest <= TOLERANCE, (name, found.text())
    assert [size_of(temp) for temp in temp_folders(wine)] == [0]
    entries = list((cache / "runtime").iterdir())
    assert all((e / ".complete").is_file() for e in entries), entries
    made = {e.name: e.stat().st_mtime_ns for e in entries}
    fmpy_case(wine, windows_python, jobs[:1])  # a new process: the same copies, none made again
    assert {e.name: e.stat().st_mtime_ns for e in (cache / "runtime").iterdir()} == made
    results[("example1 (exported), 10 runs", "FMPy 0.3.32 on Windows, FMI 2.0")] = "0 bytes left in %TEMP%"


@pytest.mark.parametrize("name", ["example1", "example1_clocked"])
def test_exported_scenario_in_the_c_host(wine: Wine, built: Path, tmp_path: Path, name: str) -> None:
    """An exported scenario (FMI 3.0 container, its FMUs FMI 2.0 inside; ``_clocked``: the
    controller's FMI 3.0 clocked twin, whose clock the win64 container ticks) in the console host:
    the container loads its FMUs' win64 binaries from its resources, under the user's folder."""
    scenario, _ = export(built / "ssp" / f"{name}.ssp", tmp_path / "Example1Scenario.fmu", fmi="3")
    folder = place(wine, scenario, "Example1Scenario", tmp_path)
    items = [item("example1", folder, 500, 1e-3, set_inputs=False)]
    found = c_host_case(wine, items, tmp_path, gui=False)
    check(found)
    results[(f"{name} (exported)", "C host console, FMI 3.0")] = found.text()


# (folder of built/ or "export", model or FMI version of the exported example1)
HOSTILE_CASES = ([(v, m) for v in ("fmus", "fmus3") for m in MODELS] + [("export", "2"), ("export", "3")]
                 if ALL else [("fmus3", "FixedTimeController")])


@pytest.fixture(scope="module")
def linux_hostile(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The hostile host built for Linux: the oracle of the Windows run."""
    return hostile.compile_host(tmp_path_factory.mktemp("hostile"))


def hostile_pair(wine: Wine, linux_host: Path, fmu: Path, linux_root: Path,
                 ) -> tuple[dict[str, hostile.Outcome], dict[str, hostile.Outcome]]:
    """Every hostile scenario on ``fmu``: by the Windows host under wine (each scenario a process
    of its own) and by the Linux host on the Linux binaries; messages with the folder as <FMU>."""
    windows_folder, arguments = hostile.unpack(fmu, wine.drive_c / "hostile")
    linux_folder, linux_arguments = hostile.unpack(fmu, linux_root)
    arguments[0] = wine.windows_path(windows_folder)
    scenarios = hostile.SCENARIOS + hostile.NONSENSE
    windows, process = hostile.run("C:/hosts/hostile.exe", arguments, scenarios, wrapper=(str(WINE),),
                                   env=wine.env, timeout=1800)
    assert windows, process.stdout[-3000:]
    linux = hostile.run(linux_host, linux_arguments, scenarios)[0]

    def plain(outcomes: dict[str, hostile.Outcome], folder: str, uri: str) -> dict[str, hostile.Outcome]:
        return {name: dataclasses.replace(o, message=o.message.replace(uri, "<FMU>").replace(folder, "<FMU>"))
                for name, o in outcomes.items()}

    return (plain(windows, arguments[0], "file:///" + arguments[0]),
            plain(linux, str(linux_folder), "file://" + str(linux_folder)))


@pytest.mark.parametrize(("version", "model"), HOSTILE_CASES)
def test_hostile_calls_never_crash_a_windows_host(wine: Wine, built: Path, linux_hostile: Path,
                                                  tmp_path: Path, version: str, model: str) -> None:
    """tests/fmu_hostile_host.c cross-compiled, every scenario of issue 30 (NULL and foreign
    resource locations, wrong and NULL GUIDs, no logger, no callbacks, NaN/0/-h/inf steps, calls
    out of state, after an error, a failing model, 50 instances, two threads) and the nonsense calls
    of issue 44 (NULL arrays and entries, counts, times, undeclared capabilities) on the FMU's win64
    binaries, each scenario a Windows process of its own: none ends by an exception, and each call
    answers as the Linux binaries answer it (status, instance, messages and their text, figure)."""
    if version == "export":
        target = tmp_path / "export" / f"example1_{model}.fmu"
        fmu, _ = export(built / "ssp" / "example1.ssp", target, fmi=model)
        row, column = "example1 (exported)", f"hostile calls, FMI {model}.0"
    else:
        fmu = built / version / f"{model}.fmu"
        row, column = model, f"hostile calls, FMI {'2.0' if version == 'fmus' else '3.0'}"
    windows, linux = hostile_pair(wine, linux_hostile, fmu, tmp_path)
    for name in hostile.SCENARIOS + hostile.NONSENSE:
        assert windows[name].exit == "0", (version, model, name, windows[name])
        assert windows[name].null_categories == 0, (name, windows[name])
        assert windows[name] == linux[name], (version, model, name, windows[name], linux[name])
    assert windows["fifty"].extra == 50 and windows["two-threads"].extra == 1
    answered = sum(o.status != -2 for o in windows.values())  # -2: the FMU lacks the variable
    results[(row, column)] = f"{answered} scenarios: no exception, answers as on Linux"


def test_fmath_gives_the_same_bits_on_windows(wine: Wine, tmp_path: Path) -> None:
    """controller/fmath.h built by mingw-w64 with the extensions' flags, run under wine, gives the
    bits of the Linux build and of controller/fmath.py on the arguments of tests/test_fmath.py: the
    reason every FMU above is bit-equal (the C runtimes' exp, sin, cos and pow are not)."""
    from test_fmath import FLAGS, HOST, PYTHON, arguments, host_input, host_results, python_results

    cases = {f: arguments(f, 40_000) for f in PYTHON}
    text = "".join(host_input(f, c) for f, c in cases.items())
    (wine.drive_c / "fmath.txt").write_text(text, encoding="ascii")
    exe = wine.drive_c / "hosts" / "fmath.exe"
    subprocess.run([MINGW, *FLAGS, f"-I{REPO / 'controller'}", "-o", str(exe), str(HOST)], check=True)
    done = wine.run(wine.windows_path(exe), "C:/fmath.txt")
    assert done.returncode == 0, done.stderr
    windows = host_results(done.stdout)
    python = [b for f, c in cases.items() for b in python_results(f, c)]
    assert len(windows) == len(python)
    differing = [(line, f"{a:016x}", f"{b:016x}")
                 for line, a, b in zip(text.splitlines(), windows, python, strict=True) if a != b]
    assert not differing, f"{len(differing)} of {len(python)} differ, Windows against Python: {differing[:5]}"


def test_the_windows_hostile_host_sees_a_crash(wine: Wine) -> None:
    """The Windows host itself: a child whose fmi2Instantiate dereferences NULL (a DLL compiled
    here) is reported with its exception code, the next scenario runs in a fresh process."""
    fmu = wine.drive_c / "crash"
    (fmu / "binaries" / "win64").mkdir(parents=True, exist_ok=True)
    source = fmu / "crash.c"
    source.write_text("__declspec(dllexport) void *fmi2Instantiate(const char *n, int t,\n"
                      "                                              const char *guid) {\n"
                      "    return guid[1] == '0' ? *(void *volatile *)0 : (void *)1;\n}\n"
                      "__declspec(dllexport) void fmi2FreeInstance(void *c) { (void)c; }\n")
    subprocess.run([str(MINGW), "-shared", "-O0", "-o", str(fmu / "binaries" / "win64" / "crash.dll"),
                    str(source)], check=True)
    arguments = [wine.windows_path(fmu), "2", "crash", "{x}", "-1", "-1", "-1"]
    outcomes = hostile.run("C:/hosts/hostile.exe", arguments, ["guid-wrong", "no-callbacks"],
                           wrapper=(str(WINE),), env=wine.env)[0]
    assert outcomes["guid-wrong"].crashed and outcomes["guid-wrong"].exit == "exception 0xc0000005"
    assert outcomes["no-callbacks"].exit == "0" and outcomes["no-callbacks"].status == 0


@pytest.mark.skipif(not ALL, reason="the whole matrix: make windows-matrix")
def test_every_fmu_in_every_host(wine: Wine, windows_python: Path, fmus: dict[str, Path], built: Path,
                                 tmp_path: Path) -> None:
    """Every FMU alone in each C host (console, GUI) for FMI 2.0 and 3.0, and every FMU in FMPy for
    both, under wine against Linux."""
    fmus3 = {p.stem: p for p in (built / "fmus3").glob("*.fmu")}
    for model in MODELS:
        for version, source in (("2.0", fmus), ("3.0", fmus3)):
            for gui in (False, True):
                items = [item(model, place(wine, source[model], f"{model}{version}", tmp_path), STEPS, H)]
                found = c_host_case(wine, items, tmp_path, gui=gui)
                check(found)
                results[(model, f"C host {'GUI' if gui else 'console'}, FMI {version}")] = found.text()
    for version, source in (("2.0", fmus), ("3.0", fmus3)):
        jobs = [(m, source[m], STEPS * H, H) for m in MODELS]
        for name, found in fmpy_case(wine, windows_python, jobs).items():
            check(found)
            results[(name, f"FMPy 0.3.32 on Windows, FMI {version}")] = found.text()


def first_departure(windows: Run, linux: Run) -> str:
    """When the two runs first differ ('' when never)."""
    times = []
    for label, rows in windows.rows.items():
        w, lin = np.array(rows, dtype=float), np.array(linux.rows[label], dtype=float)
        gap = np.abs(w[:, 1:] - lin[:, 1:])
        hit = np.flatnonzero((gap > 0).any(axis=1))
        if hit.size:
            times.append(float(w[hit[0], 0]))
    return f"first differs at t={min(times):g}" if times else ""


@pytest.mark.skipif(not ALL, reason="the whole matrix: make windows-matrix")
def test_every_scenario_exported(wine: Wine, built: Path, tmp_path: Path) -> None:
    """Every scenario exported and run over its whole experiment by the console C host under wine
    against the same host on Linux: each is recorded, then those not equal to the bit fail the test."""
    beyond = []
    for ssp in sorted((built / "ssp").glob("*.ssp")):
        if ssp.stem.endswith(("_fmi3", "_clocked")):
            continue  # the same scenario on FMI 3.0 FMUs (the container embeds FMI 2.0 FMUs, no clocks)
        scenario, _ = export(ssp, tmp_path / f"{ssp.stem}.fmu")
        folder = place(wine, scenario, ssp.stem, tmp_path)
        experiment = ElementTree.parse(folder / "modelDescription.xml").getroot().find("DefaultExperiment")
        assert experiment is not None
        step = float(experiment.get("stepSize", "0.001"))
        start, stop_time = float(experiment.get("startTime", "0")), float(experiment.get("stopTime", "1"))
        steps = round((stop_time - start) / step)
        items = [item(ssp.stem, folder, steps, step, set_inputs=False)]
        windows = run_windows(wine, items)
        assert windows.status == 0 and windows.done, windows.problem()
        linux = run_linux(wine, items, tmp_path)
        assert linux.status == 0 and linux.done, linux.problem()
        found = compare(windows, linux)
        departure = first_departure(windows, linux)
        scenario_results[ssp.stem] = (f"{steps} steps of {step:g} s: {found.text()}"
                                      + (f"; {departure}" if departure else ""))
        if found.largest > TOLERANCE:
            beyond.append(f"{ssp.stem}: {found.text()}")
    assert not beyond, "not bit-equal over the whole experiment: " + "; ".join(beyond)


def write_matrix() -> None:
    """docs/fmus/windows-matrix.md from this session's results merged into those of earlier sessions
    since ``make windows-matrix`` started (kept in build/windows/matrix.json, which it removes
    first), so that a test run again alone completes the page."""
    saved = json.loads(MATRIX_STATE.read_text(encoding="utf-8")) if MATRIX_STATE.is_file() else {}
    for key, text in saved.get("results", []):
        results.setdefault((key[0], key[1]), text)
    for name, text in saved.get("scenarios", {}).items():
        scenario_results.setdefault(name, text)
    MATRIX_STATE.parent.mkdir(parents=True, exist_ok=True)
    MATRIX_STATE.write_text(json.dumps({"results": [[list(k), v] for k, v in results.items()],
                                        "scenarios": scenario_results}), encoding="utf-8")
    columns = sorted({c for _, c in results})
    rows = list(dict.fromkeys(r for r, _ in sorted(results, key=lambda k: (k[0] not in MODELS, k[0]))))
    lines = ["# Windows: every FMU in every host, every scenario (generated)", "",
             "Written by `make windows-matrix` (tests/test_fmu_windows.py, FTC_WINDOWS_ALL=1): each FMU's",
             "Windows binaries under wine64 in a fresh prefix with no Python, unpacked under",
             f"`C:/{USER_FOLDER}/`, against its Linux binaries driven by the same calls (the same C host",
             "built for Linux; fmpy on Linux for FMPy on Windows). A cell says how many output values were",
             "compared and whether they are equal to the bit, else the largest relative difference and",
             "where (the tests require every value equal to the bit). \"hostile calls\": every scenario of",
             "tests/fmu_hostile_host.c, each in a Windows process of its own, against the same host on the",
             "Linux binaries (a scenario needing a variable the FMU lacks is not counted). See",
             "[Windows](windows.md).", "",
             "| FMU | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
    for row in rows:
        lines.append(f"| {row} | " + " | ".join(results.get((row, c), "") for c in columns) + " |")
    lines += ["", "## Every scenario, exported, Windows against Linux", "",
              "Each scenario of ssp/ exported (`orchestrate export`, FMI 2.0), run over its whole",
              "DefaultExperiment by the console C host under wine and by the same host on Linux; every",
              "exposed output at every step compared.", "",
              "| scenario | Windows against Linux |", "|---|---|"]
    lines += [f"| {name} | {text} |" for name, text in sorted(scenario_results.items())]
    MATRIX.write_text("\n".join(lines) + "\n", encoding="utf-8")
