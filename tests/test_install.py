# SPDX-License-Identifier: BSD-2-Clause
"""Installing the project on every Python it supports, and with the oldest dependencies it
declares (issue 42).

* The pins: ``constraints.txt`` with every extra resolves from wheels for Python 3.11.0 (Debian 12's
  own is 3.11.2), 3.12 and 3.13, each package pinned at the version resolved. ``uv pip compile``
  evaluates the markers and each wheel's Requires-Python for the target version (pip evaluates
  them for the Python it runs on), and Debian's ``/usr/bin/python3`` resolves them with pip as
  ``make`` does. Failed before: pymdown-extensions 13.1.2 needs Python 3.11.5.
* The floors: ``pyproject.toml``'s lower bounds, all at once, install, import every module and run
  a scenario and a campaign with the same results as the pinned ``.venv``. Failed before:
  FMPy 0.3.20 has no ``ModelVariable``, and the FMPy that has it needs numpy 2.1.3, for which
  matplotlib 3.7, pyarrow 14 and pandas 2.0 were not built.

Oracles: uv's and pip's resolvers against the pins; the pinned environment's results of the same
runs (the same FMUs, so the same bits).

``make test`` runs Debian's pip on the pins and uv's resolve for the oldest Python;
``make install-matrix`` (FTC_INSTALL_ALL=1) also the other Pythons, the pins none of them use and
the floors (about 100 s of the suite's time).
"""

from __future__ import annotations

import functools
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import tomllib
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version
from uv import find_uv_bin

REPO = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
RUNTIME = (*PROJECT["dependencies"], *PROJECT["optional-dependencies"]["pandas"])  # a user's install
OLDEST = PROJECT["requires-python"].removeprefix(">=")  # the floors are for the oldest supported Python
PYTHONS = ("3.11.0", "3.11.2", "3.12.0", "3.13.0")
ALL = os.environ.get("FTC_INSTALL_ALL") == "1"
whole_matrix = pytest.mark.skipif(not ALL, reason="the whole install matrix: make install-matrix")
PLATFORM = "x86_64-manylinux_2_28"  # wheels for glibc 2.28 or later (Debian 12 has 2.36)
DEBIAN_PYTHON = Path("/usr/bin/python3")
UV = find_uv_bin()

# A campaign of two runs: Dask's cluster, the tracking metrics, the Parquet table, a scatter plot.
DESIGN = """description = "two gains"
stop_time = 0.2
[fixed]
"actuator.t_fault" = 0.1
[grid]
"controller.k1" = [5.0, 10.0]
[[plots]]
kind = "scatter"
x = "controller.k1"
metric = "mae_after_fault"
"""

# In the floors' venv: every module imports (but the pytest plugin, for pytest, and __main__), and
# RunResult.to_pandas gives the pinned run's CSV (argv: the scenario, that CSV).
CHECK = """
import importlib, pkgutil, sys
import pandas
import controller, fmu_src, orchestrator
from orchestrator import RunOptions, run
assert orchestrator.__file__.startswith(sys.prefix), orchestrator.__file__
for package in (controller, fmu_src, orchestrator):
    for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        if module.name not in {"orchestrator.__main__", "orchestrator.regress.pytest_plugin"}:
            importlib.import_module(module.name)
frame = run(sys.argv[1], RunOptions(stop_time=1.0)).to_pandas()
expected = pandas.read_csv(sys.argv[2], index_col="time", float_precision="round_trip")
pandas.testing.assert_frame_equal(frame, expected, check_exact=True)
"""


def _run(command: list[str | Path], cwd: Path) -> str:
    proc = subprocess.run([str(c) for c in command], cwd=cwd, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, \
        f"{' '.join(map(str, command))}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


def _versions(requirements: str) -> dict[str, str]:
    """name -> version of the ``name==version`` lines of a compiled requirements text."""
    return {canonicalize_name(name): version
            for name, version in re.findall(r"^([A-Za-z0-9._-]+)==(\S+)$", requirements, re.MULTILINE)}


def _unpinned(resolved: dict[str, str], environment: dict[str, str]) -> list[str]:
    """The resolved packages that constraints.txt does not pin at that version for a Python of
    ``environment`` (its marker variables)."""
    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            pin = Requirement(line)
            if pin.marker is None or pin.marker.evaluate(environment):
                pins[canonicalize_name(pin.name)] = Version(next(iter(pin.specifier)).version)
    return sorted(f"{name}=={version} (pinned: {pins.get(name)})" for name, version in resolved.items()
                  if pins.get(name) != Version(version))


def _environment(python: str) -> dict[str, str]:
    """The marker variables of this machine with Python ``python`` (X.Y.Z)."""
    return {**default_environment(), "python_full_version": python, "implementation_version": python,
            "python_version": ".".join(python.split(".")[:2])}


@functools.cache
def _resolve(python: str) -> dict[str, str]:
    """What the project with every extra, under constraints.txt, resolves to for ``python``."""
    return _versions(_run([UV, "pip", "compile", "--quiet", "--no-header", "--no-annotate", "--all-extras",
                           "pyproject.toml", "-c", "constraints.txt", "--python-version", python,
                           "--python-platform", PLATFORM, "--only-binary", ":all:"], cwd=REPO))


@pytest.mark.system
@pytest.mark.parametrize("python", [PYTHONS[0], *(pytest.param(p, marks=whole_matrix) for p in PYTHONS[1:])])
def test_the_pins_resolve_for_every_supported_python(python: str) -> None:
    resolved = _resolve(python)
    assert {"fmpy", "numpy", "pytest", "mkdocs"} <= resolved.keys()
    assert _unpinned(resolved, _environment(python)) == []


@pytest.mark.system
@whole_matrix
def test_every_pin_is_installed_on_some_python() -> None:
    used = set().union(*map(_resolve, PYTHONS))
    pinned = {canonicalize_name(Requirement(line).name)
              for line in (REPO / "constraints.txt").read_text().splitlines() if line and line[0] != "#"}
    assert sorted(pinned - used) == []


@pytest.mark.system
def test_debians_own_python_installs_the_pins(tmp_path: Path) -> None:
    """pip's resolver on the interpreter itself, in a fresh venv, as the Makefile installs."""
    version = _run([DEBIAN_PYTHON, "-c", "import platform; print(platform.python_version())"], cwd=tmp_path) \
        if DEBIAN_PYTHON.is_file() else ""
    if not version or Version(version) < Version(OLDEST):
        pytest.skip(f"no {DEBIAN_PYTHON} of Python {OLDEST} or later on this machine")
    pip = re.search(r"--upgrade (pip==\S+)", (REPO / "Makefile").read_text())
    assert pip, "the Makefile's pip pin"
    _run([DEBIAN_PYTHON, "-m", "venv", tmp_path / "venv"], cwd=tmp_path)
    python = tmp_path / "venv" / "bin" / "python"
    _run([python, "-m", "pip", "install", "--quiet", "--upgrade", pip[1]], cwd=tmp_path)
    report = tmp_path / "report.json"
    _run([python, "-m", "pip", "install", "--dry-run", "--quiet", "--report", report, "-e", ".[test,docs]",
          "-c", "constraints.txt"], cwd=REPO)
    plan = json.loads(report.read_text())
    resolved = {canonicalize_name(item["metadata"]["name"]): item["metadata"]["version"]
                for item in plan["install"] if item["metadata"]["name"] != PROJECT["name"]}
    assert {"fmpy", "numpy", "pytest", "mkdocs"} <= resolved.keys()
    assert _unpinned(resolved, plan["environment"]) == []


def _floor(requirement: Requirement) -> Version:
    return Version(next(s.version for s in requirement.specifier if s.operator in (">=", "==")))


def _oldest_python() -> str:
    """An interpreter of the oldest supported Python: this one, else python3.X on the PATH."""
    if f"{sys.version_info.major}.{sys.version_info.minor}" == OLDEST:
        return sys.executable
    found = shutil.which(f"python{OLDEST}")
    if found is None:
        pytest.skip(f"no Python {OLDEST} on this machine for the floors")
    return found


def _campaign(folder: Path) -> tuple[list[dict], list[str]]:
    """A campaign's table without its wall times, and its summary without the run time."""
    table = pq.read_table(folder / "campaign" / "runs.parquet").drop_columns(["wall_time"])
    summary = (folder / "report" / "summary.md").read_text().splitlines()
    return table.to_pylist(), [line for line in summary if "of run time" not in line]


@pytest.mark.system
@whole_matrix
def test_the_declared_floors_install_and_run_as_the_pins_do(dist: Path, built: Path, tmp_path: Path) -> None:
    declared = [Requirement(r) for r in RUNTIME]
    python = _oldest_python()
    floors = tmp_path / "floors.txt"
    _run([UV, "pip", "compile", "--quiet", "--no-header", "--no-annotate", REPO / "pyproject.toml",
          "--extra", "pandas", "--resolution", "lowest-direct", "--python", python, "--only-binary", ":all:",
          "-o", floors], cwd=tmp_path)
    resolved = _versions(floors.read_text())
    # Each dependency installs at its declared floor: none is lifted by another's requirements or
    # by a missing wheel.
    assert {r.name: Version(resolved[canonicalize_name(r.name)]) for r in declared} == \
        {r.name: _floor(r) for r in declared}
    venv = tmp_path / "venv"
    _run([UV, "venv", "--quiet", "--python", python, venv], cwd=tmp_path)
    install = [UV, "pip", "install", "--quiet", "--python", venv / "bin" / "python"]
    _run([*install, "--only-binary", ":all:", "-r", floors], cwd=tmp_path)
    (wheel,) = dist.glob("*.whl")
    _run([*install, "--no-deps", wheel], cwd=tmp_path)

    scenario = built / "ssp" / "pendulum.ssp"
    (tmp_path / "design.toml").write_text(DESIGN)
    for name, orchestrate in (("pinned", [sys.executable, "-m", "orchestrator"]),
                              ("floors", [venv / "bin" / "orchestrate"])):
        work = tmp_path / name
        work.mkdir()
        _run([*orchestrate, "run", scenario, "--stop-time", "1", "--output", "run.csv", "--plot", "run.png",
              "--quiet"], cwd=work)
        _run([*orchestrate, "sweep", scenario, "--design", tmp_path / "design.toml", "--workers", "1",
              "--output", "campaign", "--plot", "report", "--quiet"], cwd=work)
    pinned, floors_run = tmp_path / "pinned", tmp_path / "floors"
    assert (floors_run / "run.csv").read_bytes() == (pinned / "run.csv").read_bytes()
    assert _campaign(floors_run) == _campaign(pinned)
    figures = [p.relative_to(pinned) for p in (pinned / "report").glob("*.png")]
    assert figures, "the design's scatter plot"
    for figure in ("run.png", *figures):
        assert (floors_run / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", figure
    _run([venv / "bin" / "python", "-c", CHECK, scenario, pinned / "run.csv"], cwd=tmp_path)
