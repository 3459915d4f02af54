"""The FMUs in a host without Python: a minimal C importer (tests/fmu_c_host.c) dlopens each FMU's
binaries/linux64/<model>.so, as C/C++ tools do, under ``env -i PATH=/usr/bin:/bin`` (no
LD_PRELOAD, PYTHONPATH or PYTHONHOME). The FMI shim (fmu_src/shim/fmi2_shim.c) must load the
libpython and site-packages recorded at build time, or fail with one message naming what it
tried. Values are checked against closed forms and solve_ivp, written out here or in fmu_helpers."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
import sys
import sysconfig
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

CC = shutil.which("cc") or shutil.which("gcc")
CLEAN_ENV = {"PATH": "/usr/bin:/bin"}
STEPS, H = 100, 1e-3
T = STEPS * H
OTHER_LIBPYTHON = Path("/usr/lib/x86_64-linux-gnu/libpython3.11.so.1.0")  # Debian's, not the build's
MALLOC_DEBUG = Path("/lib/x86_64-linux-gnu/libc_malloc_debug.so.0")  # glibc's checking allocator
pytestmark = [pytest.mark.system, pytest.mark.skipif(CC is None, reason="needs a C compiler for the host")]


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("c_host") / "host"
    source = Path(__file__).with_name("fmu_c_host.c")
    subprocess.run([CC, "-O1", "-Wall", "-o", str(out), str(source), "-ldl"], check=True, capture_output=True)
    return out


@pytest.fixture(scope="module")
def parallel_host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("c_host") / "parallel_host"
    source = Path(__file__).with_name("fmu_c_host_parallel.c")
    command = [CC, "-O1", "-Wall", "-o", str(out), str(source), "-ldl", "-pthread"]
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
    result = subprocess.run(command, env=env or CLEAN_ENV, capture_output=True, text=True, timeout=120)
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
    with r_inf = (gamma_gain x1^4 + d_r) / a_bar. Needs numpy from the recorded site-packages."""
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
        result = subprocess.run(command, env=CLEAN_ENV, capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
        assert result.stdout.split() == ["ok"] * len(unzipped)


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


def test_missing_libpython_is_one_message_and_no_instance(host: Path, unzipped: dict) -> None:
    missing = "/nonexistent/libpython3.11.so.1.0"
    env = CLEAN_ENV | {"FTC_PYTHON_LIBRARY": missing}
    result, _ = run_host(host, unzipped["FixedTimeController"], {}, ["v"], env)
    assert result.returncode == 3, result.stdout + result.stderr  # the host saw a NULL instance
    assert result.stdout.strip() == "instantiate failed"
    lines = result.stderr.splitlines()
    logged = [line for line in lines if line.startswith("[host status 3 logStatusError]")]
    printed = [line for line in lines if not line.startswith("[")]
    assert len(logged) == 1 and len(printed) == 1, result.stderr  # host logger and stderr, once each
    message = printed[0]
    assert logged[0].endswith(message)
    recorded = (unzipped["FixedTimeController"] / "binaries/linux64/python_env.txt").read_text()
    library = next(line.split("=", 1)[1] for line in recorded.splitlines() if line.startswith("library="))
    assert message.startswith("FixedTimeController: cannot load libpython: tried ")
    assert f"FTC_PYTHON_LIBRARY={missing} (" in message and "No such file" in message
    assert library in message and "FTC_PYTHON_PATH" in message


@pytest.mark.skipif(not OTHER_LIBPYTHON.is_file(), reason="needs a second shared libpython3.11")
def test_another_libpython_through_the_environment(host: Path, unzipped: dict) -> None:
    """As on another machine: FTC_PYTHON_LIBRARY names a different Python 3.11 (Debian's, which has
    no numpy); FTC_PYTHON_PATH gives the packages. Without them the controller cannot start, and
    the shim says which Python and directories it used."""
    site = sysconfig.get_paths()["purelib"]
    env = CLEAN_ENV | {"FTC_PYTHON_LIBRARY": str(OTHER_LIBPYTHON), "FTC_PYTHON_PATH": f"/nonexistent:{site}"}
    inputs = {"x1": 0.0, "x2": 0.0, "yd": 0.0, "yd_dot": 0.0, "yd_ddot": 0.0}
    result, got = run_host(host, unzipped["FixedTimeController"], inputs, ["r"], env)
    check_ok(result)
    assert got["r"] == pytest.approx(0.625 * (1 - math.exp(-T)), rel=1e-12)  # r' = -r + 0.625
    assert "site directory /nonexistent (from FTC_PYTHON_PATH) does not exist" in result.stderr

    env["FTC_PYTHON_PATH"] = "/nonexistent"
    result, _ = run_host(host, unzipped["FixedTimeController"], inputs, ["r"], env)
    assert result.returncode == 3, result.stdout + result.stderr
    assert "FixedTimeController: pythonfmu could not instantiate host in Python 3.11" in result.stderr
    assert f"from {OTHER_LIBPYTHON}, site directories /nonexistent" in result.stderr
    assert "No module named 'numpy'" in result.stderr  # pythonfmu's own reason (logging on)


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
