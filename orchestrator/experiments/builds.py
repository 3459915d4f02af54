# SPDX-License-Identifier: BSD-2-Clause
"""The stale-build rule of this project, plugged into ``orchestrate run``/``validate`` through the
entry-point group ``orchestrate.checks`` (:func:`orchestrator.cli.scenario_checks`).

``orchestrate build`` makes build/ssp/NAME.ssp from ssp/NAME/ and the FMUs in build/fmus/ from
fmu_src/ and controller/, and records beside each product the source files it read, each with
its digest (``fmu_src/toolchain/stamps.py``: the one definition of a build's inputs). A build
one of whose sources has other bytes now would run what the user no longer has, so ``run``
refuses it (``--allow-stale`` runs it anyway) and ``validate`` warns; ``orchestrate build``
rebuilds exactly what such a message names.
"""

from __future__ import annotations

from pathlib import Path

from fmu_src.toolchain import stamps

from ..cli import BUILD_DIR, fmu_dirs
from ..ssp import SSD_NAME
from .scenarios import FMI3_SUFFIX

__all__ = ["stale_build"]


def _advice(product: Path, changed: list[str], command: str) -> str:
    more = f" (and {len(changed) - 1} more)" if len(changed) > 1 else ""
    return (f"{product} is stale: {changed[0]}{more} changed since it was built: run '{command}' "
            "(it rebuilds what is stale; --force rebuilds everything), or give --allow-stale")


def stale_build(scenario: Path) -> str:
    """Why the build that ``scenario`` runs from is stale ('' when it is not): a built archive
    build/ssp/NAME.ssp against the sources it records (ssp/NAME/ included: a file added there
    counts), a source folder's FMUs in build/fmus/ against theirs (paths relative to the working
    directory, as 'orchestrate build' writes them). A product without a record is not judged."""
    if scenario.is_file() and scenario.suffix == ".ssp":
        archive = BUILD_DIR / "ssp" / scenario.name
        if not (archive.is_file() and archive.resolve() == scenario.resolve()):
            return ""
        ssds = [label for label in stamps.recorded_sources(archive) if label.endswith(f"/{SSD_NAME}")]
        changed = stamps.changed_sources(archive, [label.rpartition("/")[0] for label in ssds])
        name = scenario.stem.removesuffix(FMI3_SUFFIX)
        return _advice(archive, changed, f"orchestrate build {name}") if changed else ""
    dirs = fmu_dirs(scenario)
    if dirs and not any((scenario / "resources").glob("*.fmu")):
        for fmu in sorted(dirs[0].glob("*.fmu")):
            changed = stamps.changed_sources(fmu)
            if changed:
                return _advice(fmu, changed, "orchestrate build")
    return ""
