# SPDX-License-Identifier: BSD-2-Clause
"""The project's scenarios: build the five FMUs and pack each ``ssp/<name>/`` source folder into
``<dest>/ssp/<name>.ssp``, validated against the FMUs (what ``orchestrate build`` does)."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from lxml import etree

from .. import open_system, ssp
from ..errors import ScenarioError
from ..fmucache import sha256
from ..ssp import NS, SSD_NAME, pack_ssp

__all__ = ["FMI3_SUFFIX", "SCENARIO_DIR", "all_scenarios", "build_scenarios", "component_sources"]

REPO_ROOT = Path(__file__).resolve().parents[2]
# The scenario sources: the checkout's ssp/, or the copy an installed wheel carries (setup.py).
_PACKAGED = Path(__file__).resolve().parent / "ssp"
SCENARIO_DIR = _PACKAGED if _PACKAGED.is_dir() else REPO_ROOT / "ssp"
FMI3_SUFFIX = "_fmi3"  # build/ssp/<name>_fmi3.ssp: the scenario with the FMUs' FMI 3.0 variants


def all_scenarios(sources: str | os.PathLike = SCENARIO_DIR) -> list[str]:
    """Names of the scenario folders in ``sources`` (those holding a SystemStructure.ssd)."""
    return sorted(p.parent.name for p in Path(sources).glob(f"*/{SSD_NAME}"))


def component_sources(folder: Path) -> list[str]:
    """FMU file names the SSD refers to (``resources/X.fmu`` -> ``X.fmu``), read without the FMUs."""
    root = etree.parse(str(folder / SSD_NAME)).getroot()
    return [Path(c.get("source")).name for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)]


def build_scenarios(names: Iterable[str] | None, dest: str | os.PathLike,
                    sources: str | os.PathLike = SCENARIO_DIR, *, fmi3: bool = True) -> dict[str, Path]:
    """Build the FMUs into ``dest/fmus`` and their FMI 3.0 variants into ``dest/fmus3``, pack
    ``sources/<name>/`` (default: all) into ``dest/ssp/<name>.ssp`` and its FMI 3.0 twin (the same
    SSD and parameter files, the FMI 3.0 FMUs) into ``dest/ssp/<name>_fmi3.ssp``, each validated
    against its FMUs (``fmi3=False``: no FMI 3.0 variants and twins); returns name -> archive.
    Every FMU of the project is built when ``names`` is empty, else only those the named
    scenarios use (a report of four scenarios builds four FMUs, not nine)."""
    from fmu_src.toolchain.build import FMU_SCRIPTS, build_fmu
    from fmu_src.toolchain.fmi3 import build_fmu3

    dest, sources = Path(dest), Path(sources)
    models = list(FMU_SCRIPTS)
    if names:
        names = list(names)
        used = {Path(c).stem for name in names if (sources / name / SSD_NAME).is_file()
                for c in component_sources(sources / name)}
        models = [m for m in models if m in used]
    else:
        names = all_scenarios(sources)
    if not names:
        raise ScenarioError(f"no scenarios found in {sources}/")
    fmus2 = {p.name: p for p in (build_fmu(model, dest / "fmus") for model in models)}
    variants = [(fmus2, "")]
    if fmi3:
        fmus3 = {name: build_fmu3(path, dest / "fmus3") for name, path in fmus2.items()}
        variants.append((fmus3, FMI3_SUFFIX))
    archives = {}
    for name in names:
        for fmus, suffix in variants:
            archives[name + suffix] = _pack(name, sources, fmus, dest / "ssp" / f"{name}{suffix}.ssp")
    return archives


def _pack(name: str, sources: Path, fmus: dict[str, Path], target: Path) -> Path:
    """Pack the scenario source folder ``sources/<name>`` with ``fmus`` into ``target``, validated."""
    folder = sources / name
    if not (folder / SSD_NAME).is_file():
        known = ", ".join(all_scenarios(sources)) or "none"
        raise ScenarioError(f"{folder}: no {SSD_NAME} (scenarios in {sources}: {known})")
    needed = {}
    for component in component_sources(folder):
        if component not in fmus:
            from fmu_src.toolchain.build import FMU_SCRIPTS

            raise ScenarioError(f"{folder / SSD_NAME}: FMU '{component}' is not built by "
                                f"fmu_src.toolchain.build (it builds: "
                                f"{', '.join(sorted(m + '.fmu' for m in FMU_SCRIPTS))})")
        needed[component] = fmus[component]
    from fmu_src.toolchain.build import inputs_key, record_inputs, up_to_date

    key = inputs_key(*_files(folder), *(f"{n}\0{sha256(p)}" for n, p in sorted(needed.items())),
                     Path(ssp.__file__))
    if up_to_date(target, key):  # packed from the same files already (and validated then)
        return target
    target = pack_ssp(folder, needed, target)
    with open_system(target):  # validate the packed archive against the FMUs
        pass
    record_inputs(target, key)
    return target


def _files(folder: Path) -> list[str | Path]:
    """A scenario source folder's files, each named relative to it, in order (what a pack reads)."""
    found: list[str | Path] = []
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith(".")):
        found += [path.relative_to(folder).as_posix(), path]
    return found
