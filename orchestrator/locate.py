# SPDX-License-Identifier: BSD-2-Clause
"""Where a scenario is, however it was named: a ``.ssp`` file, a folder holding
``SystemStructure.ssd``, or the name of a built scenario (``build/ssp/NAME.ssp``), and where a
scenario source folder takes the FMUs it does not hold. The command line and the Python API
resolve names the same way; a name that is none of these gets the names that are (did you
mean ...?), and an FMU given as a scenario is told how to run one."""

from __future__ import annotations

import os
from pathlib import Path

from .errors import ScenarioError

__all__ = ["BUILD_DIR", "built_scenarios", "fmu_dirs", "resolve_scenario"]

BUILD_DIR = Path("build")
SHOWN = 12  # built names listed in a message


def built_scenarios(build: Path = BUILD_DIR) -> list[str]:
    """The names of the built scenarios (``build/ssp/*.ssp``), sorted ([] when there are none)."""
    try:
        return sorted(p.stem for p in (build / "ssp").glob("*.ssp") if p.is_file())
    except OSError:
        return []


def resolve_scenario(scenario: str | os.PathLike) -> Path:
    """The path a scenario name stands for, as ``orchestrate run`` and :func:`orchestrator.run`
    take it.

    Parameters
    ----------
    scenario : path or str
        An existing ``.ssp`` file or scenario folder (returned as it is), else the name of a built
        scenario (``build/ssp/NAME.ssp``, relative to the working directory).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ScenarioError
        Nothing of that name: the message names what was looked for, the closest built names
        (did you mean ...?) and the others; an ``.fmu`` file is not a scenario, and the message
        says how to run one.
    """
    path = Path(scenario)
    if path.suffix.lower() == ".fmu" and path.is_file():
        raise ScenarioError(f"{path} is an FMU, not a scenario (an .ssp archive or a folder holding "
                            f"SystemStructure.ssd): run it alone with 'fmpy simulate {path}', or put it in "
                            "a scenario's resources/ with an SSD that connects its inputs")
    if path.exists():
        return path
    built = BUILD_DIR / "ssp" / f"{path.name}.ssp"
    if path.name == str(scenario) and built.is_file():
        return built
    names = built_scenarios()
    message = f"no scenario '{scenario}': not a file or folder"
    if path.name != str(scenario) or path.suffix:
        raise ScenarioError(f"{message}")
    message += f", and no built scenario {built}"
    import difflib  # here: only a scenario not found needs it

    close = difflib.get_close_matches(str(scenario), names, n=3, cutoff=0.6)
    if close:
        message += f"; did you mean {' or '.join(close)}?"
    if names:
        shown = ", ".join(names[:SHOWN]) + (f" and {len(names) - SHOWN} more" if len(names) > SHOWN else "")
        message += f" (built: {shown})"
    source = Path("ssp") / str(scenario)
    if (source / "SystemStructure.ssd").is_file():
        message += f"; its source {source} runs as it is, or 'orchestrate build' packs it"
    elif not names:
        message += " (nothing is built here: run 'orchestrate build' first, in the project's folder)"
    raise ScenarioError(message)


def fmu_dirs(scenario: str | os.PathLike) -> list[Path]:
    """Where a scenario source folder (no FMUs under resources/) takes its FMUs: the build/fmus/
    of its project (``PROJECT/ssp/NAME`` -> ``PROJECT/build/fmus``), whatever the working
    directory, else build/fmus/ of the working directory."""
    scenario = Path(scenario)
    if not scenario.is_dir():
        return []
    candidates = [scenario.resolve().parent.parent / BUILD_DIR / "fmus", BUILD_DIR / "fmus"]
    return [d for d in candidates if d.is_dir()][:1]
