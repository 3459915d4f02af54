# SPDX-License-Identifier: BSD-2-Clause
"""The project's scenarios: build the five FMUs and pack each ``ssp/<name>/`` source folder into
``<dest>/ssp/<name>.ssp``, validated against the FMUs (what ``orchestrate build`` does)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Sequence
from functools import partial
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
CLOCKED_FMUS = "fmus_clocked"  # build/fmus_clocked/<model>_clocked.fmu: the controllers' clocked twins
FMI3_SUFFIX = "_fmi3"  # build/ssp/<name>_fmi3.ssp: the scenario with the FMUs' FMI 3.0 variants


def all_scenarios(sources: str | os.PathLike = SCENARIO_DIR) -> list[str]:
    """Names of the scenario folders in ``sources`` (those holding a SystemStructure.ssd)."""
    return sorted(p.parent.name for p in Path(sources).glob(f"*/{SSD_NAME}"))


def component_sources(folder: Path) -> list[str]:
    """FMU file names the SSD refers to (``resources/X.fmu`` -> ``X.fmu``), read without the FMUs."""
    root = etree.parse(str(folder / SSD_NAME)).getroot()
    return [Path(c.get("source")).name for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)]


def build_scenarios(names: Iterable[str] | None, dest: str | os.PathLike,
                    sources: str | os.PathLike = SCENARIO_DIR, *, fmi3: bool = True,
                    platforms: Sequence[str] | None = None, force: bool = False,
                    progress: Callable[[str], None] | None = None,
                    root: Path | None = None, jobs: int = 1) -> dict[str, Path]:
    """Build the FMUs into ``dest/fmus`` and their FMI 3.0 variants into ``dest/fmus3``, pack
    ``sources/<name>/`` (default: all) into ``dest/ssp/<name>.ssp`` and its FMI 3.0 twin (the same
    SSD and parameter files, the FMI 3.0 FMUs) into ``dest/ssp/<name>_fmi3.ssp``, each validated
    against its FMUs (``fmi3=False``: no FMI 3.0 variants and twins); returns name -> archive.
    Every FMU of the project is built when ``names`` is empty, else only those the named
    scenarios use (a report of four scenarios builds four FMUs, not nine). ``platforms``: at
    least these (default: all this machine can build); ``force``: rebuild what is up to date;
    ``progress`` receives one line per product as it is done; ``root``: the FMUs' source tree
    (default: this checkout's, or the installed package's); ``jobs``: processes that build at
    once (more than 1 only from a fresh process such as ``orchestrate build``: a process that has
    loaded Python FMUs has their resources, a partial copy of pythonfmu, on ``sys.path``, which
    the workers would inherit)."""
    from fmu_src.toolchain.build import (
        FMU_SCRIPTS,
        REPO_ROOT,
        build_fmu,
        buildable_platforms,
        fmu_current,
        prune_kept,
    )
    from fmu_src.toolchain.fmi3 import build_fmu3, fmu3_current

    root = REPO_ROOT if root is None else root

    say = progress or (lambda line: None)
    dest, sources = Path(dest), Path(sources)
    if platforms is None:
        platforms, note = buildable_platforms()
        if note:
            say(note)
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
    on = ", ".join(platforms)
    stale = [m for m in models if force or not fmu_current(m, dest / "fmus", root, platforms)]
    _in_parallel({f"{m}.fmu ({on})": partial(build_fmu, m, dest / "fmus", root, platforms, force=force)
                  for m in stale}, say, jobs, (root, platforms))
    if len(stale) < len(models):
        say(f"{len(models) - len(stale)} of {len(models)} FMUs up to date")
    fmus2 = {f"{m}.fmu": dest / "fmus" / f"{m}.fmu" for m in models}  # where build_fmu writes them
    variants = [(fmus2, "")]
    if fmi3:
        stale3 = [n for n, p in fmus2.items() if force or not fmu3_current(p, dest / "fmus3", root)]
        _in_parallel({f"{n} (FMI 3.0)": partial(build_fmu3, fmus2[n], dest / "fmus3", root, force=force)
                      for n in stale3}, say, jobs, (root, platforms))
        if len(stale3) < len(fmus2):
            say(f"{len(fmus2) - len(stale3)} of {len(fmus2)} FMI 3.0 variants up to date")
        variants.append(({n: dest / "fmus3" / n for n in fmus2}, FMI3_SUFFIX))
    archives = {}
    for name in names:
        for fmus, suffix in variants:
            target = dest / "ssp" / f"{name}{suffix}.ssp"
            archives[name + suffix] = _pack(name, sources, fmus, target, force, root)
    if fmi3:
        archives |= _clocked(names, sources, dest, fmus2, root, force, say)
    removed, kept = prune_kept()
    if removed:
        say(f"build cache: {removed} least recently used files removed, {kept / 2**20:.0f} MB kept")
    return archives


def _clocked(names: list[str], sources: Path, dest: Path, fmus2: dict[str, Path], root: Path, force: bool,
             say: Callable[[str], None]) -> dict[str, Path]:
    """The clocked variant of each scenario with a controller (:mod:`.clocked`): its twins built
    into ``dest/fmus_clocked``, its sources written into ``dest/clocked/<name>``, packed into
    ``dest/ssp/<name>_clocked.ssp`` (the other FMUs FMI 2.0: the scenario as before but for the
    controller)."""
    from fmu_src.toolchain.fmi3 import build_fmu3, fmu3_current

    from .clocked import CLOCKED_SCENARIO_SUFFIX, clocked_folder

    archives = {}
    for name in names:
        renamed = clocked_folder(sources / name, dest / "clocked" / name)
        if renamed is None:
            continue
        fmus = dict(fmus2)
        for plain, twin in renamed.items():
            if force or not fmu3_current(fmus2[plain], dest / CLOCKED_FMUS, root, clocked=True):
                build_fmu3(fmus2[plain], dest / CLOCKED_FMUS, root, force=force, clocked=True)
                say(f"{twin} (FMI 3.0, clocked): built")
            fmus[twin] = dest / CLOCKED_FMUS / twin
        target = dest / "ssp" / f"{name}{CLOCKED_SCENARIO_SUFFIX}.ssp"
        archives[name + CLOCKED_SCENARIO_SUFFIX] = _pack(name, dest / "clocked", fmus, target, force, root,
                                                         origin=sources / name)
    return archives


def _in_parallel(builds: dict[str, Callable[[], Path]], say: Callable[[str], None], jobs: int,
                 shared: tuple[Path, Sequence[str]]) -> None:
    """Run ``builds`` (label -> a product's build) in up to ``jobs`` processes (1: in this
    process), saying each as it is done; ``shared``: the source root and platforms of what the
    builds share (compiled first). The first failure is raised once the builds under way have ended."""
    if not builds:
        return
    workers = max(1, min(len(builds), jobs))
    started = time.perf_counter()
    if workers == 1:
        for number, (label, build) in enumerate(builds.items(), 1):
            build()
            say(f"[{number}/{len(builds)}] {label}: built ({time.perf_counter() - started:.1f} s)")
        return
    # Imported here: 'orchestrate run' imports this module (the stale-build check) and never builds;
    # multiprocessing and concurrent.futures are 1 MB of every run's peak memory (issue 46).
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    _ensure_runtimes(*shared)  # once, before the workers that share them
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = {pool.submit(build): label for label, build in builds.items()}
        for number, future in enumerate(as_completed(futures), 1):
            future.result()
            say(f"[{number}/{len(builds)}] {futures[future]}: built ({time.perf_counter() - started:.1f} s)")


def _ensure_runtimes(root: Path, platforms: Sequence[str]) -> None:
    """The runtimes unpacked and what every FMU shares compiled, once, before the workers."""
    from fmu_src.toolchain.build import compile_shared
    from fmu_src.toolchain.fmi3 import compile_shared_fmi3

    compile_shared(root, platforms)
    compile_shared_fmi3(root, platforms)


def _pack(name: str, sources: Path, fmus: dict[str, Path], target: Path, force: bool = False,
          root: Path | None = None, origin: Path | None = None) -> Path:
    """Pack the scenario source folder ``sources/<name>`` with ``fmus`` into ``target``, validated;
    ``origin``: the folder it was derived from (a clocked variant's), whose files the record names
    as the sources (so that editing them makes the archive stale)."""
    from fmu_src.toolchain import stamps
    from fmu_src.toolchain.build import FMU_SCRIPTS, REPO_ROOT

    folder = sources / name
    if not (folder / SSD_NAME).is_file():
        known = ", ".join(all_scenarios(sources)) or "none"
        raise ScenarioError(f"{folder}: no {SSD_NAME} (scenarios in {sources}: {known})")
    needed = {}
    for component in component_sources(folder):
        if component not in fmus:
            raise ScenarioError(f"{folder / SSD_NAME}: FMU '{component}' is not built by "
                                f"fmu_src.toolchain.build (it builds: "
                                f"{', '.join(sorted(m + '.fmu' for m in FMU_SCRIPTS))})")
        needed[component] = fmus[component]
    files = _scenario_files(folder)
    key = stamps.digest(*_named(folder, files), *(f"{n}\0{sha256(p)}" for n, p in sorted(needed.items())),
                        Path(ssp.__file__))
    root = REPO_ROOT if root is None else root
    originals = _scenario_files(origin) if origin is not None else files
    recorded: dict[str, str] = stamps.source_digests([*originals, Path(ssp.__file__)], root)
    for fmu in needed.values():
        recorded |= stamps.recorded_sources(fmu)
    if not force and stamps.up_to_date(target, key):  # packed from the same files (and validated then)
        if stamps.recorded_sources(target) != recorded:  # its FMUs rebuilt, to the same bytes, from
            stamps.record(target, key, recorded, root)  # edited sources: the archive is current again
        return target
    stamps.forget(target)
    target = pack_ssp(folder, needed, target)
    with open_system(target):  # validate the packed archive against the FMUs
        pass
    stamps.record(target, key, recorded, root)
    return target


def _scenario_files(folder: Path) -> list[Path]:
    """A scenario source folder's files, in order (what a pack reads)."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith("."))


def _named(folder: Path, files: list[Path]) -> list[str | Path]:
    """Each file named relative to ``folder``, then the file (the digest's parts)."""
    found: list[str | Path] = []
    for path in files:
        found += [path.relative_to(folder).as_posix(), path]
    return found
