# SPDX-License-Identifier: BSD-2-Clause
"""fmpy-based SSP co-simulation orchestrator: ``orchestrator.run(scenario, RunOptions(...))`` or
``orchestrate`` (also ``python -m orchestrator``).

A scenario is named as on the command line: a ``.ssp`` archive, a folder holding
``SystemStructure.ssd``, or the name of a built scenario (``run("pendulum")`` runs
``build/ssp/pendulum.ssp``).

Data flows top to bottom through the modules: ssp (read the archive) -> system (validated
components, connections, propagation order) -> plan (the one schedule every executor steps) ->
master (the Python master; native: the compiled executor) -> results and output (the recorder, the
result file and its provenance); validate runs ssp and system as far as they go and reports
everything (``orchestrate validate``).
"""

from __future__ import annotations

from . import _startup  # first: SIGINT/SIGTERM during the imports below are one line

# isort: split
import fnmatch
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

from . import native, provenance
from .errors import (
    EngineNote,
    Interrupted,
    LoopError,
    NonFiniteError,
    OrchestratorError,
    ScenarioError,
    ScenarioWarning,
    SimulationError,
    TimeLimitError,
    UsageError,
    option,
)
from .inputs import InputSeries, read_inputs
from .locate import fmu_dirs as _fmu_dirs
from .locate import resolve_scenario
from .master import MASTERS, Master, tracing
from .output import RunOutput, system_columns
from .result import RunOptions, RunResult
from .ssp import DEFAULT_LIMITS, Limits
from .system import PortRef, System
from .validate import DEFAULT_STEP, check_scenario, choose_master, no_step, timing

_startup.numpy_loaded()  # OpenBLAS has read its thread count: the user's environment for children

__all__ = ["DEFAULT_STEP", "MASTERS", "EngineNote", "Interrupted", "Limits", "LoopError", "NonFiniteError",
           "OrchestratorError",
           "PortRef", "RunOptions", "RunResult", "ScenarioError", "ScenarioWarning", "SimulationError",
           "TimeLimitError", "UsageError", "open_system", "resolve_scenario", "run", "system_columns"]

# The engine's modules a user may reach for (dir() lists them with __all__, not the imports above).
MODULES = ("errors", "formats", "inputs", "inspection", "plots", "provenance", "result", "results", "ssp",
           "system", "units", "validate")


def __dir__() -> list[str]:
    """The public names only (``dir(orchestrator)``, tab completion): no ``np``, ``os``, ``Path``."""
    return sorted({*__all__, *MODULES})


def __getattr__(name: str) -> object:
    """The engine's modules on first use (``orchestrator.plots`` imports matplotlib only then)."""
    if name in MODULES:
        import importlib

        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@contextmanager
def open_system(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
                overrides: Mapping[str, object] | None = None,
                fmu_dirs: Iterable[str | os.PathLike] = (),
                limits: Limits = DEFAULT_LIMITS, root: str | os.PathLike | None = None,
                strict_fmus: bool = False) -> Iterator[System]:
    """Open, read and validate a scenario; an archive stays unpacked until the ``with`` block ends.

    Parameters
    ----------
    scenario : path or str
        ``.ssp`` archive, folder holding ``SystemStructure.ssd``, or a built scenario's name
        (:func:`~orchestrator.locate.resolve_scenario`).
    parameter_sets : iterable of path
        ``.ssv`` files naming parameters ``<component>.<variable>``, after the SSD's own.
    overrides : mapping, optional
        ``{"component.variable": value}``, applied last.
    fmu_dirs : iterable of path
        Where FMUs missing from the scenario are looked up by file name (default for a source
        folder ``PROJECT/ssp/NAME``: ``PROJECT/build/fmus``, as ``orchestrate run`` does).
    limits : Limits
        What an archive and its FMUs may unpack to (:class:`~orchestrator.ssp.Limits`).
    root : path, optional
        A folder scenario may reference files below this folder with '..' (never an archive).
    strict_fmus : bool
        What fmpy's checks of a model description find is an error (else a warning, where the FMU
        still runs).

    Yields
    ------
    System
        The validated system (:class:`~orchestrator.system.System`).

    Raises
    ------
    ScenarioError
        Every problem found (the checks of :func:`orchestrator.validate.validate`, without its
        warnings).
    """
    scenario = resolve_scenario(scenario)
    fmu_dirs = list(fmu_dirs) or _fmu_dirs(scenario)
    with ExitStack() as stack:
        system, errors, _ = check_scenario(scenario, stack, parameter_sets=parameter_sets,
                                           overrides=overrides, fmu_dirs=fmu_dirs, limits=limits, root=root,
                                           strict_fmus=strict_fmus)
        if system is None or errors:
            raise ScenarioError(errors)
        yield system


def run(scenario: str | os.PathLike, options: RunOptions | None = None, /, *,
        progress: Callable[[int, int], None] | None = None) -> RunResult:
    """Run a scenario and return its :class:`RunResult`.

    Parameters
    ----------
    scenario : path or str
        A ``.ssp`` archive, a folder holding ``SystemStructure.ssd``, or the name of a built
        scenario (``"pendulum"``: ``build/ssp/pendulum.ssp``), as ``orchestrate run`` takes it.
    options : RunOptions, optional
        Timing, parameters, master, output file, limits (:class:`RunOptions`; default: the
        scenario's own experiment, no output file).
    progress : callable, optional
        ``progress(done, total)``, called about every 1 % of the steps.

    Returns
    -------
    RunResult
        ``status`` ``complete``, the rows as a structured array (``time`` first, one
        ``<component>.<connector>`` field per connector), provenance and the files written.

    Raises
    ------
    ScenarioError
        A bad set-up (nothing ran, nothing was written).
    UsageError
        An option that cannot apply to this scenario (e.g. an ``output_variables`` pattern that
        matches no column), found before the first step.
    SimulationError
        An FMU call failed (NonFiniteError: a value is NaN or infinite; TimeLimitError: the
        ``timeout``); Interrupted on SIGINT/SIGTERM. Each carries the :class:`RunResult` of the rows
        kept in ``result``; the output file and its provenance hold them too.

    Examples
    --------
    >>> import orchestrator
    >>> result = orchestrator.run("pendulum", orchestrator.RunOptions(stop_time=2.0))  # doctest: +SKIP
    >>> result.to_pandas()["plant.y"].max()  # doctest: +SKIP

    Notes
    -----
    Inputs that no connection feeds and no value was given for are one ScenarioWarning
    (``strict``: a ScenarioError). The output format is chosen by the extension of ``output``;
    ``output_variables``, ``output_interval`` and ``no_inputs`` select what the file holds.
    """
    options = options if options is not None else RunOptions()
    if not isinstance(options, RunOptions):
        raise UsageError(f"options must be a RunOptions (got {type(options).__name__})")
    scenario = resolve_scenario(scenario)
    output = RunOutput(options.output, tuple(options.output_variables), options.output_interval,
                       options.no_inputs)
    with open_system(scenario, parameter_sets=options.parameter_sets, overrides=options.overrides,
                     fmu_dirs=options.fmu_dirs, limits=options.limits, root=options.root,
                     strict_fmus=options.strict_fmus) as system:
        start, stop, h = timing(system.structure, options.stop_time, options.step, options.start_time)
        master, chosen_by = choose_master(system.structure, options.master)
        series = _before_the_run(system, options, start, stop)
        compiled, note = _compiled(system, options, master)
        record = provenance.describe(scenario, system, start=start, stop=stop, step=h, master=master,
                                     master_from=chosen_by, parameter_sets=options.parameter_sets,
                                     overrides=options.overrides)
        record["executor"] = "compiled" if compiled else "python"
        if options.input_file is not None and series is not None:
            record["input_file"] = {"path": str(Path(options.input_file).resolve()),
                                    "sha256": provenance.digest(options.input_file),
                                    "inputs": [str(p) for p in series.ports]}
        stream = output.start(system, h, record)  # the master streams a CSV; other formats come from it
        runner = MASTERS[master](system, start, stop, h, stream, progress,
                                 keep=options.keep or stream is None, timeout=options.timeout,
                                 inputs=series, instances=tracing(options.fmi_log),
                                 binary_copy=output.staged, loop_tolerance=options.loop_tolerance,
                                 loop_iterations=options.loop_iterations, compiled=compiled,
                                 layout=output.layout, preview=options.preview)
        try:
            runner.run()
        except BaseException as exc:  # however the run ends early, the sidecar says so
            status = ("timeout" if isinstance(exc, TimeLimitError) else
                      "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed")
            result = _result(runner, output, record, status, str(exc) or type(exc).__name__, h)
            if isinstance(exc, (SimulationError, Interrupted)):
                exc.result = result
            raise
        if note:  # after a run that completed: a failed one says only what failed
            warnings.warn(f"the Python master ran this scenario: {note}", EngineNote, stacklevel=2)
        return _result(runner, output, record, "complete", "", h)


def _before_the_run(system: System, options: RunOptions, start: float, stop: float) -> InputSeries | None:
    """What must hold before anything runs or is written: the input file read, the --fmi-log
    patterns matching components; ScenarioWarnings (``strict``: a ScenarioError) for inputs left
    at their start value and a step the SSD does not give. Returns the input series."""
    unmatched = [p for p in options.fmi_log if not fnmatch.filter(system.components, p)]
    if unmatched:
        raise UsageError(f"{option('fmi_log')}: no component matches {', '.join(unmatched)} "
                         f"(components: {', '.join(system.components)})")
    series, noted = (None, []) if options.input_file is None else read_inputs(options.input_file, system,
                                                                             start, stop)
    driven = set(series.ports) if series is not None else set()
    unconnected = [(m, port) for m, port in zip(system.unconnected, system.unconnected_ports, strict=True)
                   if port not in driven]
    defaulted = [no_step(system.structure)] if options.step is None and no_step(system.structure) else []
    if options.strict and (unconnected or defaulted):
        raise ScenarioError([*(m for m, _ in unconnected), *defaulted])
    for message in [*_unconnected_warning(system, unconnected), *defaulted, *noted]:
        warnings.warn(message, ScenarioWarning, stacklevel=3)
    return series


def _compiled(system: System, options: RunOptions, master: str) -> tuple[bool, str]:
    """Whether the compiled executor runs the scenario (``options.executor``); where ``auto`` finds
    that it cannot, the Python master does, and the second item says why (for the EngineNote of a
    run that completes; ``compiled``: a UsageError)."""
    if options.executor == "python":
        return False, ""
    old = [name for name, c in system.components.items() if c.model.fmiVersion.startswith("1.")]
    loop = master == "gauss-seidel" and bool(system.iterated)
    why = (f"{option('fmi_log')} traces the calls the Python master makes" if options.fmi_log else
           f"FMI 1.0 component{'s' if len(old) > 1 else ''} {', '.join(old)}" if old else
           "an algebraic loop is iterated to a fixed point" if loop else native.unavailable())
    if not why:
        return True, ""
    if options.executor == "compiled":
        raise UsageError(f"{option('executor')} compiled cannot run this scenario: {why}")
    return False, why


def _result(runner: Master, output: RunOutput, record: dict[str, object], status: str,
            message: str, step: float) -> RunResult:
    """The result of a run that ended with ``status``; the output's files finished."""
    recorder = runner.recorder
    count = recorder.count if recorder is not None else 0
    rows = recorder.result() if recorder is not None else np.empty(0, [("time", np.float64)])
    outputs = output.finish(recorder, record, status, message, runner.time, step)
    return RunResult(status, message, rows, count, runner.time(count - 1) if count else None, record, outputs,
                     preview=recorder is not None and not recorder.keep)


SHOWN_INPUTS = 40  # inputs named in the one warning about unconnected inputs


def _unconnected_warning(system: System, unconnected: list[tuple[str, PortRef]]) -> list[str]:
    """The inputs left at their start values as one warning (a third-party FMU may have many: a
    line each, on every run, buried everything else); a single one keeps its own sentence."""
    if len(unconnected) < 2:
        return [m for m, _ in unconnected]
    by_component: dict[str, list[str]] = {}
    for _, port in unconnected[:SHOWN_INPUTS]:
        start = system.components[port.component].variables[port.connector].start
        by_component.setdefault(port.component, []).append(f"{port.connector} ({start})")
    shown = "; ".join(f"{c}: {', '.join(names)}" for c, names in by_component.items())
    more = f" and {len(unconnected) - SHOWN_INPUTS} more" if len(unconnected) > SHOWN_INPUTS else ""
    return [f"{system.ssd}: {len(unconnected)} inputs are not connected and keep the FMU's start value "
            f"(in brackets) for the whole run: {shown}{more} (give values with {option('overrides')} or "
            f"{option('input_file')}; 'orchestrate validate' lists each)"]
