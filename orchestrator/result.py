# SPDX-License-Identifier: BSD-2-Clause
"""What a run is asked to do (:class:`RunOptions`) and what it gives back (:class:`RunResult`).

SciPy's ``solve_ivp`` shape: one frozen options object instead of a long list of keywords, and one
result object with ``status``, ``message`` and ``success`` whatever the outcome. A run that fails
still raises (nothing hides a failure), and the error carries the same :class:`RunResult` in its
``result`` attribute, with the rows computed before the failure.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import UsageError, option
from .master import LOOP_ITERATIONS, LOOP_TOLERANCE, MASTERS
from .ssp import DEFAULT_LIMITS, Limits

if TYPE_CHECKING:
    import matplotlib.figure
    import pandas

__all__ = ["EXECUTORS", "STATUSES", "RunOptions", "RunResult"]

STATUSES = ("complete", "failed", "timeout", "interrupted")
EXECUTORS = ("auto", "compiled", "python")
HTML_ROWS = 40  # signals listed by RunResult._repr_html_


def _paths(items: str | os.PathLike | Sequence[str | os.PathLike]) -> tuple[Path, ...]:
    return (Path(items),) if isinstance(items, (str, os.PathLike)) else tuple(Path(p) for p in items)


@dataclass(frozen=True)
class RunOptions:
    """How to run a scenario; every field is optional.

    Parameters
    ----------
    start_time, stop_time, step : float, optional
        Seconds; default: the SSD's DefaultExperiment and step annotation (a scenario without a step
        annotation needs ``step``). The step must divide the run.
    parameter_sets : sequence of path
        ``.ssv`` files naming parameters ``<component>.<variable>``, applied after the SSD's own.
    overrides : mapping
        ``{"controller.k1": 12}``, applied last.
    master : str, optional
        A name of :data:`orchestrator.master.MASTERS` (``gauss-seidel`` or ``jacobi``); None: the one
        the SSD's algorithm annotation implies (libcosim's ``osp:FixedStepAlgorithm``: jacobi), else
        gauss-seidel. The provenance says which ran and why.
    output : path, optional
        Result file written as the run goes (``.csv``, ``.parquet``, ``.mat``), its provenance in
        ``<output>.json``.
    output_variables, output_interval, no_inputs
        What the output file holds (:mod:`orchestrator.formats`); the rows returned are not affected.
    keep : bool
        False (with an ``output``): rows are only streamed to the file and :attr:`RunResult.rows`
        is a preview for plotting (each column's extremes per bucket, at most 4000 rows).
    preview : bool
        With ``keep`` False: False makes :attr:`RunResult.rows` the first and the last row
        computed only, for a caller that plots nothing (the preview costs 0.4 us per step).
    strict : bool
        An input no connection feeds and no value was given for is a ScenarioError, not a warning.
    timeout : float, optional
        Wall-clock limit in seconds.
    fmu_dirs : sequence of path
        Where FMUs a scenario folder does not hold are looked up by file name.
    limits : Limits
        What an archive and its FMUs may unpack to.
    input_file : path, optional
        CSV (``time`` then ``<component>.<input>`` columns, FMPy's convention) that drives
        unconnected inputs; held between its rows.
    fmi_log : sequence of str
        Components whose FMI calls are traced (logger ``orchestrator.fmi.calls``, level INFO);
        ``*`` for all.
    root : path, optional
        A folder scenario may reference files below this folder with '..' (never an archive).
    strict_fmus : bool
        What fmpy's checks of a model description find is an error even where the FMU still runs.
    loop_tolerance, loop_iterations : float, int
        Convergence of an algebraic loop under gauss-seidel: no input on it moving by more than
        ``loop_tolerance`` (relative to 1 + its size) between two sweeps, within ``loop_iterations``
        sweeps at each communication point (else a :class:`~orchestrator.errors.LoopError`).
    executor : str
        ``auto`` (default): the compiled executor, else the Python master with an
        :class:`~orchestrator.errors.EngineNote` saying why (FMI 1.0, a loop iterated to a fixed
        point, ``fmi_log``, no C compiler); ``compiled``: the compiled executor or a UsageError;
        ``python``: the Python master. Every executor gives the same rows, bit for bit.

    Raises
    ------
    UsageError
        A value out of range (the message names the field and the value).
    """

    start_time: float | None = None
    stop_time: float | None = None
    step: float | None = None
    parameter_sets: Sequence[str | os.PathLike] = ()
    overrides: Mapping[str, object] = field(default_factory=dict)
    master: str | None = None
    output: str | os.PathLike | None = None
    output_variables: Sequence[str] = ()
    output_interval: float | None = None
    no_inputs: bool = False
    keep: bool = True
    preview: bool = True
    strict: bool = False
    timeout: float | None = None
    fmu_dirs: Sequence[str | os.PathLike] = ()
    limits: Limits = DEFAULT_LIMITS
    input_file: str | os.PathLike | None = None
    fmi_log: Sequence[str] = ()
    root: str | os.PathLike | None = None
    strict_fmus: bool = False
    loop_tolerance: float = LOOP_TOLERANCE
    loop_iterations: int = LOOP_ITERATIONS
    executor: str = "auto"

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "parameter_sets", _paths(self.parameter_sets))
        set_(self, "fmu_dirs", _paths(self.fmu_dirs))
        set_(self, "output_variables", (self.output_variables,) if isinstance(self.output_variables, str)
             else tuple(self.output_variables))
        set_(self, "fmi_log", (self.fmi_log,) if isinstance(self.fmi_log, str) else tuple(self.fmi_log))
        set_(self, "overrides", dict(self.overrides))
        for name in ("output", "input_file"):
            value = getattr(self, name)
            if value is not None:
                set_(self, name, Path(value))
        if self.master is not None and self.master not in MASTERS:
            raise UsageError(f"{option('master')}: unknown master {self.master!r} (choose from "
                             f"{', '.join(MASTERS)})")
        if self.executor not in EXECUTORS:
            raise UsageError(f"{option('executor')}: unknown executor {self.executor!r} (choose from "
                             f"{', '.join(EXECUTORS)})")
        if not isinstance(self.limits, Limits):
            raise UsageError(f"limits must be a Limits (got {type(self.limits).__name__})")
        if not (isinstance(self.loop_iterations, int) and self.loop_iterations >= 1):
            raise UsageError(f"loop_iterations must be a positive integer (got {self.loop_iterations!r})")
        if not (isinstance(self.loop_tolerance, numbers.Real) and not isinstance(self.loop_tolerance, bool)
                and math.isfinite(self.loop_tolerance) and self.loop_tolerance > 0):
            raise UsageError(f"loop_tolerance must be positive and finite (got {self.loop_tolerance!r})")
        for name in ("step", "timeout", "output_interval", "start_time", "stop_time"):
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise UsageError(f"{option(name)} must be a number of seconds (got {type(value).__name__} "
                                 f"{value!r})")
            positive = name not in ("start_time", "stop_time")
            number = float(value)
            if not (math.isfinite(number) and (number > 0 or not positive)):
                raise UsageError(f"{option(name)} must be {'positive and ' if positive else ''}finite "
                                 f"(got {value!r})")


@dataclass(frozen=True)
class RunResult:
    """The outcome of one run, returned by :func:`orchestrator.run` and carried by every run error
    (``exc.result``).

    Attributes
    ----------
    status : str
        ``complete``, ``failed``, ``timeout`` or ``interrupted``.
    message : str
        Empty when complete; else the one-line error.
    rows : numpy.ndarray
        Structured array, ``time`` first, one ``<component>.<connector>`` field per connector
        (FMPy's convention): every row computed, or a preview when ``preview`` is True.
    count : int
        The number of rows computed (``len(rows)`` unless ``preview``).
    time : float or None
        The time of the last row computed (None: none).
    provenance : dict
        What produced the run (:func:`orchestrator.provenance.describe`) and how it ended.
    outputs : dict
        Files written: ``result`` and ``provenance`` (empty without an ``output``).
    preview : bool
        ``rows`` is a bounded preview (``RunOptions.keep`` False).
    """

    status: str
    message: str
    rows: np.ndarray
    count: int
    time: float | None
    provenance: dict[str, Any] = field(default_factory=dict)
    outputs: dict[str, Path] = field(default_factory=dict)
    preview: bool = False

    @property
    def success(self) -> bool:
        """True when the run reached its stop time."""
        return self.status == "complete"

    @property
    def columns(self) -> tuple[str, ...]:
        """The field names of ``rows`` (``time`` first)."""
        return tuple(self.rows.dtype.names or ())

    @property
    def units(self) -> dict[str, str | None]:
        """The unit each column's variable declares in its FMU (None: none)."""
        units = self.provenance.get("units")
        return dict(units) if isinstance(units, Mapping) else {}

    def _span(self) -> str:
        if not len(self.rows):
            return "no rows"
        first, last = float(self.rows["time"][0]), float(self.rows["time"][-1])
        shown = f"{len(self.rows)} rows (preview of {self.count})" if self.preview else f"{self.count} rows"
        return f"{shown}, t = {first:g} .. {last:g} s"

    def __repr__(self) -> str:
        """One line: status, rows, time span, columns, files (never the whole array)."""
        signals = max(len(self.columns) - 1, 0)
        files = ", ".join(f"{k}={str(v)!r}" for k, v in self.outputs.items())
        message = f", message={self.message!r}" if self.message else ""
        return (f"RunResult(status={self.status!r}{message}, {self._span()}, {signals} signals"
                + (f", outputs: {files}" if files else "") + ")")

    def _repr_html_(self) -> str:
        """A table for Jupyter: status, span, then each signal with its unit, first and last value."""
        import html  # only in Jupyter: not on every run's peak memory

        e = html.escape
        units = self.units
        head = (f"<p><b>RunResult</b>: {e(self.status)}{': ' + e(self.message) if self.message else ''}; "
                f"{e(self._span())}</p>")
        rows = "".join(
            f"<tr><td><code>{e(c)}</code></td><td>{e(units.get(c) or '')}</td>"
            + ("".join(f"<td>{float(self.rows[c][i]):.6g}</td>" for i in (0, -1)) if len(self.rows) else
               "<td></td><td></td>") + "</tr>"
            for c in self.columns[1:HTML_ROWS + 1])
        more = (f"<p>and {len(self.columns) - 1 - HTML_ROWS} more signals</p>"
                if len(self.columns) - 1 > HTML_ROWS else "")
        files = "".join(f"<li>{e(k)}: <code>{e(str(v))}</code></li>" for k, v in self.outputs.items())
        return (head + "<table><tr><th>signal</th><th>unit</th><th>first</th><th>last</th></tr>" + rows
                + "</table>" + more + (f"<ul>{files}</ul>" if files else ""))

    def to_pandas(self) -> pandas.DataFrame:
        """The rows as a DataFrame indexed by ``time`` (needs pandas).

        Returns
        -------
        pandas.DataFrame
            One column per signal; ``attrs["units"]`` maps each column to the unit its FMU
            declares (None: none; ``time`` is in s), ``attrs["status"]`` is :attr:`status`.
            ``DataFrame.to_parquet`` keeps ``attrs`` in the file's metadata.
        Raises
        ------
        ImportError
            pandas is not installed: it is the optional extra ``pandas``
            (``pip install 'fixed-time-cosim[pandas]'``).
        """
        try:
            import pandas
        except ImportError as exc:
            raise ImportError("RunResult.to_pandas() needs pandas, the optional extra 'pandas': "
                              "pip install 'fixed-time-cosim[pandas]'") from exc

        frame = pandas.DataFrame.from_records(self.rows).set_index("time")
        frame.attrs["units"] = {"time": "s", **{c: self.units.get(c) for c in self.columns[1:]}}
        frame.attrs["status"] = self.status
        return frame

    def plot(self, path: str | os.PathLike | None = None, variables: Sequence[str] = (),
             title: str = "") -> Path | matplotlib.figure.Figure:
        """Plot the rows (the figure of :func:`orchestrator.plots.plot_run`).

        Parameters
        ----------
        path : path, optional
            Image file to write (format by extension). None: show the figure in the current
            matplotlib backend (inline in Jupyter, a window elsewhere), as FMPy's ``plot_result``.
        variables : sequence of str
            Shell patterns of the signals to plot, e.g. ``["plant.*"]`` (default: every output).
        title : str
            Figure title.

        Returns
        -------
        pathlib.Path or matplotlib.figure.Figure
            The file written, or (``path`` None) the figure shown.
        """
        from .plots import plot_run, show_figure

        if path is None:
            return show_figure(self.rows, title, self.units, variables=variables, record=self.provenance)
        return plot_run(self.rows, path, title, self.units, variables=variables, record=self.provenance)
