# SPDX-License-Identifier: BSD-2-Clause
"""Running tests/fmu_hostile_host.c on an FMU: unpack, pick the value references it needs from the
model description (read with fmpy), run the scenarios, parse their lines."""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy

import fmu_src.cbase as cbase

SOURCES = (Path(__file__).with_name("fmu_hostile_host.c"), Path(__file__).with_name("fmu_hostile_nonsense.c"))
FMI_HEADERS = cbase.FMI_HEADERS  # the official FMI headers the C hosts include
CC = shutil.which("cc") or shutil.which("gcc")
# Every scenario of the host; the leak one (cycles) runs on its own.
SCENARIOS = (
    "ok", "resources-missing", "resources-empty", "resources-null", "resources-not-a-file-uri",
    "guid-wrong", "guid-null", "no-logger", "no-callbacks", "step-before-init", "get-before-init",
    "step-nan", "step-negative", "step-zero", "step-infinite", "unknown-vr", "set-output",
    "set-output-twice", "set-fixed-after-init", "step-after-terminate", "after-error", "reset-after-error",
    "model-fails", "fifty", "two-threads",
)
# The nonsense calls (fmu_hostile_host.c's NONSENSE), each on an instance of its own: a NULL array or
# entry, a count beyond any array, a time that cannot be, a capability the FMU does not declare.
NONSENSE = (
    "debug-null-categories", "debug-null-entry", "setup-stop-before-start", "setup-start-nan",
    "setup-start-inf", "setup-stop-inf", "setup-tolerance-nan", "setup-tolerance-negative", "get-null-vr",
    "get-null-values", "set-null-values", "get-count-beyond", "get-integer-null-vr",
    "get-boolean-null-values", "set-string-null-entry", "get-state-null", "set-state-null",
    "get-state-undeclared-size", "deserialize-null", "directional-null", "output-derivatives-null",
    "input-derivatives-null", "status-null", "real-status-null",
)
# How the leak scenario names its instances: one name, a new one each cycle, two in turn.
NAMINGS = {"same": "cycles", "distinct": "cycles-distinct", "alternating": "cycles-alternating"}


@dataclass(frozen=True)
class Outcome:
    """What one scenario gave: its status, whether the instance existed, the messages logged (and
    of them with a NULL category), a figure of the scenario, the first message, and how the child
    ended ('0', 'signal N', on Windows 'exception 0x...'; '' if it printed nothing)."""

    status: int
    instance: bool
    messages: int
    null_categories: int
    extra: float
    message: str
    exit: str

    @property
    def crashed(self) -> bool:
        return self.exit.startswith("signal") or self.exit not in ("0", "")


def compile_host(dest: Path) -> Path:
    """Compile the hostile host into ``dest``."""
    assert CC is not None
    out = dest / "fmu_hostile_host"
    command = [CC, "-O1", "-g", "-Wall", "-Wextra", f"-I{FMI_HEADERS}", "-o", str(out), *map(str, SOURCES),
               "-ldl", "-pthread", "-lm"]
    subprocess.run(command, check=True, capture_output=True)
    return out


def unpack(fmu: Path, dest: Path) -> tuple[Path, list[str]]:
    """The FMU unpacked under ``dest``; the host's arguments before the scenarios."""
    folder = dest / f"{fmu.parent.name}-{fmu.stem}"
    if not folder.is_dir():
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(folder)
    md = fmpy.read_model_description(str(folder))
    version = "2" if md.fmiVersion == "2.0" else "3"
    token = md.guid if version == "2" else md.instantiationToken

    def first(causality: str, variability: str | None = None) -> str:
        for v in md.modelVariables:
            if v.causality == causality and v.type in ("Real", "Float64") and \
                    (variability is None or v.variability == variability):
                return str(v.valueReference)
        return "-1"

    identifier = md.coSimulation.modelIdentifier
    return folder, [str(folder), version, identifier, token, first("input"), first("output"),
                    first("parameter", "fixed")]


def resources_of(folder: Path, version: str) -> str:
    """The resource location of the FMU unpacked in ``folder`` as the host passes it (FMI 2.0: a
    file URI; FMI 3.0: a native path ending in a separator)."""
    return f"{(folder / 'resources').as_uri()}" if version == "2" else f"{folder / 'resources'}/"


def run(
    host: Path | str, arguments: list[str], scenarios: tuple[str, ...] | list[str],
    wrapper: tuple[str, ...] = (), timeout: float = 600, env: dict[str, str] | None = None,
) -> tuple[dict[str, Outcome], subprocess.CompletedProcess]:
    """Run ``scenarios`` (under ``wrapper``, e.g. valgrind or wine64 with its ``env``); the outcome of
    each, and the process."""
    if env is None:
        env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp")}
    result = subprocess.run([*wrapper, str(host), *arguments, *scenarios], capture_output=True, text=True,
                            timeout=timeout, env=env, stdin=subprocess.DEVNULL)
    lines: dict[str, dict[str, str]] = {}
    exits: dict[str, str] = {}
    for line in result.stdout.splitlines():
        if line.startswith("SCENARIO "):
            head, _, message = line.partition(" | ")
            fields = head.split()
            lines[fields[1]] = dict(f.split("=", 1) for f in fields[2:]) | {"message": message}
        elif line.startswith("EXIT "):
            name, code = line[5:].split(" ", 1)
            exits[name] = code
    outcomes = {}
    for name in scenarios:
        f = lines.get(name)
        if f is None:
            outcomes[name] = Outcome(-1, False, 0, 0, 0.0, "", exits.get(name, "no exit"))
        else:
            outcomes[name] = Outcome(int(f["status"]), f["instance"] == "1", int(f["messages"]),
                                     int(f["nullcat"]), float(f["extra"]), f["message"], exits.get(name, ""))
    return outcomes, result
