"""fmpy-based SSP co-simulation orchestrator: ``orchestrator.run(scenario, ...)`` or ``orchestrate``.

Data flows top to bottom through the modules: ssp (read the archive) -> system (validated
components, connections, propagation order) -> master (FMI stepping) -> results (CSV + array).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

from .errors import OrchestratorError, ScenarioError, SimulationError, UsageError
from .master import MASTERS
from .ssp import SSD_NAME, open_scenario, read_parameter_set, read_scenario
from .system import PortRef, System

__all__ = ["MASTERS", "OrchestratorError", "PortRef", "ScenarioError", "SimulationError", "UsageError",
           "open_system", "run"]

DEFAULT_STEP = 1e-3


@contextmanager
def open_system(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
                overrides: Mapping[str, object] | None = None) -> Iterator[System]:
    """Open, read and validate a scenario (``.ssp`` archive or folder); an archive stays unpacked
    until the ``with`` block ends. Raises ScenarioError listing every problem found."""
    with ExitStack() as stack:
        folder = open_scenario(scenario, stack)
        path = Path(scenario)
        label = f"{path}:{SSD_NAME}" if path.is_file() else str(folder / SSD_NAME)
        structure = read_scenario(folder, label)
        sets = [read_parameter_set(p) for p in parameter_sets]
        yield System(structure, sets, overrides)


def run(scenario: str | os.PathLike, *, stop_time: float | None = None, step: float | None = None,
        parameter_sets: Iterable[str | os.PathLike] = (), overrides: Mapping[str, object] | None = None,
        master: str = "gauss-seidel", output: str | os.PathLike | None = None,
        progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Run a scenario (``.ssp`` archive or folder) and return the results as a structured array
    with a ``time`` field and one ``<component>.<connector>`` field per connector.

    Stop time and step default to the SSD's DefaultExperiment and step annotation (1 ms if none).
    ``parameter_sets`` are ``.ssv`` files naming parameters ``<component>.<variable>``, applied after
    the SSD's bindings; ``overrides`` (``{"controller.k1": 12}``) apply last. ``output``: CSV file
    written as the run goes. Raises ScenarioError for a bad set-up and SimulationError (with the
    rows computed so far in ``.result``) when an FMU fails.
    """
    if master not in MASTERS:
        raise ValueError(f"unknown master '{master}' (choose from {', '.join(MASTERS)})")
    with open_system(scenario, parameter_sets=parameter_sets, overrides=overrides) as system:
        experiment = system.structure.experiment
        stop = stop_time if stop_time is not None else experiment.stop_time
        if stop is None:
            raise ScenarioError(f"{system.ssd}: no stopTime in DefaultExperiment; give a stop time")
        h = step if step is not None else experiment.step or DEFAULT_STEP
        try:
            algorithm = MASTERS[master](system, experiment.start_time, stop, h, output, progress)
        except ValueError as exc:
            raise ScenarioError(f"{system.ssd}: {exc}") from exc
        return algorithm.run()
