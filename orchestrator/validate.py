# SPDX-License-Identifier: BSD-2-Clause
"""Every check that can be made before a simulation, without simulating: ``orchestrate validate``.

One code path for ``run`` and ``validate``: :func:`check_scenario` unpacks the archive (unsafe
members left out), reads the SSD and its parameter files against the SSP schemas, and builds the
:class:`~orchestrator.system.System` (FMU model descriptions, connections, units, parameters,
unconnected inputs, algebraic loops). Each stage goes as far as what is known allows, so one broken
FMU or a schema error still leaves the other components, connections and parameters checked.
``run`` refuses a scenario with any error; :func:`validate` reports them all, plus warnings.

Severity: an *error* is what makes ``orchestrate run`` refuse the scenario (or fail at once); a
*warning* is what fmpy's full FMU validation (``fmpy.validation.validate_fmu``: schema, variable
names, ModelStructure) finds beyond that, i.e. FMI non-compliance that this engine tolerates but
another importer might not, and a scenario without a stop time (``run`` then needs one).
"""

from __future__ import annotations

import os
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from tempfile import TemporaryDirectory

from .errors import OrchestratorError, ScenarioError, UsageError, is_option, option
from .fmi import load_problem
from .fmucache import materialize, release, unpack_fmu
from .plan import NS_PER_S, GridError, grid
from .ssp import (
    DEFAULT_LIMITS,
    SSD_NAME,
    Limits,
    SystemStructure,
    scan_parameter_set,
    scan_scenario,
    test_zip,
    unpack_scenario,
)
from .system import System

__all__ = ["DEFAULT_MASTER", "DEFAULT_STEP", "STEP_ANNOTATIONS", "Problem", "Validation", "check_scenario",
           "choose_master", "no_step", "timing", "validate"]

DEFAULT_STEP = 1e-3
DEFAULT_MASTER = "gauss-seidel"
STEP_ANNOTATIONS = ("a step annotation (libcosim's osp:FixedStepAlgorithm baseStepSize in the "
                    "DefaultExperiment, or OMSimulator's oms:FixedStepMaster stepSize in the System)")


def no_step(structure: SystemStructure) -> str:
    """Why a run of ``structure`` would take the default step ('' when the SSD gives one)."""
    if structure.experiment.step is not None:
        return ""
    return (f"{structure.ssd_file}: no communication step: the SSD has no step annotation "
            f"{STEP_ANNOTATIONS.removeprefix('a step annotation ')}; "
            f"running at the default {DEFAULT_STEP:g} s (give --step)")


@dataclass(frozen=True)
class Problem:
    """One finding, on one line naming the file, component and connector or variable."""

    message: str
    severity: str = "error"

    def __str__(self) -> str:
        return f"{self.severity}: {self.message}"


@dataclass(frozen=True)
class Validation:
    """What :func:`validate` found, and how much it checked."""

    scenario: str
    problems: tuple[Problem, ...]
    components: int = 0
    connections: int = 0
    parameters: int = 0

    @property
    def errors(self) -> list[Problem]:
        """The problems that make ``run`` refuse the scenario."""
        return [p for p in self.problems if p.severity == "error"]

    @property
    def ok(self) -> bool:
        """True when there is no error (warnings allowed)."""
        return not self.errors


def check_scenario(scenario: str | os.PathLike, stack: ExitStack, *,
                   parameter_sets: Iterable[str | os.PathLike] = (),
                   overrides: Mapping[str, object] | None = None,
                   fmu_warnings: bool = False,
                   fmu_dirs: Iterable[str | os.PathLike] = (),
                   limits: Limits = DEFAULT_LIMITS,
                   unpack_fmus: bool = False,
                   root: str | os.PathLike | None = None,
                   strict_fmus: bool = False,
                   load: bool = False) -> tuple[System | None, list[str], list[str]]:
    """Unpack (into a folder ``stack`` removes; within ``limits``), read and check a scenario, every
    stage as far as it can go. Returns the system (None when no SSD could be read; its ``schedule``
    is empty when there are errors), the errors and the warnings (``fmu_warnings``: add fmpy's full
    FMU validation). FMUs missing from the scenario are looked up by file name in ``fmu_dirs``.
    ``unpack_fmus``: also read every member of every FMU, as a run unpacks it (a corrupt member, or
    one whose declared size lies, is an error here rather than when the run starts). ``root``: a
    folder scenario may reference files below it with '..' (never an archive). ``strict_fmus``:
    what fmpy's checks of a model description find is an error even where the FMU still runs (else
    a warning). ``load``: also load every FMU's library as a run would (:func:`load_problems`)."""
    path = Path(scenario)
    if root is not None and not path.is_dir():
        raise UsageError(f"--root {root}: only a scenario folder may reference files outside itself, "
                         f"not an archive ({path})")
    if root is not None and not Path(root).is_dir():
        raise UsageError(f"--root {root}: no such folder")
    if root is not None and not path.resolve().is_relative_to(Path(root).resolve()):
        raise UsageError(f"--root {root}: the scenario {path} is not below it")
    top = Path(root) if root is not None else None
    folder, errors = unpack_scenario(scenario, stack, limits, top)
    if folder is None:
        return None, errors, []
    reading = scan_scenario(folder, f"{path}:{SSD_NAME}" if path.is_file() else str(folder / SSD_NAME),
                            [Path(d) for d in fmu_dirs], top)
    errors += reading.problems
    sets, unreadable = [], False
    for file in parameter_sets:
        parameter_set, problems = scan_parameter_set(file)
        errors += problems
        unreadable = unreadable or bool(problems)
        if parameter_set is not None:
            sets.append(parameter_set)
    structure = reading.structure
    if structure is None:
        return None, errors, []
    if unpack_fmus:
        label = path.name if path.is_file() else str(folder)
        for c in structure.components:
            if c.name not in reading.no_fmu:
                where = f"{label}: component '{c.name}': FMU '{c.source.name}'"
                errors += test_zip(materialize(c.source), where)
    # a value lost from a --parameter-set may have been meant for any input of any component
    partial = {c.name for c in structure.components} if unreadable else reading.partial
    system = System(structure, sets, overrides, strict=False, no_fmu=reading.no_fmu, partial=partial,
                    fmu_warnings=fmu_warnings, strict_fmus=strict_fmus)
    loaded = load_problems(system, stack) if load else []
    return system, errors + system.problems + loaded, [*reading.notes, *system.warnings]


def load_problems(system: System, stack: ExitStack) -> list[str]:
    """Each component whose FMU's library the loader refuses, one line naming the SSD, component,
    FMU, file and the loader's reason (what a run would fail on at instantiation). Each FMU is
    unpacked as a run unpacks it (into the cache, which the run then reuses) and loaded once, in a
    child process (:func:`orchestrator.fmi.load_problem`)."""
    found: list[str] = []
    reasons: dict[Path, str] = {}
    for comp in system.components.values():
        assert comp.model.coSimulation is not None  # System keeps Co-Simulation FMUs only
        if comp.fmu not in reasons:
            fallback = stack.enter_context(TemporaryDirectory(prefix="orchestrate-load-")) + "/fmu"
            try:
                folder = unpack_fmu(comp.fmu, fallback)
            except (zipfile.BadZipFile, zlib.error, ValueError, OSError):  # damaged: already a finding
                reasons[comp.fmu] = ""
                continue
            try:
                reasons[comp.fmu] = load_problem(folder, comp.model.fmiVersion,
                                                 comp.model.coSimulation.modelIdentifier)
            finally:
                release(folder)
        if reasons[comp.fmu]:
            found.append(f"{system.ssd}: component '{comp.name}': FMU '{comp.fmu.name}': cannot load "
                         f"{reasons[comp.fmu]}")
    return found


def choose_master(structure: SystemStructure, requested: str | None = None) -> tuple[str, str]:
    """The master a run uses and why: ``requested`` (``--master``) when given, else the one the
    SSD's algorithm annotation implies (libcosim's osp:FixedStepAlgorithm: jacobi, OMSimulator's
    oms:FixedStepMaster: gauss-seidel), else the default, gauss-seidel."""
    if requested is not None:
        return requested, option("master")
    if structure.experiment.algorithm is not None:
        return structure.experiment.algorithm, structure.experiment.algorithm_from
    return DEFAULT_MASTER, "the default (the SSD names no algorithm)"


def timing(structure: SystemStructure, stop_time: float | None = None,
           step: float | None = None, start_time: float | None = None) -> tuple[float, float, float]:
    """Start, stop and step of a run: the arguments, else the SSD's DefaultExperiment and step
    annotation (1 ms if none).

    The run must be a whole number of steps (in the integer nanoseconds the masters count in):
    a stop time the step does not divide would end the run early without a word, and a step longer
    than the run would run no step at all. Every message says where each value came from (the
    option or the SSD); UsageError when an option is among the values at fault, ScenarioError when
    only the SSD's own values are (or there is no stop)."""
    experiment = structure.experiment
    start = start_time if start_time is not None else experiment.start_time
    stop = stop_time if stop_time is not None else experiment.stop_time
    if stop is None:
        raise ScenarioError(f"{structure.ssd_file}: no stopTime in DefaultExperiment; give a stop time")
    h = step if step is not None else experiment.step if experiment.step is not None else DEFAULT_STEP
    ssd = structure.ssd_file
    origin = {"start time": option("start_time") if start_time is not None else ssd,
              "stop time": option("stop_time") if stop_time is not None else ssd,
              "communication step": option("step") if step is not None else
              ssd if experiment.step is not None else "default"}

    def error(message: str, *at_fault: str) -> OrchestratorError:
        options = [origin[name] for name in at_fault if is_option(origin[name])]
        return (UsageError if options else ScenarioError)(f"{', '.join(options) or ssd}: {message}")

    def source(*names: str) -> str:
        """`` (from SSD)`` for the values the SSD (or the default) gave, when options are named in
        front of the message (with none, the SSD is, and it gave them all)."""
        given = sorted({origin[name] for name in names if not is_option(origin[name])})
        options = any(is_option(name) for name in origin.values())
        return f" (from {' and '.join(given)})" if given and options else ""

    step_text = f"the step {h:g} s{source('communication step')}"
    run_text = f"the run {start:g} .. {stop:g} s{source('start time', 'stop time')}"
    try:
        t0, hn, n = grid(start, stop, h)
    except GridError as exc:
        at_fault = list(exc.quantities)
        raise error(f"{exc}{source(*at_fault)}", *at_fault) from exc
    t1 = round(stop * NS_PER_S)
    if n < 1:
        raise error(f"{step_text} is longer than {run_text}: no step would be taken", *origin)
    if (t1 - t0) % hn:
        raise error(f"{step_text} does not divide {run_text} (the last step would end at "
                    f"{(t0 + n * hn) / NS_PER_S:.9g} s); stop at {start + n * h:.9g} or "
                    f"{start + (n + 1) * h:.9g} s, or choose a step that divides {stop - start:.9g} s",
                    *origin)
    return start, stop, h


def validate(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
             overrides: Mapping[str, object] | None = None,
             fmu_dirs: Iterable[str | os.PathLike] = (), limits: Limits = DEFAULT_LIMITS,
             root: str | os.PathLike | None = None, strict_fmus: bool = False) -> Validation:
    """Check a scenario without simulating and report every problem found; nothing is written.

    Parameters
    ----------
    scenario : path
        ``.ssp`` archive or folder holding ``SystemStructure.ssd``.
    parameter_sets, overrides, fmu_dirs, limits, root, strict_fmus
        As for :func:`orchestrator.open_system` (what ``run`` would get).

    Returns
    -------
    Validation
        Errors (what ``run`` refuses) and warnings, one :class:`Problem` each, and how much was
        checked.
    """
    with ExitStack() as stack:
        system, errors, warnings = check_scenario(scenario, stack, parameter_sets=parameter_sets,
                                                  overrides=overrides, fmu_warnings=True, fmu_dirs=fmu_dirs,
                                                  limits=limits, unpack_fmus=True, root=root,
                                                  strict_fmus=strict_fmus, load=True)
    if system is None:
        return Validation(str(scenario), tuple(Problem(e) for e in errors))
    structure = system.structure
    if no_step(structure):
        warnings.append(no_step(structure))
    if structure.experiment.stop_time is None:
        warnings.append(f"{system.ssd}: no stopTime in DefaultExperiment; 'run' needs --stop-time")
    else:
        try:
            timing(structure)
        except ScenarioError as exc:
            errors += exc.problems
    problems = [Problem(e) for e in errors] + [Problem(w, "warning") for w in warnings]
    return Validation(str(scenario), tuple(problems), len(structure.components), len(structure.connections),
                      system.values_checked)
