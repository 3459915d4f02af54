# SPDX-License-Identifier: BSD-2-Clause
"""The stale-build rule of this project, plugged into ``orchestrate run``/``validate`` through the
entry-point group ``orchestrate.checks`` (:func:`orchestrator.cli.scenario_checks`).

``orchestrate build`` makes build/ssp/NAME.ssp from ssp/NAME/ and the FMUs in build/fmus/ from
fmu_src/ and controller/: a build older than any of its sources would run what the user no longer
has, so ``run`` refuses it (``--allow-stale`` runs it anyway) and ``validate`` warns.
"""

from __future__ import annotations

from pathlib import Path

from ..cli import BUILD_DIR, fmu_dirs

__all__ = ["FMU_SOURCES", "SOURCE_DIR", "stale_build"]

SOURCE_DIR = Path("ssp")
FMU_SOURCES = (Path("fmu_src"), Path("controller"))  # what 'orchestrate build' makes the FMUs from


def _files(folder: Path) -> list[Path]:
    return [f for f in folder.rglob("*") if f.is_file() and "__pycache__" not in f.parts
            and not f.name.startswith(".")]


def _newer(target: Path, sources: list[Path]) -> Path | None:
    """The most recently modified file of ``sources`` (folders, walked) modified after ``target``."""
    files = [f for folder in sources if folder.is_dir() for f in _files(folder)]
    newest = max(files, key=lambda f: f.stat().st_mtime, default=None)
    return newest if newest is not None and newest.stat().st_mtime > target.stat().st_mtime else None


def stale_build(scenario: Path) -> str:
    """Why the build that ``scenario`` runs from is older than its sources ('' when it is not): a
    built archive build/ssp/NAME.ssp against ssp/NAME/ and the FMU sources, a source folder's
    FMUs in build/fmus/ against the FMU sources (paths relative to the working directory, as
    'orchestrate build' writes them)."""
    if scenario.is_file() and scenario.suffix == ".ssp":
        archive = BUILD_DIR / "ssp" / scenario.name
        if not (archive.is_file() and archive.resolve() == scenario.resolve()):
            return ""
        folder = SOURCE_DIR / scenario.stem
        changed = _newer(archive, [folder, *FMU_SOURCES])
        if changed is None:
            return ""
        other = (f", or run the source folder {folder} (with the FMUs of {BUILD_DIR / 'fmus'})"
                 if changed.is_relative_to(folder) else "")
        return (f"{archive} is older than {changed} (changed after the build): run 'orchestrate build' "
                f"again{other}, or give --allow-stale")
    dirs = fmu_dirs(scenario)
    if dirs and not any((scenario / "resources").glob("*.fmu")):
        fmus = sorted(dirs[0].glob("*.fmu"), key=lambda f: f.stat().st_mtime)
        changed = _newer(fmus[0], list(FMU_SOURCES)) if fmus else None
        if changed is not None:
            return (f"{fmus[0]} is older than {changed} (changed after the build): run 'orchestrate build' "
                    "again, or give --allow-stale")
    return ""


