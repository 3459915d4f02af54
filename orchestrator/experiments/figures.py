"""The paper's tracking figure, plugged into ``orchestrate run``/``plot`` through the entry-point
group ``orchestrate.figures`` (:mod:`orchestrator.plots`).

For a result with ``plant.y`` and ``reference.yd``: the output against the reference with an
inset on the first second (the fixed-time transient is over in tens of milliseconds), the tracking
error |y - yd| on a log scale, and the control ``controller.v`` / ``actuator.uf`` on a symmetric
log scale with ticks that do not overlap. A dashed line marks the fault time ``actuator.t_fault``
when the run's provenance gives one. Any other result: None (the engine's default figure).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..plots import axis_label

if TYPE_CHECKING:
    import matplotlib.figure
    from matplotlib.axes import Axes

__all__ = ["CONTROL", "TRACKING", "fault_time", "tracking_figure"]

TRACKING = ("plant.y", "reference.yd")
CONTROL = ("controller.v", "actuator.uf")


def fault_time(record: Mapping[str, object] | None) -> float | None:
    """The actuator's fault time ``actuator.t_fault`` of a run's provenance (None: not given)."""
    values = record.get("start_values") if record else None
    fault = values.get("actuator.t_fault") if isinstance(values, Mapping) else None
    return float(fault) if isinstance(fault, (int, float)) else None


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


def _fault_line(ax: Axes, fault: float | None, t: np.ndarray, label: bool) -> None:
    if fault is not None and t[0] <= fault <= t[-1]:
        ax.axvline(fault, color="tab:red", linestyle="--", linewidth=0.9, label="fault" if label else None)


def tracking_figure(result: np.ndarray, units: Mapping[str, str | None],
                    record: Mapping[str, object] | None) -> matplotlib.figure.Figure | None:
    """The tracking figure of ``result`` (the caller closes it), or None when it has no
    ``plant.y`` and ``reference.yd``."""
    names = [n for n in result.dtype.names or () if n != "time"]
    if not all(c in names for c in TRACKING):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fault = fault_time(record)
    t = result["time"]
    control = [c for c in CONTROL if c in names]
    first = t <= t[0] + 1.0
    zoom = bool(first.sum() > 2 and t[-1] > t[0] + 2.0)  # a panel on the first second
    panels = 2 + bool(control) + zoom
    fig, axes = plt.subplots(panels, 1, figsize=(9, 2.6 * panels))
    axes = list(axes)
    for ax in axes[1:]:
        if ax is not axes[1] or not zoom:
            ax.sharex(axes[0])
    _outputs(axes[0], result, t, fault, units)
    if zoom:
        _first_second(axes.pop(1), result, t, first, fault, units)
    _error(axes[1], result, t, fault, units)
    if control:
        _control(axes[2], result, t, control, fault, units)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    return fig


def _outputs(ax: Axes, result: np.ndarray, t: np.ndarray, fault: float | None,
             units: Mapping[str, str | None]) -> None:
    for c in TRACKING:
        ax.plot(t, result[c], label=c, linewidth=1)
    _fault_line(ax, fault, t, True)
    ax.set_ylabel(axis_label("output", list(TRACKING), units))
    ax.legend(loc="upper right", fontsize="small")


def _first_second(ax: Axes, result: np.ndarray, t: np.ndarray, first: np.ndarray, fault: float | None,
                  units: Mapping[str, str | None]) -> None:
    for c in TRACKING:
        ax.plot(t[first], result[c][first], linewidth=1)
    _fault_line(ax, fault, t[first], False)
    ax.set_ylabel(axis_label("first second", list(TRACKING), units))
    ax.set_xlabel("time (s)")
    ax.grid(True, alpha=0.3)


def _error(ax: Axes, result: np.ndarray, t: np.ndarray, fault: float | None,
           units: Mapping[str, str | None]) -> None:
    error = np.abs(result["plant.y"] - result["reference.yd"])
    positive = error > 0
    ax.semilogy(t[positive], error[positive], linewidth=0.8, color="tab:purple", label="|y - yd|")
    _fault_line(ax, fault, t, False)
    ax.set_ylabel(axis_label("|y - yd|", list(TRACKING), units))
    ax.legend(loc="upper right", fontsize="small")


def _control(ax: Axes, result: np.ndarray, t: np.ndarray, control: list[str], fault: float | None,
             units: Mapping[str, str | None]) -> None:
    from matplotlib.ticker import NullLocator

    for c in control:
        ax.plot(t, result[c], label=c, linewidth=0.8)
    _fault_line(ax, fault, t, False)
    magnitude = np.abs(np.concatenate([result[c] for c in control]))
    typical = float(np.percentile(magnitude, 95)) if magnitude.size else 0.0
    if typical > 0.0 and magnitude.max() > 50.0 * typical:  # the initial spike of the fixed-time law
        ax.set_yscale("symlog", linthresh=typical)
        ax.set_yticks(_decade_ticks(magnitude, typical))
        ax.yaxis.set_minor_locator(NullLocator())
    ax.set_ylabel(axis_label("control", control, units))
    ax.legend(loc="upper right", fontsize="small")
