"""The project's scenarios: build the five FMUs and pack each ``ssp/<name>/`` source folder into
``<dest>/ssp/<name>.ssp``, validated against the FMUs (what ``orchestrate build`` does)."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from lxml import etree

from .. import open_system
from ..errors import ScenarioError
from ..ssp import NS, SSD_NAME, pack_ssp

__all__ = ["SCENARIO_DIR", "all_scenarios", "build_scenarios", "component_sources"]

REPO_ROOT = Path(__file__).resolve().parents[2]
SCENARIO_DIR = REPO_ROOT / "ssp"


def all_scenarios(sources: str | os.PathLike = SCENARIO_DIR) -> list[str]:
    """Names of the scenario folders in ``sources`` (those holding a SystemStructure.ssd)."""
    return sorted(p.parent.name for p in Path(sources).glob(f"*/{SSD_NAME}"))


def component_sources(folder: Path) -> list[str]:
    """FMU file names the SSD refers to (``resources/X.fmu`` -> ``X.fmu``), read without the FMUs."""
    root = etree.parse(str(folder / SSD_NAME)).getroot()
    return [Path(c.get("source")).name for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)]


def build_scenarios(names: Iterable[str] | None, dest: str | os.PathLike,
                    sources: str | os.PathLike = SCENARIO_DIR) -> dict[str, Path]:
    """Build the FMUs into ``dest/fmus`` and pack ``sources/<name>/`` (default: all) into
    ``dest/ssp/<name>.ssp``, each validated against its FMUs; returns name -> archive."""
    from fmu_src.build import build_all

    dest, sources = Path(dest), Path(sources)
    names = list(names) if names else all_scenarios(sources)
    if not names:
        raise ScenarioError(f"no scenarios found in {sources}/")
    fmus = {p.name: p for p in build_all(dest / "fmus")}
    archives = {}
    for name in names:
        folder = sources / name
        if not (folder / SSD_NAME).is_file():
            known = ", ".join(all_scenarios(sources)) or "none"
            raise ScenarioError(f"{folder}: no {SSD_NAME} (scenarios in {sources}: {known})")
        needed = {}
        for component in component_sources(folder):
            if component not in fmus:
                raise ScenarioError(f"{folder / SSD_NAME}: FMU '{component}' is not built by "
                                    f"fmu_src.build (built: {', '.join(sorted(fmus))})")
            needed[component] = fmus[component]
        target = pack_ssp(folder, needed, dest / "ssp" / f"{name}.ssp")
        with open_system(target):  # validate the packed archive against the FMUs
            pass
        archives[name] = target
    return archives
