# SPDX-License-Identifier: BSD-2-Clause
"""What runs inside a Dask worker: every task simulates one variant in the scenario folder that
:class:`~orchestrator.campaign.plugin.ScenarioPlugin` unpacked once per worker, and returns one
table row -- a failure or a timeout is a row too, never an exception."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import RunOptions, RunResult, run
from ..errors import OrchestratorError, SimulationError, TimeLimitError

__all__ = ["Metrics", "RunOutcome", "RunSpec", "run_variant", "scenario_folder"]

# Status of a row in the campaign table.
OK, FAILED, TIMEOUT = "ok", "failed", "timeout"


@dataclass(frozen=True)
class Metrics:
    """Metric columns of a campaign: ``function(result, params)`` returns ``{name: value}`` for
    ``names``; ``params`` are the run's overrides plus ``stop_time`` and ``step``. The function must
    be importable on the workers (a module-level function), e.g. the paper's tracking metrics that
    ``orchestrator.experiments.campaigns`` plugs in. ``partial``: the names that keep their meaning
    on the rows a failed run computed before it stopped (e.g. a peak so far); a failed run's row
    gets those, computed on its partial result, and no other. ``events``: parameters that are times
    within a run (e.g. a fault time), each with the metrics it defines: a run that stops before its
    event leaves them undefined (NaN), which the sweep warns of before anything runs."""

    names: tuple[str, ...]
    function: Callable[[np.ndarray, Mapping[str, object]], Mapping[str, float]]
    partial: tuple[str, ...] = ()
    events: Mapping[str, tuple[str, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class RunSpec:
    """One variant: which archive (by digest), its overrides and experiment."""

    index: int
    run_id: str
    scenario: str
    digest: str
    overrides: Mapping[str, object]
    stop_time: float
    step: float
    master: str = "gauss-seidel"
    timeout: float | None = None
    keep_every: int | None = None  # keep every n-th row of the trajectory (None: none)


@dataclass
class RunOutcome:
    """The row of one run, and its (decimated) trajectory if asked for."""

    index: int
    status: str
    reason: str
    wall_time: float
    metrics: dict[str, float] = field(default_factory=dict)
    trajectory: np.ndarray | None = None


def scenario_folder(digest: str, local_directory: Path | None = None) -> Path:
    """Where the unpacked scenario with this digest lives on the current worker."""
    if local_directory is None:
        from distributed import get_worker

        local_directory = Path(get_worker().local_directory)
    return local_directory / f"campaign-{digest[:16]}"


class _LastMessage(logging.Handler):
    """The last warning or error logged during a run (FMUs written in Python log in this process),
    so a failure's one-line reason carries the FMU's own explanation."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.last = ""

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage().strip()
        if text:
            self.last = text.splitlines()[-1]


def _one_line(text: str) -> str:
    return " ".join(text.split())


def run_variant(spec: RunSpec, metrics: Metrics | None = None) -> RunOutcome:
    """Simulate one variant on this worker; every failure becomes a row with a one-line reason
    (a timeout, the engine's ``timeout``, keeps its rows as a failure does)."""
    folder = scenario_folder(spec.digest) / "scenario"
    started = time.perf_counter()
    messages = _LastMessage()
    root = logging.getLogger()
    root.addHandler(messages)
    try:
        result = run(folder, RunOptions(stop_time=spec.stop_time, step=spec.step, overrides=spec.overrides,
                                        master=spec.master, timeout=spec.timeout))
    except TimeLimitError as exc:
        return _kept(spec, TIMEOUT, str(exc), exc.result, started)
    except SimulationError as exc:
        reason = str(exc) if exc.explained or not messages.last else f"{exc} ({messages.last})"
        return _kept(spec, FAILED, reason, exc.result, started, metrics)
    except OrchestratorError as exc:
        return RunOutcome(spec.index, FAILED, _one_line(str(exc)), time.perf_counter() - started)
    except Exception as exc:  # a failed run never stops the campaign: any error becomes its row
        return RunOutcome(
            spec.index, FAILED, _one_line(f"{type(exc).__name__}: {exc}"), time.perf_counter() - started
        )
    finally:
        root.removeHandler(messages)
    wall = time.perf_counter() - started
    values: dict[str, float] = {}
    status, reason = OK, ""
    if metrics is not None:
        params = {**spec.overrides, "stop_time": spec.stop_time, "step": spec.step}
        try:
            values = {k: float(v) for k, v in metrics.function(result.rows, params).items()}
        except (ValueError, ArithmeticError) as exc:
            status, reason = FAILED, _one_line(f"metrics: {exc}")
            values = {}
    return RunOutcome(spec.index, status, reason, wall, values, _decimate(result.rows, spec.keep_every))


def _kept(spec: RunSpec, status: str, reason: str, result: RunResult, started: float,
          metrics: Metrics | None = None) -> RunOutcome:
    """The row of a run that stopped early, with the trajectory of the rows it kept and the metrics
    named ``metrics.partial`` on them (a failed run keeps its peaks and the time it reached)."""
    return RunOutcome(spec.index, status, _one_line(f"{reason}; {result.count} rows computed"),
                      time.perf_counter() - started,
                      _partial_metrics(metrics, result.rows, spec) if result.count else {},
                      trajectory=_decimate(result.rows, spec.keep_every) if result.count else None)


def _partial_metrics(metrics: Metrics | None, partial: np.ndarray, spec: RunSpec) -> dict[str, float]:
    """The metrics named ``metrics.partial`` on a failed run's rows (none if they cannot be computed)."""
    if metrics is None or not metrics.partial:
        return {}
    params = {**spec.overrides, "stop_time": spec.stop_time, "step": spec.step}
    try:
        values = metrics.function(partial, params)
    except (ValueError, ArithmeticError, KeyError):
        return {}
    return {k: float(values[k]) for k in metrics.partial if k in values}


def _decimate(result: np.ndarray, every: int | None) -> np.ndarray | None:
    """Every ``every``-th row and the last one (None: no trajectory kept)."""
    if not every:
        return None
    kept = result[::every]
    return kept if (len(result) - 1) % every == 0 else np.concatenate([kept, result[-1:]])
