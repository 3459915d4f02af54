"""fmpy-based SSP co-simulation orchestrator: ``orchestrator.run(scenario, ...)`` or ``orchestrate``.

Data flows top to bottom through the modules: ssp (read the archive) -> system (validated
components, connections, propagation order) -> master (FMI stepping) -> results (CSV + array);
validate runs ssp and system as far as they go and reports everything (``orchestrate validate``).
"""

from __future__ import annotations

from . import _startup  # noqa: F401 - first: SIGINT/SIGTERM during the imports below are one line

# isort: split
import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import formats, provenance
from .errors import (
    Interrupted,
    NonFiniteError,
    OrchestratorError,
    ScenarioError,
    ScenarioWarning,
    SimulationError,
    TimeLimitError,
    UsageError,
)
from .master import MASTERS
from .ssp import DEFAULT_LIMITS, Limits
from .system import PortRef, System
from .validate import DEFAULT_STEP, check_scenario, timing

__all__ = ["DEFAULT_STEP", "MASTERS", "Interrupted", "Limits", "NonFiniteError", "OrchestratorError",
           "PortRef", "ScenarioError", "ScenarioWarning", "SimulationError", "TimeLimitError", "UsageError",
           "open_system", "run"]


@contextmanager
def open_system(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
                overrides: Mapping[str, object] | None = None,
                fmu_dirs: Iterable[str | os.PathLike] = (),
                limits: Limits = DEFAULT_LIMITS) -> Iterator[System]:
    """Open, read and validate a scenario (``.ssp`` archive or folder); an archive stays unpacked
    until the ``with`` block ends. FMUs missing from the scenario are looked up by file name in
    ``fmu_dirs`` (a source folder with the built FMUs); an archive and its FMUs must stay within
    ``limits`` (:class:`~orchestrator.ssp.Limits`). Raises ScenarioError listing every problem
    found (the checks of :func:`orchestrator.validate.validate`, without its warnings)."""
    with ExitStack() as stack:
        system, errors, _ = check_scenario(scenario, stack, parameter_sets=parameter_sets,
                                           overrides=overrides, fmu_dirs=fmu_dirs, limits=limits)
        if system is None or errors:
            raise ScenarioError(errors)
        yield system


def run(scenario: str | os.PathLike, *, stop_time: float | None = None, step: float | None = None,
        parameter_sets: Iterable[str | os.PathLike] = (), overrides: Mapping[str, object] | None = None,
        master: str = "gauss-seidel", output: str | os.PathLike | None = None,
        progress: Callable[[int, int], None] | None = None, start_time: float | None = None,
        strict: bool = False, fmu_dirs: Iterable[str | os.PathLike] = (), keep: bool = True,
        timeout: float | None = None, limits: Limits = DEFAULT_LIMITS,
        output_variables: Sequence[str] = (), output_interval: float | None = None,
        no_inputs: bool = False) -> np.ndarray:
    """Run a scenario (``.ssp`` archive or folder) and return the results as a structured array
    with a ``time`` field and one ``<component>.<connector>`` field per connector.

    Start time, stop time and step default to the SSD's DefaultExperiment and step annotation (1 ms
    if none); the step must divide the run (:func:`orchestrator.validate.timing`).
    ``parameter_sets`` are ``.ssv`` files naming parameters ``<component>.<variable>``, applied after
    the SSD's bindings; ``overrides`` (``{"controller.k1": 12}``) apply last. ``output``: CSV file
    written as the run goes, with its provenance in ``<output>.json``
    (:mod:`orchestrator.provenance`). An input that no connection feeds and no value was given for is a
    ScenarioWarning (``strict``: a ScenarioError). ``fmu_dirs``, ``limits``: as for :func:`open_system`.
    ``keep`` False (with an ``output``): the rows are only streamed to the CSV, memory stays flat
    however long the run, and the array returned is a preview for plotting (at most 4000 rows: each
    column's extremes per bucket of rows). ``timeout``: wall-clock limit in seconds.
    Raises ScenarioError for a bad set-up; SimulationError when an FMU fails, NonFiniteError when
    a value is NaN or infinite, TimeLimitError at the ``timeout``, Interrupted on SIGINT/SIGTERM
    (a KeyboardInterrupt), each with the rows kept in ``.result`` and their number in ``.rows``.

    Output control (:mod:`orchestrator.formats`): the format is chosen by the extension of
    ``output`` (``.csv``, ``.parquet``, ``.mat``; others are a UsageError before anything runs);
    ``output_variables`` (fnmatch patterns), ``output_interval`` (a multiple of the step) and
    ``no_inputs`` (leave out input columns that only repeat their source) select what the file
    holds; the array returned is not affected.
    """
    selection = formats.Selection(tuple(output_variables), output_interval)
    if output is not None:
        formats.check_output(output, selection=selection)
    if master not in MASTERS:
        raise ValueError(f"unknown master '{master}' (choose from {', '.join(MASTERS)})")
    parameter_sets = list(parameter_sets)
    with open_system(scenario, parameter_sets=parameter_sets, overrides=overrides,
                     fmu_dirs=fmu_dirs, limits=limits) as system:
        start, stop, h = timing(system.structure, stop_time, step, start_time)
        if strict and system.unconnected:
            raise ScenarioError(system.unconnected)
        for message in system.unconnected:
            warnings.warn(message, ScenarioWarning, stacklevel=2)
        stream = output
        if output is not None:  # the master streams a CSV; other formats and selections come from it
            formats.check_output(output, h, selection)
            if no_inputs:
                selection = replace(selection, drop=tuple(str(end) for end, link in system.links.items()
                                                          if not link.transformed))
            stream = formats.staging_path(output, selection)
        runner = MASTERS[master](system, start, stop, h, stream, progress, keep=keep or output is None,
                                 timeout=timeout)
        if output is None:
            return runner.run()
        assert stream is not None  # the staging path of ``output``
        record = provenance.describe(scenario, system, start=start, stop=stop, step=h, master=master,
                                     parameter_sets=parameter_sets, overrides=overrides)
        record["output"] = {"format": Path(output).suffix.lower(), "variables": list(selection.variables),
                            "interval": selection.interval, "left_out": list(selection.drop)}
        provenance.write_provenance(output, record)
        try:
            result = runner.run()
        except BaseException as exc:  # however the run ends early, the sidecar says so
            rows = runner.recorder.saved if runner.recorder is not None else 0  # what is on disk
            status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
            provenance.finish(output, record, status, rows, runner.time(rows - 1) if rows else None,
                              str(exc) or type(exc).__name__)
            if rows and Path(stream).is_file():
                formats.write_selected(stream, output, selection)  # the rows kept, in the format asked for
            raise
        formats.write_selected(stream, output, selection)
        assert runner.recorder is not None  # created by the run
        provenance.finish(output, record, "complete", runner.recorder.count, runner.time(runner.n))
        return result
