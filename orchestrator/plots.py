# SPDX-License-Identifier: BSD-2-Clause
"""The figure of one result, as people read it (``orchestrate run`` / ``orchestrate plot``).

The engine's default figure knows no scenario: one panel per component with the signals it
outputs (input columns only repeat the outputs connected to them), or, with ``variables`` (shell
patterns, ``--plot-variables``), the signals asked for, grouped by component. Every y axis carries
the unit the model descriptions declare (``-`` when none is declared).

An application may offer a figure of its own for the results it recognises: a function
``figure(rows, units, record) -> matplotlib Figure | None`` listed under the entry-point group
``orchestrate.figures`` (e.g. the paper's tracking figure of :mod:`orchestrator.experiments.figures`).
Without ``variables``, the first such function (by entry-point name) that returns a figure wins.
"""

from __future__ import annotations

import fnmatch
import logging
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import files
from .errors import OutputError, UsageError, option
from .installed import entry_points

if TYPE_CHECKING:
    import matplotlib.figure

__all__ = ["FIGURE_GROUP", "MAX_PANELS", "axis_label", "build_figure", "check_plot", "chosen_columns",
           "plot_run", "show_figure"]

FIGURE_GROUP = "orchestrate.figures"
MAX_PANELS = 12  # a result of more components gets the first ones and a note in the title

log = logging.getLogger(__name__)

FigureFunction = Callable[[np.ndarray, Mapping[str, str | None], Mapping[str, object] | None],
                          "matplotlib.figure.Figure | None"]


def axis_label(what: str, columns: list[str], units: Mapping[str, str | None]) -> str:
    """``what (unit)``: the unit the ``columns`` declare (those declaring none are taken to share
    it, e.g. a reference for a plant output in rad); ``-`` when none declares one, ``mixed units``
    when they declare different ones."""
    found = {units[c] for c in columns if units.get(c)}
    return f"{what} ({found.pop() if len(found) == 1 else 'mixed units' if found else '-'})"


def chosen_columns(names: Sequence[str], variables: Sequence[str] = (),
                   outputs: Sequence[str] | None = None) -> list[str]:
    """The columns to plot: those matching ``variables`` (UsageError naming a pattern that matches
    none), else the ``outputs`` among ``names`` (all of them when the outputs are not known)."""
    signals = [n for n in names if n != "time"]
    if variables:
        for pattern in variables:
            if not fnmatch.filter(signals, pattern):
                raise UsageError(f"{option('variables')}: '{pattern}' matches no column "
                                 f"(columns: {', '.join(signals)})")
        return [n for n in signals if any(fnmatch.fnmatchcase(n, p) for p in variables)]
    if outputs:
        known = set(outputs)
        chosen = [n for n in signals if n in known]
        if chosen:
            return chosen
    return signals


def check_plot(path: str | os.PathLike) -> None:
    """Before a run: UsageError for a format matplotlib does not write (by the extension),
    OutputError for an existing ``path`` that is not a regular file (a FIFO would block)."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in formats:
        raise UsageError(f"{option('plot')} {path}: cannot write '{suffix}' images (choose "
                         f"{', '.join(sorted(formats))})")
    unusable = files.not_regular(path)
    if unusable:
        raise OutputError(f"{path}: {unusable}")


def plot_run(result: np.ndarray, path: str | os.PathLike, title: str = "",
             units: Mapping[str, str | None] | None = None, *, variables: Sequence[str] = (),
             record: Mapping[str, object] | None = None) -> Path:
    """Write the figure of ``result`` to ``path`` (see the module's docstring) and return the path.

    Parameters
    ----------
    result : numpy.ndarray
        Structured array with a ``time`` field (FMPy's convention).
    path : path
        Image file (format by extension, as matplotlib writes them).
    title : str
        Figure title.
    units : mapping, optional
        Column -> unit (None: none declared).
    variables : sequence of str
        Shell patterns of the signals to plot (default: an application's figure, else every output).
    record : mapping, optional
        The run's provenance (:mod:`orchestrator.provenance`): says which columns are outputs.
    """
    import matplotlib.pyplot as plt

    fig = _figure(result, title, units, variables, record)
    try:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    finally:
        plt.close(fig)  # drawn for the file only: an interactive session does not show it
    return path


def show_figure(result: np.ndarray, title: str = "", units: Mapping[str, str | None] | None = None, *,
                variables: Sequence[str] = (),
                record: Mapping[str, object] | None = None) -> matplotlib.figure.Figure:
    """Show the figure of ``result`` (as :func:`plot_run` draws it) in matplotlib's current backend,
    as FMPy's ``plot_result`` does: inline in Jupyter, in a window elsewhere; returns it."""
    import matplotlib.pyplot as plt

    fig = _figure(result, title, units, variables, record)
    plt.show()
    return fig


def _figure(result: np.ndarray, title: str, units: Mapping[str, str | None] | None,
            variables: Sequence[str], record: Mapping[str, object] | None) -> matplotlib.figure.Figure:
    fig = None if variables else _application_figure(result, units or {}, record)
    if fig is None:
        fig = build_figure(result, title, units, variables=variables, record=record)
    elif title:
        fig.suptitle(title)
        if fig.get_layout_engine() is None:
            fig.tight_layout()
    return fig


def _application_figure(result: np.ndarray, units: Mapping[str, str | None],
                        record: Mapping[str, object] | None) -> matplotlib.figure.Figure | None:
    """The figure of the first ``orchestrate.figures`` entry point that recognises ``result``."""
    for entry in entry_points(FIGURE_GROUP):
        function: FigureFunction = entry.load()
        fig = function(result, units, record)
        if fig is not None:
            log.debug("figure of %s", entry.value)
            return fig
    return None


def build_figure(result: np.ndarray, title: str = "", units: Mapping[str, str | None] | None = None, *,
                 variables: Sequence[str] = (),
                 record: Mapping[str, object] | None = None) -> matplotlib.figure.Figure:
    """The engine's default figure (the caller closes it): the chosen columns
    (:func:`chosen_columns`) on the time axis, one panel per component."""
    import matplotlib.pyplot as plt

    units = units or {}
    assert result.dtype.names is not None  # a structured array
    outputs = record.get("outputs") if record else None
    columns = chosen_columns(result.dtype.names, variables, outputs if isinstance(outputs, list) else None)
    panels: dict[str, list[str]] = {}
    for c in columns:
        panels.setdefault(c.partition(".")[0] if "." in c else c, []).append(c)
    shown = list(panels.items())[:MAX_PANELS]
    if len(panels) > MAX_PANELS:
        title = f"{title}\n(first {MAX_PANELS} of {len(panels)} components; choose with --plot-variables)"
    t = result["time"]
    fig, axes = plt.subplots(max(1, len(shown)), 1, sharex=True, figsize=(9, 2.2 + 1.8 * len(shown)),
                             squeeze=False)
    axes = axes[:, 0]
    for ax, (component, names) in zip(axes, shown, strict=False):
        for c in names:
            ax.plot(t, result[c], linewidth=1, label=c)
        ax.set_ylabel(axis_label(component, names, units), fontsize="small")
        ax.legend(loc="upper right", fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
