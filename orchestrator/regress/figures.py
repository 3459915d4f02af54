# SPDX-License-Identifier: BSD-2-Clause
"""Figures of signal checks: the baseline, its tube and the result, then the deviation from the
baseline with the tube around zero, so that a reviewer sees where and by how much a signal left it."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from .tubes import Comparison, SignalCheck

__all__ = ["plot_failures", "signal_png"]


def signal_png(check: SignalCheck, result_label: str = "result", dpi: int = 90) -> bytes:
    """The figure of one signal check as PNG bytes (two panels: values, then result - baseline)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    s = check
    fig = Figure(figsize=(9, 5.2))
    ax, ax_d = fig.subplots(2, 1, sharex=True)
    ax.fill_between(s.time, s.lower, s.upper, color="tab:green", alpha=0.25, label="tube")
    ax.plot(s.time, s.reference, color="tab:green", linewidth=1, label="baseline")
    ax.plot(s.time, s.value, color="tab:blue", linewidth=1, label=result_label)
    out = (s.value < s.lower) | (s.value > s.upper) | ~np.isfinite(s.value)
    if out.any():
        ax.plot(s.time[out], s.value[out], "r.", markersize=3, label="outside")
    ax.set_ylabel(s.name)
    ax.legend(loc="best", fontsize="small")
    if s.n_out:
        title = (f"{s.name}: {s.n_out} samples outside, worst {s.worst_excess:.3g} beyond at "
                 f"t = {s.worst_time:.3f} s")
    else:
        title = f"{s.name}: inside its tube, max |deviation| {s.max_deviation:.3g}"
    ax.set_title(title, fontsize="medium")
    ax_d.fill_between(s.time, s.lower - s.reference, s.upper - s.reference, color="tab:green", alpha=0.25)
    ax_d.plot(s.time, s.value - s.reference, color="tab:blue", linewidth=1)
    ax_d.set_ylabel(f"{result_label} - baseline")
    ax_d.set_xlabel("time (s)")
    for a in (ax, ax_d):
        a.grid(True, alpha=0.3)
    fig.subplots_adjust(left=0.11, right=0.98, top=0.93, bottom=0.1, hspace=0.28)  # tight_layout: 2x slower
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def plot_failures(comparison: Comparison, folder: str | os.PathLike) -> list[Path]:
    """One PNG per signal outside its tube, ``folder/<signal>.png`` (``orchestrate compare
    --plot-dir``); returns the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for check in comparison.failed:
        path = folder / f"{check.name.replace(os.sep, '_')}.png"
        path.write_bytes(signal_png(check, dpi=100))
        written.append(path)
    return written
