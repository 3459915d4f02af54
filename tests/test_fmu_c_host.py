"""The FMUs outside a Python process: a minimal C importer (tests/fmu_c_host.c) loads the FMU
binary with dlopen, as C/C++ tools do. pythonfmu's linux64 binary does not link libpython (its
Python symbols are undefined), so the host must have libpython loaded globally, e.g. with
LD_PRELOAD; this is what README.md ("Running the FMUs outside Python") tells tool users."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import pytest
from fmu_helpers import reference_formula

LIBPYTHON = Path(sysconfig.get_config_var("LIBDIR") or "", sysconfig.get_config_var("INSTSONAME") or "")
pytestmark = [
    pytest.mark.system,
    pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc to build the C host"),
    pytest.mark.skipif(not LIBPYTHON.is_file(), reason="needs a shared libpython"),
]


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("c_host") / "host"
    source = Path(__file__).with_name("fmu_c_host.c")
    subprocess.run(["gcc", "-O1", "-o", str(out), str(source), "-ldl"], check=True, capture_output=True)
    return out


def run_host(
    host: Path, fmu: Path, tmp_path: Path, output: str, steps: int, env: dict
) -> subprocess.CompletedProcess:
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}[output]
    unzipped = tmp_path / fmu.stem
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(unzipped)
    binary = unzipped / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    command = [str(host), str(binary), (unzipped / "resources").as_uri(), md.guid, str(vr), str(steps)]
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("LD_", "PYTHON"))}
    return subprocess.run(command, env={**clean, **env}, capture_output=True, text=True, timeout=60)


def test_binary_needs_libpython_loaded_by_the_host(fmus: dict, host: Path, tmp_path: Path) -> None:
    result = run_host(host, fmus["Reference"], tmp_path, "yd", 10, {})
    assert "undefined symbol" in result.stdout


def test_c_host_runs_reference_and_controller(fmus: dict, host: Path, tmp_path: Path) -> None:
    site = sysconfig.get_paths()["purelib"]  # where numpy lives for this interpreter
    env = {"LD_PRELOAD": str(LIBPYTHON), "PYTHONPATH": site}
    result = run_host(host, fmus["Reference"], tmp_path, "yd", 100, env)
    assert result.returncode == 0, result.stdout + result.stderr
    value = float(result.stdout.split("value")[1])
    assert value == pytest.approx(reference_formula(0.1, 0.5, 1.0, 0.0, 0.0)[0], abs=1e-15)
    result = run_host(host, fmus["FixedTimeController"], tmp_path, "r", 100, env)
    assert result.returncode == 0, result.stdout + result.stderr
    # r' = -r + 2.5 x1^4 + 0.625 with x1 = 0: r(t) = 0.625 (1 - exp(-t)), RK4 error ~1e-15
    assert float(result.stdout.split("value")[1]) == pytest.approx(0.625 * (1 - math.exp(-0.1)), rel=1e-12)
