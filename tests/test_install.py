# SPDX-License-Identifier: BSD-2-Clause
"""Installing the project on every Python it supports (issue 42).

* The pins: ``constraints.txt`` with every extra resolves from wheels for Python 3.11.0 (Debian 12's
  own is 3.11.2), 3.12 and 3.13, each package pinned at the version resolved. ``uv pip compile``
  evaluates the markers and each wheel's Requires-Python for the target version (pip evaluates
  them for the Python it runs on), and Debian's ``/usr/bin/python3`` resolves them with pip as
  ``make`` does. Failed before: pymdown-extensions 13.1.2 needs Python 3.11.5.

Oracles: uv's and pip's resolvers against the pins.
"""

from __future__ import annotations

import functools
import json
import re
import subprocess
from pathlib import Path

import pytest
import tomllib
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version
from uv import find_uv_bin

REPO = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
OLDEST = PROJECT["requires-python"].removeprefix(">=")
PYTHONS = ("3.11.0", "3.11.2", "3.12.0", "3.13.0")
PLATFORM = "x86_64-manylinux_2_28"  # wheels for glibc 2.28 or later (Debian 12 has 2.36)
DEBIAN_PYTHON = Path("/usr/bin/python3")
UV = find_uv_bin()


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
@pytest.mark.parametrize("python", PYTHONS)
def test_the_pins_resolve_for_every_supported_python(python: str) -> None:
    resolved = _resolve(python)
    assert {"fmpy", "numpy", "pytest", "mkdocs"} <= resolved.keys()
    assert _unpinned(resolved, _environment(python)) == []


@pytest.mark.system
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

