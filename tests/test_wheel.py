# SPDX-License-Identifier: BSD-2-Clause
"""The package as PyPI would serve it: an sdist and a wheel built from the checkout (the wheel
from the sdist, so the sdist is complete), clean under ``twine check``, installed into a fresh
virtual environment outside the checkout, where an empty folder builds the FMUs, runs a shipped
scenario and exports one, writing nothing into site-packages."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RUNTIME = REPO / "build" / "runtime"  # the checkout's fetched runtime, lent to the new install


def _run(command: list[str], cwd: Path, env: dict[str, str] | None = None) -> str:
    proc = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, f"{' '.join(command)}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.mark.system
def test_wheel_and_sdist_carry_what_a_build_needs(dist: Path) -> None:
    _run([sys.executable, "-m", "twine", "check", "--strict", *map(str, dist.iterdir())], cwd=dist)
    (wheel,) = dist.glob("*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    needed = {"fmu_src/toolchain/shim/fmi2_functions.c", "fmu_src/toolchain/shim/fmi3_functions.c",
              "fmu_src/toolchain/shim/start_python.c",
              "orchestrator/native/container.c", "orchestrator/native/container_fmi3.c",
              "orchestrator/native/container.h", "fmu_src/models/_dopri.c", "controller/fmath.h",
              "controller/fmath_pow.h",
              "fmu_src/cbase/platform.c", "fmu_src/cbase/fmi/fmi3FunctionTypes.h",
              "fmu_src/cbase/fmi/LICENSE.txt",
              "controller/fmath-LICENSE.txt", "orchestrator/launcher.c",
              "orchestrator/experiments/ssp/pendulum/SystemStructure.ssd",
              "orchestrator/experiments/ssp/campaigns/fault_tolerance.toml"}
    assert needed <= names, sorted(needed - names)
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    info = next(n for n in names if n.endswith(".dist-info/METADATA"))
    metadata = zipfile.ZipFile(wheel).read(info).decode()
    assert "License-Expression: BSD-2-Clause AND MIT" in metadata
    assert "Requires-Python: >=3.11" in metadata
    assert "Provides-Extra: pandas" in metadata


def _files(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if "__pycache__" not in p.parts}


@pytest.mark.system
def test_installed_wheel_builds_runs_and_exports_in_an_empty_folder(dist: Path, tmp_path: Path) -> None:
    (wheel,) = dist.glob("*.whl")
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], cwd=tmp_path)
    python = venv / "bin" / "python"
    _run([str(python), "-m", "pip", "install", "--quiet", str(wheel), "-c", str(REPO / "constraints.txt")],
         cwd=tmp_path)
    site = Path(_run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=tmp_path).strip())
    before = _files(site)
    cache = tmp_path / "cache"
    if RUNTIME.is_dir():  # spare the 57 MB download; the fetch itself is tested on its own
        (cache / "fixed-time-cosim").mkdir(parents=True)
        (cache / "fixed-time-cosim" / "runtime").symlink_to(RUNTIME, target_is_directory=True)
    env = {"PATH": f"{venv / 'bin'}:/usr/bin:/bin", "HOME": str(tmp_path), "XDG_CACHE_HOME": str(cache),
           "LANG": "C.UTF-8", **({"CC": os.environ["CC"]} if "CC" in os.environ else {})}
    work = tmp_path / "work"
    work.mkdir()
    out = _run(["orchestrate", "build", "pendulum", "example1"], cwd=work, env=env)
    assert "build/ssp/pendulum.ssp" in out
    _run(["orchestrate", "run", "pendulum", "--stop-time", "0.5", "--no-plot", "--quiet"], cwd=work, env=env)
    rows = (work / "results" / "pendulum.csv").read_text().splitlines()
    assert len(rows) == 1 + 1001 and rows[0].startswith("time,")
    _run(["orchestrate", "export", "example1", "-o", "example1.fmu"], cwd=work, env=env)
    check = ("from fmpy import simulate_fmu; "
             "assert len(simulate_fmu('example1.fmu', stop_time=0.01)) == 11")
    _run([str(python), "-c", check], cwd=work, env=env)
    assert _files(site) == before, sorted(_files(site) ^ before)


def test_to_pandas_without_pandas_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """pandas is the optional extra 'pandas': without it, to_pandas says how to install it."""
    import numpy as np

    from orchestrator import RunResult

    monkeypatch.setitem(sys.modules, "pandas", None)  # what an install without the extra has
    rows = np.zeros(2, dtype=[("time", "f8"), ("plant.y", "f8")])
    with pytest.raises(ImportError, match=r"pip install 'fixed-time-cosim\[pandas\]'"):
        RunResult("complete", "", rows, 2, 1.0).to_pandas()
