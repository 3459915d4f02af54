"""fmpy-based SSP co-simulation orchestrator: ``orchestrator.run(scenario, ...)`` or ``orchestrate``.

Data flows top to bottom through the modules: ssp (read the archive) -> system (validated
components, connections, propagation order) -> master (FMI stepping) -> results (CSV + array);
validate runs ssp and system as far as they go and reports everything (``orchestrate validate``).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack, contextmanager

import numpy as np

from . import provenance
from .errors import OrchestratorError, ScenarioError, ScenarioWarning, SimulationError, UsageError
from .master import MASTERS
from .system import PortRef, System
from .validate import DEFAULT_STEP, check_scenario, timing

__all__ = ["DEFAULT_STEP", "MASTERS", "OrchestratorError", "PortRef", "ScenarioError", "ScenarioWarning",
           "SimulationError", "UsageError", "open_system", "run"]


@contextmanager
def open_system(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
                overrides: Mapping[str, object] | None = None,
                fmu_dirs: Iterable[str | os.PathLike] = ()) -> Iterator[System]:
    """Open, read and validate a scenario (``.ssp`` archive or folder); an archive stays unpacked
    until the ``with`` block ends. FMUs missing from the scenario are looked up by file name in
    ``fmu_dirs`` (a source folder with the built FMUs). Raises ScenarioError listing every problem
    found (the checks of :func:`orchestrator.validate.validate`, without its warnings)."""
    with ExitStack() as stack:
        system, errors, _ = check_scenario(scenario, stack, parameter_sets=parameter_sets,
                                           overrides=overrides, fmu_dirs=fmu_dirs)
        if system is None or errors:
            raise ScenarioError(errors)
        yield system


def run(scenario: str | os.PathLike, *, stop_time: float | None = None, step: float | None = None,
        parameter_sets: Iterable[str | os.PathLike] = (), overrides: Mapping[str, object] | None = None,
        master: str = "gauss-seidel", output: str | os.PathLike | None = None,
        progress: Callable[[int, int], None] | None = None, start_time: float | None = None,
        strict: bool = False, fmu_dirs: Iterable[str | os.PathLike] = ()) -> np.ndarray:
    """Run a scenario (``.ssp`` archive or folder) and return the results as a structured array
    with a ``time`` field and one ``<component>.<connector>`` field per connector.

    Start time, stop time and step default to the SSD's DefaultExperiment and step annotation (1 ms
    if none); the step must divide the run (:func:`orchestrator.validate.timing`).
    ``parameter_sets`` are ``.ssv`` files naming parameters ``<component>.<variable>``, applied after
    the SSD's bindings; ``overrides`` (``{"controller.k1": 12}``) apply last. ``output``: CSV file
    written as the run goes, with its provenance in ``<output>.json``
    (:mod:`orchestrator.provenance`). An input that no connection feeds and no value was given for is a
    ScenarioWarning (``strict``: a ScenarioError). ``fmu_dirs``: as for :func:`open_system`.
    Raises ScenarioError for a bad set-up and SimulationError (with the rows computed so far in
    ``.result``) when an FMU fails.
    """
    if master not in MASTERS:
        raise ValueError(f"unknown master '{master}' (choose from {', '.join(MASTERS)})")
    parameter_sets = list(parameter_sets)
    with open_system(scenario, parameter_sets=parameter_sets, overrides=overrides,
                     fmu_dirs=fmu_dirs) as system:
        start, stop, h = timing(system.structure, stop_time, step, start_time)
        if strict and system.unconnected:
            raise ScenarioError(system.unconnected)
        for message in system.unconnected:
            warnings.warn(message, ScenarioWarning, stacklevel=2)
        if output is None:
            return MASTERS[master](system, start, stop, h, output, progress).run()
        record = provenance.describe(scenario, system, start=start, stop=stop, step=h, master=master,
                                     parameter_sets=parameter_sets, overrides=overrides)
        provenance.write_provenance(output, record)
        try:
            result = MASTERS[master](system, start, stop, h, output, progress).run()
        except SimulationError as exc:
            rows = getattr(exc, "result", np.empty(0, dtype=[("time", float)]))
            provenance.finish(output, record, "failed", len(rows),
                              float(rows["time"][-1]) if len(rows) else None, str(exc))
            raise
        except KeyboardInterrupt:
            provenance.finish(output, record, "interrupted", -1, None)
            raise
        provenance.finish(output, record, "complete", len(result), float(result["time"][-1]))
        return result
