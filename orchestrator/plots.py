"""The figure of one result, as people read it (``orchestrate run`` / ``orchestrate plot``).

For a tracking result (``plant.y``, ``reference.yd``): the output against the reference with an
inset on the first second (the fixed-time transient is over in tens of milliseconds), the tracking
error |y - yd| on a log scale, and the control ``controller.v`` / ``actuator.uf`` on a symmetric
log scale with ticks that do not overlap. Every y axis carries the unit the model descriptions
declare (``-`` when none is declared), and a dashed line marks the fault time when the run's
provenance gives one. Any other result: one panel per column (at most eight).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from . import files
from .errors import OutputError, UsageError

if TYPE_CHECKING:
    import matplotlib.figure
    from matplotlib.axes import Axes

__all__ = ["axis_label", "build_figure", "check_plot", "plot_run"]

TRACKING = ("plant.y", "reference.yd")
CONTROL = ("controller.v", "actuator.uf")


def axis_label(what: str, columns: list[str], units: Mapping[str, str | None]) -> str:
    """``what (unit)``: the unit the ``columns`` declare (those declaring none are taken to share
    it, e.g. a reference for a plant output in rad); ``-`` when none declares one, ``mixed units``
    when they declare different ones."""
    found = {units[c] for c in columns if units.get(c)}
    return f"{what} ({found.pop() if len(found) == 1 else 'mixed units' if found else '-'})"


def _decade_ticks(values: np.ndarray, linthresh: float) -> list[float]:
    """0 and the signed powers of ten beyond 10 * linthresh that the data reach: labels that
    cannot overlap on a symlog axis."""
    top = float(np.max(np.abs(values)))
    ticks = [0.0]
    k = int(np.ceil(np.log10(10 * linthresh)))
    while 10.0 ** k <= top:
        ticks += [-(10.0 ** k), 10.0 ** k]
        k += 1
    return sorted(ticks)


def _fault_line(ax: Axes, fault_time: float | None, t: np.ndarray, label: bool) -> None:
    if fault_time is not None and t[0] <= fault_time <= t[-1]:
        ax.axvline(fault_time, color="tab:red", linestyle="--", linewidth=0.9,
                   label="fault" if label else None)


def check_plot(path: str | os.PathLike) -> None:
    """Before a run: UsageError for a format matplotlib does not write (by the extension),
    OutputError for an existing ``path`` that is not a regular file (a FIFO would block)."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in formats:
        raise UsageError(f"--plot {path}: cannot write '{suffix}' images (choose "
                         f"{', '.join(sorted(formats))})")
    unusable = files.not_regular(path)
    if unusable:
        raise OutputError(f"{path}: {unusable}")


def plot_run(result: np.ndarray, path: str | os.PathLike, title: str = "",
             units: Mapping[str, str | None] | None = None, fault_time: float | None = None) -> Path:
    """Write the figure of ``result`` to ``path`` (see the module's docstring) and return the path."""
    import matplotlib.pyplot as plt

    fig = build_figure(result, title, units, fault_time)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def build_figure(result: np.ndarray, title: str = "", units: Mapping[str, str | None] | None = None,
                 fault_time: float | None = None) -> matplotlib.figure.Figure:
    """The figure :func:`plot_run` writes (the caller closes it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullLocator

    units = units or {}
    t = result["time"]
    assert result.dtype.names is not None  # a structured array
    names = [n for n in result.dtype.names if n != "time"]
    if all(c in names for c in TRACKING):
        control = [c for c in CONTROL if c in names]
        first = t <= t[0] + 1.0
        zoom = bool(first.sum() > 2 and t[-1] > t[0] + 2.0)  # a panel on the first second
        panels = 2 + bool(control) + zoom
        fig, axes = plt.subplots(panels, 1, figsize=(9, 2.6 * panels))
        axes = list(axes)
        for ax in axes[1:]:
            if ax is not axes[1] or not zoom:
                ax.sharex(axes[0])
        ax = axes[0]
        for c in TRACKING:
            ax.plot(t, result[c], label=c, linewidth=1)
        _fault_line(ax, fault_time, t, True)
        ax.set_ylabel(axis_label("output", list(TRACKING), units))
        ax.legend(loc="upper right", fontsize="small")
        if zoom:
            ax = axes.pop(1)
            for c in TRACKING:
                ax.plot(t[first], result[c][first], linewidth=1)
            _fault_line(ax, fault_time, t[first], False)
            ax.set_ylabel(axis_label("first second", list(TRACKING), units))
            ax.set_xlabel("time (s)")
            ax.grid(True, alpha=0.3)
        error = np.abs(result["plant.y"] - result["reference.yd"])
        ax = axes[1]
        positive = error > 0
        ax.semilogy(t[positive], error[positive], linewidth=0.8, color="tab:purple", label="|y - yd|")
        _fault_line(ax, fault_time, t, False)
        ax.set_ylabel(axis_label("|y - yd|", list(TRACKING), units))
        ax.legend(loc="upper right", fontsize="small")
        if control:
            ax = axes[2]
            for c in control:
                ax.plot(t, result[c], label=c, linewidth=0.8)
            _fault_line(ax, fault_time, t, False)
            magnitude = np.abs(np.concatenate([result[c] for c in control]))
            typical = float(np.percentile(magnitude, 95)) if magnitude.size else 0.0
            if typical > 0.0 and magnitude.max() > 50.0 * typical:  # the initial spike of the fixed-time law
                ax.set_yscale("symlog", linthresh=typical)
                ax.set_yticks(_decade_ticks(magnitude, typical))
                ax.yaxis.set_minor_locator(NullLocator())
            ax.set_ylabel(axis_label("control", control, units))
            ax.legend(loc="upper right", fontsize="small")
    else:
        shown = names[:8]
        fig, axes = plt.subplots(len(shown), 1, sharex=True, figsize=(9, 2.2 * len(shown)), squeeze=False)
        axes = axes[:, 0]
        for ax, c in zip(axes, shown, strict=True):
            ax.plot(t, result[c], linewidth=1, label=c)
            _fault_line(ax, fault_time, t, False)
            ax.set_ylabel(axis_label(c, [c], units), fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
