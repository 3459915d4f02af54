# SPDX-License-Identifier: BSD-2-Clause
"""The FMUs in a host without Python: a minimal C importer (tests/fmu_c_host.c) dlopens each FMU's
binaries/linux64/<model>.so, as C/C++ tools do, on a colleague's machine (tests/colleague.py: every
Python of this machine hidden, ``env -i PATH=/usr/bin:/bin``; only ``env -i`` where the kernel
refuses mount namespaces). The FMI shim (fmu_src/toolchain/shim/) must start the runtime the FMU carries, or
fail with one message. Values are checked against closed forms and solve_ivp, written out here or
in fmu_helpers, and bit for bit against the same calls made from fmpy in this process."""

from __future__ import annotations

import ctypes
import glob
import math
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmu_helpers import (
    dead_zone_formula,
    example1,
    open_slave,
    pendulum,
    reference_formula,
    solve_held,
    uf_formula,
)

import fmu_src.cbase as cbase
from orchestrator.crosscheck.colleague import hidden, refusal

CC = shutil.which("cc") or shutil.which("gcc")
CLEAN_ENV = {"PATH": "/usr/bin:/bin"}
STEPS, H = 100, 1e-3
T = STEPS * H
COLLEAGUE = refusal() is None  # else: env -i on this machine, its Pythons visible
MALLOC_DEBUG = Path("/lib/x86_64-linux-gnu/libc_malloc_debug.so.0")  # glibc's checking allocator
pytestmark = [pytest.mark.system, pytest.mark.skipif(CC is None, reason="needs a C compiler for the host")]


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("c_host") / "host"
    source = Path(__file__).with_name("fmu_c_host.c")
    subprocess.run([CC, "-O1", "-Wall", f"-I{cbase.FMI_HEADERS}", "-o", str(out), str(source), "-ldl"],
                   check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def parallel_host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("c_host") / "parallel_host"
    source = Path(__file__).with_name("fmu_c_host_parallel.c")
    command = [CC, "-O1", "-Wall", f"-I{cbase.FMI_HEADERS}", "-o", str(out), str(source), "-ldl", "-pthread"]
    subprocess.run(command, check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def unzipped(fmus: dict, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Each FMU extracted once, model name -> folder."""
    root = tmp_path_factory.mktemp("unzipped")
    for model, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(root / model)
    return {model: root / model for model in fmus}


def run_host(
    host: Path, folder: Path, sets: dict[str, float], gets: list[str], env: dict[str, str] | None = None
) -> tuple[subprocess.CompletedProcess, dict[str, float]]:
    """Run the C host on an extracted FMU for STEPS steps of H; returns the process and the values read."""
    md = fmpy.read_model_description(str(folder))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    binary = folder / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    command = [str(host), str(binary), (folder / "resources").as_uri(), md.guid, str(STEPS), repr(H)]
    command += [f"{vr[name]}={value!r}" for name, value in sets.items()] + [str(vr[name]) for name in gets]
    return collect(host_run(command, env), vr, gets)


def host_run(
    command: list[str], env: dict[str, str] | None = None, also: tuple[str, ...] = ()
) -> subprocess.CompletedProcess:
    """``command`` on a colleague's machine with ``env`` (PATH=/usr/bin:/bin plus what is given),
    the files ``also`` hidden too."""
    extra = {k: v for k, v in (env or {}).items() if k != "PATH"}
    if COLLEAGUE:
        return subprocess.run(hidden(command, extra, also), capture_output=True, text=True, timeout=120)
    return subprocess.run(command, env=CLEAN_ENV | extra, capture_output=True, text=True, timeout=120)


def collect(
    result: subprocess.CompletedProcess, vr: dict[str, int], gets: list[str]
) -> tuple[subprocess.CompletedProcess, dict[str, float]]:
    pairs = (line.split() for line in result.stdout.splitlines())
    by_vr = {int(k): float(v) for k, v in pairs if k.isdigit()}
    return result, {name: by_vr[vr[name]] for name in gets if vr[name] in by_vr}


def check_ok(result: subprocess.CompletedProcess) -> None:
    assert result.returncode == 0, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    assert "status 0" in result.stdout


def test_reference(host: Path, unzipped: dict) -> None:
    p = {"amplitude": 1.5, "omega": 2.0, "phase": 0.3, "offset": -0.2}
    result, got = run_host(host, unzipped["Reference"], p, ["yd", "yd_dot", "yd_ddot"])
    check_ok(result)
    expected = reference_formula(T, **p)
    np.testing.assert_allclose([got["yd"], got["yd_dot"], got["yd_ddot"]], expected, rtol=0, atol=1e-14)


def test_fixed_time_controller(host: Path, unzipped: dict) -> None:
    """x1 = yd = 0.5 held, everything else 0: z1 = 0, so zeta1 = z2 = v = 0 and the adaptive laws
    and the dynamic signal decay in closed form (SPEC section 1):
    eta_i(t) = eta_i0 exp(-(rho_i + rho_bar_i) t), r(t) = r_inf + (r0 - r_inf) exp(-a_bar t)
    with r_inf = (gamma_gain x1^4 + d_r) / a_bar."""
    p = {"rho1": 0.5, "rho_bar1": 0.25, "rho2": 1.0, "rho_bar2": 0.5, "eta1_0": 0.3, "eta2_0": 0.2}
    p |= {"a_bar": 2.0, "gamma_gain": 2.5, "gamma_power": 4.0, "d_r": 0.625, "r0": 0.1}
    inputs = {"x1": 0.5, "x2": 0.0, "yd": 0.5, "yd_dot": 0.0, "yd_ddot": 0.0}
    outputs = ["v", "z1", "z2", "zeta1", "eta1_hat", "eta2_hat", "r"]
    result, got = run_host(host, unzipped["FixedTimeController"], p | inputs, outputs)
    check_ok(result)
    assert [got["v"], got["z1"], got["z2"], got["zeta1"]] == [0.0, 0.0, 0.0, 0.0]
    assert got["eta1_hat"] == pytest.approx(0.3 * math.exp(-0.75 * T), rel=1e-12)
    assert got["eta2_hat"] == pytest.approx(0.2 * math.exp(-1.5 * T), rel=1e-12)
    r_inf = (2.5 * 0.5**4 + 0.625) / 2.0
    assert got["r"] == pytest.approx(r_inf + (0.1 - r_inf) * math.exp(-2.0 * T), rel=1e-12)


def test_actuator(host: Path, unzipped: dict) -> None:
    """Faulted from 0.05 s: uf at 0.1 s with inputs held, against SPEC section 2 written out."""
    p = {"m_r": 1.1, "m_l": 1.3, "b_r": 0.4, "b_l": 0.7, "K_inf": 0.5, "K_amp": 0.3, "K_rate": 2.0}
    p |= {"L_gain": 0.8, "L_bias": 0.05, "t_fault": 0.05}
    inputs = {"v": 1.7, "x1": 0.4, "x2": -0.3}
    result, got = run_host(host, unzipped["Actuator"], p | inputs, ["uf", "u_dz"])
    check_ok(result)
    assert got["u_dz"] == pytest.approx(dead_zone_formula(1.7, p), rel=1e-15)
    assert got["uf"] == pytest.approx(uf_formula(T, 1.7, 0.4, -0.3, p), rel=1e-12)


@pytest.mark.parametrize(
    ("model", "rhs", "start", "uf"),
    [("Example1Plant", example1, (0.3, -0.2, 0.1), 0.0), ("PendulumPlant", pendulum, (0.6, 0.1, 0.0), -2.0)],
)
def test_plants(host: Path, unzipped: dict, model: str, rhs: object, start: tuple, uf: float) -> None:
    """From a known state with uf held, against solve_ivp of SPEC section 3's equations."""
    sets = {"x1_0": start[0], "x2_0": start[1], "z_0": start[2], "uf": uf}
    result, got = run_host(host, unzipped[model], sets, ["x1", "x2", "z", "y"])
    check_ok(result)
    oracle = solve_held(rhs, 0.0, start, [uf] * STEPS, H)[-1]
    np.testing.assert_allclose([got["x1"], got["x2"], got["z"]], oracle, rtol=0, atol=1e-9)
    assert got["y"] == got["x1"]


def test_five_fmus_instantiated_at_once_in_five_threads(parallel_host: Path, unzipped: dict) -> None:
    """Python starts once even when every shim finds it missing at the same moment (without the
    shim's lock this crashed in 30 of 30 runs); repeated because the race is timing-dependent."""
    command = [str(parallel_host)]
    for folder in unzipped.values():
        md = fmpy.read_model_description(str(folder))
        binary = folder / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
        command += [str(binary), (folder / "resources").as_uri(), md.guid]
    for _ in range(5):
        result = host_run(command)
        assert result.returncode == 0, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
        assert result.stdout.split() == ["ok"] * len(unzipped)


def test_sixteen_instances_of_one_fmu_at_once_without_python(parallel_host: Path, unzipped: dict) -> None:
    """16 live instances of one FMU in a host without Python (the bundled interpreter): pythonfmu
    constructs each, running the FMU's entry module again every time, and releases a reference to
    its namespace that it never took; the entry keeps one per run (fmu_src/toolchain/build.py
    ``_entry``), else an instance after the first would find the namespace freed."""
    for model in ("Reference", "FixedTimeController"):
        folder = unzipped[model]
        md = fmpy.read_model_description(str(folder))
        binary = folder / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
        result = host_run([str(parallel_host), *[str(binary), (folder / "resources").as_uri(), md.guid] * 16])
        assert result.returncode == 0, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
        assert result.stdout.split() == ["ok"] * 16, model


@pytest.mark.skipif(not MALLOC_DEBUG.is_file(), reason="needs glibc's libc_malloc_debug.so.0")
def test_exit_leaves_the_heap_intact(host: Path, unzipped: dict) -> None:
    """pythonfmu 0.7.0 frees its PyState twice at exit when its binary is still loaded (the host
    never unloads it, or cannot: it is NODELETE); the shim releases it once before. Under glibc's
    heap checks that double free aborts the process ("free(): corrupted unsorted chunks")."""
    env = CLEAN_ENV | {"LD_PRELOAD": str(MALLOC_DEBUG), "MALLOC_CHECK_": "3"}
    inputs = {"x1": 0.0, "x2": 0.0, "yd": 0.0, "yd_dot": 0.0, "yd_ddot": 0.0}
    result, got = run_host(host, unzipped["FixedTimeController"], inputs, ["r"], env)
    check_ok(result)
    assert "corrupted" not in result.stderr
    assert got["r"] == pytest.approx(0.625 * (1 - math.exp(-T)), rel=1e-12)


def test_missing_runtime_is_one_message_and_no_instance(host: Path, unzipped: dict, tmp_path: Path) -> None:
    """An FMU whose runtime was removed (on a machine with no other libpython3.11) fails at
    fmi2Instantiate with one message naming the library, and no instance."""
    folder = Path(shutil.copytree(unzipped["FixedTimeController"], tmp_path / "broken"))
    (folder / "binaries/linux64/python/lib/libpython3.11.so.1.0.xz").unlink()
    result, _ = run_host(host, folder, {}, ["v"])
    if not COLLEAGUE and Path("/usr/lib/x86_64-linux-gnu/libpython3.11.so.1.0").is_file():
        pytest.skip("needs a colleague's machine: this one has a libpython3.11 the loader would find")
    assert result.returncode == 3, result.stdout + result.stderr  # the host saw a NULL instance
    assert result.stdout.strip() == "instantiate failed"
    lines = result.stderr.splitlines()
    logged = [line for line in lines if line.startswith("[host status 3 logStatusError]")]
    printed = [line for line in lines if not line.startswith("[")]
    assert len(logged) == 1 and len(printed) == 1, result.stderr  # host logger and stderr, once each
    assert logged[0].endswith(printed[0])
    assert printed[0].startswith("FixedTimeController: cannot load the bundled libpython3.11.so.1.0: ")
    # the loader's reason: not found, or (colleague's machine) the system's copy is an empty file
    assert "No such file" in printed[0] or "file too short" in printed[0], printed[0]


@pytest.mark.skipif(not COLLEAGUE, reason="needs a private mount namespace to hide the system's libraries")
def test_without_the_systems_expat_and_zlib_the_fmus_copies_serve(host: Path, unzipped: dict) -> None:
    """libpython links expat and zlib: the shim takes the machine's, and the FMU's own copies
    (binaries/linux64/python/fallback/) where the machine has none."""
    folder = unzipped["FixedTimeController"]
    md = fmpy.read_model_description(str(folder))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    binary = folder / "binaries" / "linux64" / "FixedTimeController.so"
    command = [str(host), str(binary), (folder / "resources").as_uri(), md.guid, str(STEPS), repr(H)]
    command += [f"{vr[n]}=0.0" for n in ("x1", "x2", "yd", "yd_dot", "yd_ddot")] + [str(vr["r"])]
    libs = "/usr/lib/x86_64-linux-gnu"
    system = tuple(glob.glob(f"{libs}/libexpat.so.1*") + glob.glob(f"{libs}/libz.so.1*"))
    result, got = collect(host_run(command, also=system), vr, ["r"])
    check_ok(result)
    assert got["r"] == pytest.approx(0.625 * (1 - math.exp(-T)), rel=1e-12)


def test_the_environment_does_not_reach_the_runtime(host: Path, unzipped: dict, tmp_path: Path) -> None:
    """PYTHONPATH, PYTHONHOME, PYTHONSTARTUP and a broken module on the path of the current folder
    change nothing: the bundled Python starts isolated (a leak made the import of logging fail)."""
    evil = tmp_path / "evil"
    (evil / "logging").mkdir(parents=True)
    (evil / "logging" / "__init__.py").write_text("raise ImportError('the environment leaked in')\n")
    (evil / "startup.py").write_text("raise SystemExit(7)\n")
    env = {"PYTHONPATH": str(evil), "PYTHONHOME": str(evil), "PYTHONSTARTUP": str(evil / "startup.py"),
           "PYTHONWARNINGS": "error", "PYTHONNOUSERSITE": "0"}
    inputs = {"x1": 0.0, "x2": 0.0, "yd": 0.0, "yd_dot": 0.0, "yd_ddot": 0.0}
    result, got = run_host(host, unzipped["FixedTimeController"], inputs, ["r"], env)
    check_ok(result)
    assert got["r"] == pytest.approx(0.625 * (1 - math.exp(-T)), rel=1e-12)  # r' = -r + 0.625


def replay_in_fmpy(folder: Path, sets: dict[str, float], gets: list[str]) -> dict[str, float]:
    """The C host's calls made from fmpy in this process (the build's Python, not the FMU's)."""
    md = fmpy.read_model_description(str(folder))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = fmpy.fmi2.FMU2Slave(guid=md.guid, unzipDirectory=str(folder),
                                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="host")
    slave.instantiate()
    try:
        slave.setReal([vr[n] for n in sets], list(sets.values()))
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        for k in range(STEPS):
            slave.doStep(k * H, H)
        values = dict(zip(gets, slave.getReal([vr[n] for n in gets]), strict=True))
        slave.terminate()
    finally:
        slave.freeInstance()
    return values


@pytest.mark.parametrize(
    ("model", "sets"),
    [
        ("FixedTimeController", {"x1": 0.7, "x2": -0.2, "yd": 0.5, "yd_dot": 0.1, "yd_ddot": -0.05}),
        ("Example1Plant", {"x1_0": 0.3, "x2_0": -0.2, "z_0": 0.1, "uf": 0.5}),
        ("PendulumPlant", {"x1_0": 0.6, "x2_0": 0.1, "z_0": 0.0, "uf": -2.0}),
    ],
)
def test_bundled_runtime_gives_the_hosts_numbers(host: Path, unzipped: dict, model: str, sets: dict) -> None:
    """The same calls give the same bits on the FMU's own Python (C host, no Python on the
    machine) as on the build's interpreter (fmpy here): the law and the integrators run on the
    same libm, and neither interpreter changes a float operation."""
    md = fmpy.read_model_description(str(unzipped[model]))
    gets = [v.name for v in md.modelVariables if v.causality == "output"]
    result, got = run_host(host, unzipped[model], sets, gets)
    check_ok(result)
    assert got == replay_in_fmpy(unzipped[model], sets, gets)


def test_python_host_keeps_its_interpreter(fmus: dict) -> None:
    """In a Python process the shim only forwards: no second libpython, and sys.path gains only
    the resources folder pythonfmu itself adds (no site directories)."""
    path = set(sys.path)
    with open_slave(fmus["FixedTimeController"]) as slave:
        slave.initialize()
        slave.set(x1=0.0, x2=0.0, yd=0.0, yd_dot=0.0, yd_ddot=0.0)
        for k in range(STEPS):
            slave.step(k * H, H)
        assert slave.get("r")[0] == pytest.approx(0.625 * (1 - math.exp(-T)), rel=1e-12)
    maps = Path("/proc/self/maps").read_text().splitlines()
    libpythons = {line.split()[-1] for line in maps if "/libpython3" in line}
    assert len(libpythons) <= 1, libpythons  # the interpreter's own (none if linked statically)
    assert all(p.endswith("/resources") for p in set(sys.path) - path), set(sys.path) - path


FMI2_FUNCTIONS = """fmi2GetTypesPlatform fmi2GetVersion fmi2SetDebugLogging fmi2Instantiate
fmi2FreeInstance fmi2SetupExperiment fmi2EnterInitializationMode fmi2ExitInitializationMode
fmi2Terminate fmi2Reset fmi2GetReal fmi2GetInteger fmi2GetBoolean fmi2GetString fmi2SetReal
fmi2SetInteger fmi2SetBoolean fmi2SetString fmi2GetFMUstate fmi2SetFMUstate fmi2FreeFMUstate
fmi2SerializedFMUstateSize fmi2SerializeFMUstate fmi2DeSerializeFMUstate
fmi2GetDirectionalDerivative fmi2SetRealInputDerivatives fmi2GetRealOutputDerivatives fmi2DoStep
fmi2CancelStep fmi2GetStatus fmi2GetRealStatus fmi2GetIntegerStatus fmi2GetBooleanStatus
fmi2GetStringStatus""".split()  # the FMI 2.0 standard's Co-Simulation interface


def test_shim_exports_the_co_simulation_interface(unzipped: dict) -> None:
    for model, folder in unzipped.items():
        shim = ctypes.CDLL(str(folder / "binaries" / "linux64" / f"{model}.so"))
        assert [f for f in FMI2_FUNCTIONS if not hasattr(shim, f)] == [], model
        shim.fmi2GetVersion.restype = shim.fmi2GetTypesPlatform.restype = ctypes.c_char_p
        assert (shim.fmi2GetVersion(), shim.fmi2GetTypesPlatform()) == (b"2.0", b"default")
