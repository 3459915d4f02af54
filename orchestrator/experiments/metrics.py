# SPDX-License-Identifier: BSD-2-Clause
"""Tracking metrics of SPEC section 4 (the paper's eq. 94-97) on a uniform sample grid.

With ``e = y - yd`` sampled at ``t_0 < t_1 < ... < t_N`` (uniform step):

* ``RAE = sqrt(sum e^2 / sum y^2)``, ``MSE = mean(e^2)``, ``RMSE = sqrt(MSE)``, ``MAE = mean|e|``;
  plain sample sums and means, which are time averages only because the grid is uniform (so the
  grid is checked);
* settling time: the first sample time ``t_j`` such that ``|e_k| <= band`` for every ``k >= j``.
  If ``|e|`` never leaves the band it is ``t_0``; if the last sample is outside the band the run
  never settles and it is ``math.inf``;
* peak ``|v|`` and peak ``|uf|`` when those signals are given (``None`` otherwise);
* control effort (issue 37) when they are given: the integrals of ``|v|``, ``v^2`` and ``|uf|``
  over the run, of the signals as a sampled controller applies them (held from each sample to the
  next: ``sum |v_k| (t_(k+1) - t_k)``, exact for the zero-order hold, no quadrature error);
* recovery after a fault at ``t_fault`` (issue 37, :func:`recovery_time`): the pre-fault band is
  the largest ``|e|`` over the window ``t_fault - window <= t < t_fault``; the recovery time is the
  settling time into that band of the samples from ``t_fault`` on, measured from ``t_fault``:
  ``t_j - t_fault`` for the first sample ``t_j >= t_fault`` after which ``|e| <= band`` holds to the
  end (0 if ``|e|`` never leaves the band), ``math.inf`` if the last sample is outside it (the error
  has not returned within the run: "never", which is an answer, not a failed run).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "GRID_RTOL", "TrackingMetrics", "format_table", "held_integral", "pre_fault_band", "recovery_time",
    "settling_time",
    "tracking_metrics",
]

# Largest allowed deviation of any sample step from the mean step, relative to the mean step.
GRID_RTOL = 1e-6


@dataclass(frozen=True)
class TrackingMetrics:
    """Metrics of one run; ``settling_time`` is ``inf`` if the run never settles."""

    rae: float
    mse: float
    rmse: float
    mae: float
    settling_time: float
    peak_v: float | None = None
    peak_uf: float | None = None
    effort_v: float | None = None  # integral of |v| dt
    energy_v: float | None = None  # integral of v^2 dt
    effort_uf: float | None = None  # integral of |uf| dt


def held_integral(t: np.ndarray, values: np.ndarray) -> float:
    """The integral over [t_0, t_N] of a signal held at ``values[k]`` over [t_k, t_(k+1)) (the last
    sample, applied at t_N, covers no time)."""
    return float(np.sum(values[:-1] * np.diff(t)))


def _signal(name: str, values: ArrayLike, length: int) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    if array.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional (got shape {array.shape})")
    if array.size != length:
        raise ValueError(f"{name} has {array.size} samples but t has {length}")
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise ValueError(f"{name} has {bad.size} non-finite samples (first at index {bad[0]})")
    return array


def _check_grid(t: np.ndarray) -> None:
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        index = int(np.flatnonzero(steps <= 0.0)[0])
        raise ValueError(f"t must be strictly increasing (t[{index}] = {t[index]!r}, t[{index + 1}] = "
                         f"{t[index + 1]!r})")
    mean_step = (t[-1] - t[0]) / steps.size
    deviation = float(np.max(np.abs(steps - mean_step)))
    if deviation > GRID_RTOL * mean_step:
        raise ValueError(f"t is not a uniform grid: a step deviates from the mean step {mean_step!r} by "
                         f"{deviation!r} (allowed {GRID_RTOL:g} relative)")


def settling_time(t: np.ndarray, error: np.ndarray, band: float) -> float:
    """First sample time after which ``|error| <= band`` holds to the end (``inf`` if never)."""
    outside = np.flatnonzero(np.abs(error) > band)
    if outside.size == 0:
        return float(t[0])
    last = int(outside[-1])
    return float(t[last + 1]) if last + 1 < t.size else math.inf


def pre_fault_band(t: ArrayLike, error: ArrayLike, t_fault: float, window: float = 1.0) -> float:
    """The largest ``|error|`` over ``t_fault - window <= t < t_fault``: the band :func:`recovery_time`
    measures the return into. ``ValueError`` if the window holds no sample or is not positive."""
    t = np.asarray(t, dtype=float)
    if not (math.isfinite(window) and window > 0.0):
        raise ValueError(f"window must satisfy window > 0 (got {window!r})")
    before = (t >= t_fault - window) & (t < t_fault)
    if not before.any():
        raise ValueError(f"no sample in the pre-fault window [{t_fault - window!r}, {t_fault!r})")
    return float(np.max(np.abs(np.asarray(error, dtype=float)[before])))


def recovery_time(t: ArrayLike, error: ArrayLike, t_fault: float, window: float = 1.0) -> float:
    """Time after ``t_fault`` until ``|error|`` is back inside its pre-fault band for good.

    The band is :func:`pre_fault_band` (module docstring); the result is 0 if ``|error|`` never
    leaves it from ``t_fault`` on and ``math.inf`` if the last sample is outside it. ``ValueError``
    if the window holds no sample or no sample lies at or after ``t_fault`` (the band or the
    recovery would be undefined), or for a window that is not positive.
    """
    t = np.asarray(t, dtype=float)
    band = pre_fault_band(t, error, t_fault, window)
    after = t >= t_fault
    if not after.any():
        raise ValueError(f"no sample at or after t_fault = {t_fault!r} (the run ends at {t[-1]!r})")
    e = np.abs(np.asarray(error, dtype=float)[after])
    if np.all(e <= band):
        return 0.0
    return settling_time(t[after], e, band) - t_fault


def tracking_metrics(
    t: ArrayLike,
    y: ArrayLike,
    yd: ArrayLike,
    v: ArrayLike | None = None,
    uf: ArrayLike | None = None,
    band: float = 0.05,
) -> TrackingMetrics:
    """Metrics of output ``y`` tracking ``yd`` on the uniform grid ``t`` (at least 2 samples).

    Raises ``ValueError`` for arrays of different lengths, non-finite samples, a grid that is not
    strictly increasing and uniform (within ``GRID_RTOL``), or a band that is not positive.
    ``rae`` is NaN when ``y`` is identically zero (the ratio is undefined).
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"t must be a one-dimensional grid of at least 2 samples (got shape {t.shape})")
    t = _signal("t", t, t.size)
    _check_grid(t)
    if not (math.isfinite(band) and band > 0.0):
        raise ValueError(f"band must satisfy band > 0 (got {band!r})")
    y = _signal("y", y, t.size)
    error = y - _signal("yd", yd, t.size)
    sum_e2 = float(np.sum(error * error))
    sum_y2 = float(np.sum(y * y))
    mse = sum_e2 / t.size
    return TrackingMetrics(
        rae=math.sqrt(sum_e2 / sum_y2) if sum_y2 > 0.0 else math.nan,
        mse=mse,
        rmse=math.sqrt(mse),
        mae=float(np.mean(np.abs(error))),
        settling_time=settling_time(t, error, band),
        **_effort(t, v, uf),
    )


def _effort(t: np.ndarray, v: ArrayLike | None, uf: ArrayLike | None) -> dict[str, float | None]:
    """The peaks and held integrals of |v| (and v^2) and |uf|; None for a signal not given."""
    v_abs, uf_abs = (None if signal is None else np.abs(_signal(name, signal, t.size))
                     for name, signal in (("v", v), ("uf", uf)))
    return {
        "peak_v": None if v_abs is None else float(np.max(v_abs)),
        "peak_uf": None if uf_abs is None else float(np.max(uf_abs)),
        "effort_v": None if v_abs is None else held_integral(t, v_abs),
        "energy_v": None if v_abs is None else held_integral(t, v_abs * v_abs),
        "effort_uf": None if uf_abs is None else held_integral(t, uf_abs),
    }


def _cell(value: float | None, spec: str) -> str:
    if value is None:
        return "-"
    if math.isinf(value):
        return "never"
    return format(value, spec)


def format_table(rows: Sequence[tuple[str, TrackingMetrics]]) -> str:
    """A Markdown table with one row per ``(name, metrics)``; ``-`` marks a signal not given."""
    lines = [
        "| case | RAE | MSE | RMSE | MAE | settling time (s) | peak abs(v) | peak abs(uf) "
        "| int abs(v) dt | int v^2 dt | int abs(uf) dt |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, m in rows:
        cells = [
            name.replace("|", "\\|"),
            _cell(m.rae, ".4g"),
            _cell(m.mse, ".4g"),
            _cell(m.rmse, ".4g"),
            _cell(m.mae, ".4g"),
            _cell(m.settling_time, ".3f"),
            _cell(m.peak_v, ".1f"),
            _cell(m.peak_uf, ".1f"),
            _cell(m.effort_v, ".4g"),
            _cell(m.energy_v, ".4g"),
            _cell(m.effort_uf, ".4g"),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
