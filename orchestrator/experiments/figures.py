# SPDX-License-Identifier: BSD-2-Clause
"""The paper's tracking figure, plugged into ``orchestrate run``/``plot`` through the entry-point
group ``orchestrate.figures`` (:mod:`orchestrator.plots`).

For a result with ``plant.y`` and ``reference.yd``: the output against the reference with an
inset on the first second (the fixed-time transient is over in tens of milliseconds), the tracking
error |y - yd| on a log scale, and the control ``controller.v`` / ``actuator.uf`` on a symmetric
log scale with one tick per decade (linear below the decade of the typical |v|, so the sampled
loop's bursts show), ``controller.v`` drawn over ``actuator.uf``. Legends sit beside the panels,
never on a trace. A dashed line marks the fault time ``actuator.t_fault`` when the run's provenance
gives one. Any other result: None (the engine's default figure).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

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
    """0 and every power of ten from ``linthresh`` (itself one) up to the data's largest magnitude,
    with the sign(s) the data take: one tick per decade, a decade apart on a symlog axis whose
    linear part [-linthresh, linthresh] is one decade tall (linscale 1), so no labels overlap."""
    top = float(np.max(np.abs(values)))
    signs = [s for s, present in ((-1.0, bool(np.any(values < 0))), (1.0, bool(np.any(values > 0))))
             if present]
    ticks = [0.0]
    k = round(np.log10(linthresh))
    while 10.0 ** k <= top * (1 + 1e-12):
        ticks += [s * 10.0 ** k for s in signs]
        k += 1
    return sorted(ticks)


def _legend(ax: Axes) -> None:
    """The legend beside the panel, outside the data (it covered the trace inside)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small",
              frameon=False)


def _fault_line(ax: Axes, fault: float | None, t: np.ndarray, label: bool) -> None:
    if fault is not None and t[0] <= fault <= t[-1]:
        ax.axvline(fault, color="tab:red", linestyle="--", linewidth=0.9, label="fault" if label else None)


def tracking_figure(result: np.ndarray, units: Mapping[str, str | None],
                    record: Mapping[str, object] | None) -> matplotlib.figure.Figure | None:
    """The tracking figure of ``result`` (the caller closes it), or None when it has no
    ``plant.y`` and ``reference.yd``."""
    names = _signals(result)
    if not all(c in names for c in TRACKING):
        return None
    import matplotlib.pyplot as plt

    fault = fault_time(record)
    t = result["time"]
    control = [c for c in CONTROL if c in names]
    first = t <= t[0] + 1.0
    zoom = bool(first.sum() > 2 and t[-1] > t[0] + 2.0)  # a panel on the first second
    panels = 2 + bool(control) + zoom
    fig, axes = plt.subplots(panels, 1, figsize=(10.5, 2.6 * panels), layout="constrained")
    axes = _shared_time(list(axes), zoom)
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


def _signals(result: np.ndarray) -> list[str]:
    """The result's columns besides time."""
    return [n for n in result.dtype.names or () if n != "time"]


def _shared_time(axes: list[Axes], zoom: bool) -> list[Axes]:
    """The panels sharing the first one's time axis, all but the zoom on the first second (the
    second panel, where there is one)."""
    for ax in axes[1:]:
        if ax is not axes[1] or not zoom:
            ax.sharex(axes[0])
    return axes


def _outputs(ax: Axes, result: np.ndarray, t: np.ndarray, fault: float | None,
             units: Mapping[str, str | None]) -> None:
    for c in TRACKING:
        ax.plot(t, result[c], label=c, linewidth=1)
    _fault_line(ax, fault, t, True)
    ax.set_ylabel(axis_label("output", list(TRACKING), units))
    _legend(ax)


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
    _legend(ax)


def _control(ax: Axes, result: np.ndarray, t: np.ndarray, control: list[str], fault: float | None,
             units: Mapping[str, str | None]) -> None:
    from matplotlib.ticker import NullLocator

    # the actuator's uf first and lighter, v on top: uf follows v, and v's bursts must stay visible
    style: dict[str, dict[str, Any]] = {"actuator.uf": {"color": "tab:orange", "alpha": 0.7, "zorder": 2},
             "controller.v": {"color": "tab:blue", "zorder": 3}}
    for c in sorted(control, key=lambda c: c != "actuator.uf"):
        ax.plot(t, result[c], label=c, linewidth=0.8, **style.get(c, {}))
    _fault_line(ax, fault, t, False)
    values = np.concatenate([result[c] for c in control])
    magnitude = np.abs(values)
    typical = float(np.percentile(magnitude, 95)) if magnitude.size else 0.0
    if typical > 0.0 and magnitude.max() > 50.0 * typical:  # the initial spike of the fixed-time law
        linthresh = 10.0 ** np.floor(np.log10(typical))  # a decade: the bursts stay in the linear part
        ax.set_yscale("symlog", linthresh=linthresh, linscale=1.0)
        ax.set_yticks(_decade_ticks(values, linthresh))
        ax.yaxis.set_minor_locator(NullLocator())
    ax.set_ylabel(axis_label("control", control, units))
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda i: labels[i] != "controller.v")  # v first, as drawn on top
    ax.legend([handles[i] for i in order], [labels[i] for i in order], loc="upper left",
              bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize="small", frameon=False)
