# SPDX-License-Identifier: BSD-2-Clause
"""Provenance of a result: the sidecar ``<result>.json`` written beside every result file.

A result alone does not say what produced it. The sidecar records the scenario and its SHA-256
digest, every FMU (GUID, model name, generation tool, digest), every parameter set and override,
the start values finally applied, the unit of every column (from the model descriptions),
start/stop/step, the master, the package versions, the git commit of the code (when it runs from
a checkout) and the date; and the run's ``status`` (``running`` while it runs, then ``complete``,
``failed``, ``timeout`` or ``interrupted``) with the time of the last row, so a partial result is
recognisable. It is written atomically (temporary file, rename) before the first step and again
when the run ends.
"""

from __future__ import annotations

import glob
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path

from . import files
from .errors import OutputError
from .fmucache import deferred, sha256
from .installed import version
from .results import FLUSH_ROWS, FLUSH_SECONDS
from .system import System

__all__ = ["PACKAGES", "column_units", "commit", "describe", "digest", "finish", "overrides_text",
           "read_provenance", "sidecar", "summary", "versions", "write_provenance"]

PACKAGES = ("fixed-time-cosim", "fmpy", "pythonfmu", "numpy", "scipy", "lxml", "pyarrow")
CODE_ROOT = Path(__file__).resolve().parents[1]


def sidecar(result: str | os.PathLike) -> Path:
    """The provenance file of a result file: ``r.csv`` -> ``r.csv.json``."""
    result = Path(result)
    return result.with_name(result.name + ".json")


def digest(path: str | os.PathLike) -> str:
    """SHA-256 of a file, or of a folder's files (relative names and contents, in sorted order)."""
    path = Path(path)
    if deferred(path) or path.is_file():
        return sha256(path)  # computed once per process (the FMU cache needs it too)
    h = files.bulk_sha256()
    for f in sorted(f for f in path.rglob("*") if f.is_file()):
        if path.is_dir():
            h.update(f.relative_to(path).as_posix().encode() + b"\0")
        with f.open("rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a result depends on."""
    found = {"python": sys.version.split()[0]}  # platform.python_version(), without importing platform
    for name in PACKAGES:
        found[name] = version(name) or "not installed"
    return found


def commit() -> dict[str, object] | None:
    """The git commit of the code that runs (and whether the checkout has changes), if any."""
    try:
        head = subprocess.run(["git", "-C", str(CODE_ROOT), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return None
        status = subprocess.run(["git", "-C", str(CODE_ROOT), "status", "--porcelain",
                                 "--untracked-files=no"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": head.stdout.strip(), "modified": bool(status.stdout.strip())}


def describe(scenario: str | os.PathLike, system: System, *, start: float, stop: float, step: float,
             master: str, master_from: str = "", parameter_sets: Iterable[str | os.PathLike] = (),
             overrides: Mapping[str, object] | None = None) -> dict[str, object]:
    """Everything that produced a run of ``system`` (status ``running``); ``master_from``: why that
    master (``--master``, the SSD's algorithm annotation, or the default)."""
    scenario = Path(scenario)
    return {
        "scenario": {"path": str(scenario.resolve()), "sha256": digest(scenario),
                     "ssd": system.ssd, "name": system.structure.name},
        "fmus": {name: {"file": comp.fmu.name, "guid": comp.model.guid, "model": comp.model.modelName,
                        "generation_tool": comp.model.generationTool, "sha256": digest(comp.fmu)}
                 for name, comp in system.components.items()},
        "parameter_sets": [{"path": str(Path(p).resolve()), "sha256": digest(p)} for p in parameter_sets],
        "ssd_parameter_sets": [f"{c.name}: {ps.origin}" for c in system.structure.components
                               for ps in c.parameter_sets],
        "overrides": {k: str(v) for k, v in (overrides or {}).items()},
        "start_values": {f"{name}.{k}": v for name, comp in system.components.items()
                         for k, v in comp.start_values.items()},
        "units": column_units(system),
        "outputs": [f"{name}.{k}" for name, comp in system.components.items() for k in comp.outputs],
        "start_time": start, "stop_time": stop, "step": step, "master": master,
        "master_from": master_from,
        "versions": versions(),
        "git": commit(),
        "date": time.strftime("%Y-%m-%dT%H:%M:%S+00:00", time.gmtime()),  # isoformat, UTC
        "status": "running",
        "process": {"pid": os.getpid(), "host": files.HOST},  # a dead 'running' run: read_provenance
    }


def column_units(system: System) -> dict[str, str | None]:
    """The unit of every result column ``component.connector`` (None: the FMU declares none)."""
    return {f"{name}.{k}": _unit(comp.variables[k]) for name, comp in system.components.items()
            for k in (*comp.outputs, *comp.inputs)}


def _unit(var: object) -> str | None:
    """The unit a variable declares, directly or through its type (None: none)."""
    declared = getattr(var, "declaredType", None)
    return getattr(var, "unit", None) or (declared.unit if declared is not None else None)


def write_provenance(result: str | os.PathLike, record: Mapping[str, object]) -> Path:
    """Write (atomically) the sidecar of ``result``; returns its path. OutputError when it cannot."""
    try:
        return files.write_text(sidecar(result), json.dumps(record, indent=1) + "\n")
    except OSError as exc:
        raise OutputError(f"{exc.filename or sidecar(result)}: {exc.strerror or exc}") from exc


def finish(result: str | os.PathLike, record: dict[str, object], status: str, rows: int,
           last_time: float | None, message: str = "") -> Path:
    """Record how the run ended (``complete``, ``failed``, ``timeout`` or ``interrupted``) in the sidecar."""
    record.update(status=status, rows=rows, last_time=last_time)
    if message:
        record["message"] = message
    return write_provenance(result, record)


def read_provenance(result: str | os.PathLike) -> dict[str, object] | None:
    """The sidecar of ``result`` (None when there is none or it is not readable JSON). A run still
    ``running`` whose process is gone (killed, ``kill -9``: it could not say so) is reported as
    ``failed``, with no row claimed: what the result file holds is whatever was flushed."""
    try:
        record = json.loads(sidecar(result).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    process = record.get("process")
    if (record.get("status") == "running" and isinstance(process, dict) and process.get("host") == files.HOST
            and isinstance(process.get("pid"), int) and not files.alive(process["pid"])):
        result = Path(result)
        left = sorted(result.parent.glob(f".{glob.escape(result.name)}.{files.HOST}-{process['pid']}.*.part"))
        where = (f"the rows it wrote (every {FLUSH_ROWS} rows or {FLUSH_SECONDS:g} s) are in {left[0]}"
                 if left else "no rows of it were kept")
        record.update(status="failed", rows=None, last_time=None,
                      message=f"the process that ran it (pid {process['pid']}) ended without finishing it "
                              f"(killed?); {where}")
    return record


def summary(record: Mapping[str, object] | None) -> str:
    """One line: scenario, overrides, parameter sets, timing, master, status, commit and date."""
    if record is None:
        return "no provenance file"
    scenario = _mapping(record.get("scenario"))
    parts = [f"{Path(str(scenario.get('path', '?'))).name} (sha256 {str(scenario.get('sha256', ''))[:12]})"]
    overrides = _mapping(record.get("overrides"))
    parts.append("--set " + " ".join(f"{k}={v}" for k, v in overrides.items()) if overrides else "no --set")
    sets = _set_names(record)
    if sets:
        parts.append("--parameter-set " + " ".join(sets))
    parts.append(f"t = {record.get('start_time')} .. {record.get('stop_time')} s, "
                 f"step {record.get('step')} s, {record.get('master')}")
    status = record.get("status")
    if status != "complete":
        parts.append(f"{status} at t = {record.get('last_time')} s")
    git = record.get("git")
    if isinstance(git, Mapping):
        parts.append(f"commit {str(git.get('commit'))[:10]}{' (modified)' if git.get('modified') else ''}")
    parts.append(str(record.get("date", "")))
    return "; ".join(parts)


def overrides_text(record: Mapping[str, object] | None) -> str:
    """The overrides and parameter sets of a run, short, for a plot title ('' when none)."""
    if record is None:
        return ""
    items = [f"{k}={v}" for k, v in _mapping(record.get("overrides")).items()]
    items += _set_names(record)
    return ", ".join(items)


def _mapping(value: object) -> Mapping[str, object]:
    """A JSON object of a record (empty when absent, null or not an object)."""
    return value if isinstance(value, Mapping) else {}


def _set_names(record: Mapping[str, object]) -> list[str]:
    """File names of the parameter sets a record lists."""
    sets = record.get("parameter_sets")
    if not isinstance(sets, list):
        return []
    return [Path(str(_mapping(s).get("path", ""))).name for s in sets]
