"""fmpy-based SSP co-simulation orchestrator: ``orchestrator.run(scenario, RunOptions(...))`` or
``orchestrate`` (also ``python -m orchestrator``).

A scenario is named as on the command line: a ``.ssp`` archive, a folder holding
``SystemStructure.ssd``, or the name of a built scenario (``run("pendulum")`` runs
``build/ssp/pendulum.ssp``).

Data flows top to bottom through the modules: ssp (read the archive) -> system (validated
components, connections, propagation order) -> master (FMI stepping) -> results (CSV + array);
validate runs ssp and system as far as they go and reports everything (``orchestrate validate``).
"""

from __future__ import annotations

from . import _startup  # noqa: F401 - first: SIGINT/SIGTERM during the imports below are one line

# isort: split
import fnmatch
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import formats, provenance
from .errors import (
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
from .result import RunOptions, RunResult
from .ssp import DEFAULT_LIMITS, Limits
from .system import PortRef, System
from .validate import DEFAULT_STEP, check_scenario, no_step, timing

__all__ = ["DEFAULT_STEP", "MASTERS", "Interrupted", "Limits", "LoopError", "NonFiniteError",
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
    selection = formats.Selection(tuple(options.output_variables), options.output_interval)
    output = options.output
    if output is not None:
        formats.check_output(output, selection=selection)
    with open_system(scenario, parameter_sets=options.parameter_sets, overrides=options.overrides,
                     fmu_dirs=options.fmu_dirs, limits=options.limits, root=options.root,
                     strict_fmus=options.strict_fmus) as system:
        start, stop, h = timing(system.structure, options.stop_time, options.step, options.start_time)
        series = _before_the_run(system, options, start, stop)
        record = provenance.describe(scenario, system, start=start, stop=stop, step=h, master=options.master,
                                     parameter_sets=options.parameter_sets, overrides=options.overrides)
        if options.input_file is not None and series is not None:
            record["input_file"] = {"path": str(Path(options.input_file).resolve()),
                                    "sha256": provenance.digest(options.input_file),
                                    "inputs": [str(p) for p in series.ports]}
        stream = None
        if options.no_inputs:
            selection = replace(selection, drop=tuple(str(end) for end, link in system.links.items()
                                                      if not link.transformed))
        selection.columns(["time", *system_columns(system)])  # a pattern matching nothing: now, file or not
        if output is not None:  # the master streams a CSV; other formats and selections come from it
            formats.check_output(output, h, selection)
            stream = formats.staging_path(output, selection)
            record["output"] = {"format": Path(output).suffix.lower(), "variables": list(selection.variables),
                                "interval": selection.interval, "left_out": list(selection.drop)}
            provenance.write_provenance(output, record)
        runner = MASTERS[options.master](system, start, stop, h, stream, progress,
                                         keep=options.keep or output is None, timeout=options.timeout,
                                         inputs=series, instances=tracing(options.fmi_log),
                                         binary_copy=stream is not None and stream != Path(output or ""),
                                         loop_tolerance=options.loop_tolerance,
                                         loop_iterations=options.loop_iterations)
        texts = descriptions(system)
        try:
            runner.run()
        except BaseException as exc:  # however the run ends early, the sidecar says so
            status = ("timeout" if isinstance(exc, TimeLimitError) else
                      "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed")
            result = _finish(runner, record, status, str(exc) or type(exc).__name__, output, stream,
                             selection, texts, h)
            if isinstance(exc, (SimulationError, Interrupted)):
                exc.result = result
            raise
        return _finish(runner, record, "complete", "", output, stream, selection, texts, h)


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


def system_columns(system: System) -> list[str]:
    """Every connector of a system as a result column names it.

    Parameters
    ----------
    system : System
        A validated system (:func:`open_system`).

    Returns
    -------
    list of str
        ``component.connector`` for each input and output, in the order of the result's columns
        (after ``time``).
    """
    return [str(PortRef(name, c)) for name, comp in system.components.items()
            for c in (*comp.inputs, *comp.outputs)]


def descriptions(system: System) -> dict[str, str]:
    """Each column's description and unit as Dymola writes them into a result file:
    ``Plant output [rad]`` (the FMU's description; the unit in brackets when it declares one)."""
    units = provenance.column_units(system)
    texts = {}
    for name, comp in system.components.items():
        variables = comp.variables
        for k in (*comp.inputs, *comp.outputs):
            column = str(PortRef(name, k))
            text, unit = variables[k].description or "", units.get(column)
            texts[column] = f"{text} [{unit}]".strip() if unit else text
    return texts


def _finish(runner: Master, record: dict[str, object], status: str, message: str,
            output: str | os.PathLike | None, stream: str | os.PathLike | None,
            selection: formats.Selection, texts: Mapping[str, str], step: float) -> RunResult:
    """The result of a run that ended with ``status``; with an ``output``, its rows written in the
    format asked for and the provenance finished (``rows``: the rows the file holds, after
    ``output_interval``; ``rows_computed``: every communication point computed)."""
    recorder = runner.recorder
    count = recorder.count if recorder is not None else 0
    rows = recorder.result() if recorder is not None else np.empty(0, [("time", np.float64)])
    last = runner.time(count - 1) if count else None
    outputs: dict[str, Path] = {}
    if output is not None and stream is not None:
        saved = recorder.saved if recorder is not None else 0  # what is on disk, never more
        record["rows_computed"] = count
        outputs["provenance"] = provenance.finish(output, record, status, selection.kept(saved, step),
                                                  runner.time(saved - 1) if saved else None, message)
        if saved and Path(stream).is_file():
            units = record.get("units")  # the rows kept, in the format asked for, with their units
            formats.write_selected(stream, output, selection, texts,
                                   units if isinstance(units, dict) else None)
            outputs["result"] = Path(output)
        formats.binary_copy_path(stream).unlink(missing_ok=True)
    else:
        record.update(status=status, rows=count, last_time=last)
        if message:
            record["message"] = message
    return RunResult(status, message, rows, count, last, record, outputs,
                     preview=recorder is not None and not recorder.keep)
