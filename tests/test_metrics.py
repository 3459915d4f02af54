# SPDX-License-Identifier: BSD-2-Clause
"""Tracking metrics (SPEC section 4) on hand-made signals with known values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from orchestrator.experiments.metrics import TrackingMetrics, format_table, recovery_time, tracking_metrics


def periodic_grid(periods: int = 3, samples: int = 3000) -> np.ndarray:
    """Whole periods of sin t, endpoint excluded, so sum(sin) = 0 and sum(sin^2) = N/2 exactly."""
    return np.arange(samples) * (2.0 * math.pi * periods / samples)


def test_constant_offset() -> None:
    t = periodic_grid()
    yd = np.sin(t)
    c = -0.03
    m = tracking_metrics(t, yd + c, yd)
    assert m.mse == pytest.approx(c * c, rel=1e-12)
    assert m.rmse == pytest.approx(abs(c), rel=1e-12)
    assert m.mae == pytest.approx(abs(c), rel=1e-12)
    # sum y^2 = sum(sin^2) + 2c sum(sin) + N c^2 = N (1/2 + c^2).
    assert m.rae == pytest.approx(math.sqrt(c * c / (0.5 + c * c)), rel=1e-10)
    assert m.settling_time == 0.0  # inside the 0.05 band from the start
    assert m.peak_v is None and m.peak_uf is None


def test_sinusoidal_error() -> None:
    t = periodic_grid(periods=4, samples=40000)
    amplitude = 0.2
    yd = np.ones_like(t)
    m = tracking_metrics(t, yd + amplitude * np.sin(3.0 * t), yd)
    assert m.rmse == pytest.approx(amplitude / math.sqrt(2.0), rel=1e-12)  # RMS of a sine
    assert m.mse == pytest.approx(amplitude**2 / 2.0, rel=1e-12)
    assert m.mae == pytest.approx(2.0 * amplitude / math.pi, rel=1e-6)  # mean |sin| = 2/pi
    # sum y^2 = N (1 + amplitude^2 / 2): y = 1 + 0.2 sin(3t).
    assert m.rae == pytest.approx(math.sqrt((amplitude**2 / 2) / (1 + amplitude**2 / 2)), rel=1e-12)
    # |e| = 0.2 |sin 3t| last leaves the band 0.05 where 3t = 24 pi - asin(0.25), just before the end.
    last_exit = (24.0 * math.pi - math.asin(0.25)) / 3.0
    assert last_exit <= m.settling_time < last_exit + t[1]


@pytest.mark.parametrize("dt", [1e-3, 1e-2, 0.037])
def test_settling_time_of_exponential_decay(dt: float) -> None:
    c0, rate, band = 2.0, 1.5, 0.05
    t = np.arange(round(10.0 / dt) + 1) * dt
    yd = np.sin(t)
    m = tracking_metrics(t, yd + c0 * np.exp(-rate * t), yd, band=band)
    exact = math.log(c0 / band) / rate  # |e(t)| = band
    assert exact <= m.settling_time < exact + dt


def test_settling_time_after_a_late_excursion() -> None:
    t = np.linspace(0.0, 10.0, 1001)
    error = np.zeros_like(t)
    error[700] = 0.06  # outside the default band once, at t = 7
    error[701] = -0.05  # on the band edge counts as inside
    m = tracking_metrics(t, error, np.zeros_like(t))
    assert m.settling_time == t[701]


def test_settling_band_is_a_parameter() -> None:
    t = np.linspace(0.0, 1.0, 11)
    error = np.where(t < 0.5, 0.08, 0.0)
    assert tracking_metrics(t, error, 0 * t).settling_time == t[5]
    assert tracking_metrics(t, error, 0 * t, band=0.1).settling_time == 0.0


def test_never_settles_when_last_sample_is_outside() -> None:
    t = np.linspace(0.0, 1.0, 11)
    error = np.zeros_like(t)
    error[-1] = 1.0
    assert tracking_metrics(t, error, 0 * t).settling_time == math.inf


def test_peaks_of_control_signals() -> None:
    t = np.linspace(0.0, 1.0, 5)
    v = [1.0, -772.5, 3.0, 0.0, 2.0]
    uf = [0.0, 0.5, -0.25, 0.125, 0.0]
    m = tracking_metrics(t, t, t, v=v, uf=uf)
    assert (m.peak_v, m.peak_uf) == (772.5, 0.5)
    assert m.mse == 0.0 and m.mae == 0.0


def test_rae_undefined_for_zero_output() -> None:
    t = np.linspace(0.0, 1.0, 5)
    assert math.isnan(tracking_metrics(t, 0 * t, 0.01 + 0 * t).rae)


@pytest.mark.parametrize(
    ("t", "y", "yd", "kwargs", "message"),
    [
        ([0.0, 1.0, 2.0], [0.0, 1.0], [0.0, 1.0, 2.0], {}, "y has 2 samples but t has 3"),
        ([0.0, 1.0, 2.0], [0.0, 1.0, 2.0], [0.0], {}, "yd has 1 samples but t has 3"),
        ([0.0, 1.0, 2.0], [0, 1, 2], [0, 1, 2], {"v": [1.0]}, "v has 1 samples"),
        ([0.0, 1.0, 2.0], [0, 1, 2], [0, 1, 2], {"uf": [1.0, 2.0]}, "uf has 2 samples"),
        ([0.0], [0.0], [0.0], {}, "at least 2 samples"),
        ([[0.0, 1.0]], [0.0, 1.0], [0.0, 1.0], {}, "at least 2 samples"),
        ([0.0, 1.0, 2.5], [0, 1, 2], [0, 1, 2], {}, "not a uniform grid"),
        ([0.0, 1.0, 1.0], [0, 1, 2], [0, 1, 2], {}, "strictly increasing"),
        ([0.0, 1.0, 2.0], [0, math.nan, 2], [0, 1, 2], {}, "y has 1 non-finite samples (first at index 1)"),
        ([0.0, 1.0, 2.0], [0, 1, 2], [0, 1, 2], {"v": [0, 0, math.inf]}, "v has 1 non-finite"),
        ([0.0, 1.0, 2.0], [0, 1, 2], [0, 1, 2], {"band": 0.0}, "band must satisfy band > 0"),
        ([0.0, 1.0, 2.0], [0, 1, 2], [0, 1, 2], {"band": math.nan}, "band must satisfy band > 0"),
    ],
)
def test_invalid_inputs(t, y, yd, kwargs, message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        tracking_metrics(t, y, yd, **kwargs)


def test_grid_from_repeated_addition_is_accepted() -> None:
    # Accumulated time (t += h) drifts by rounding only; that is still a uniform grid.
    t = np.cumsum(np.full(30001, 1e-3)) - 1e-3
    assert tracking_metrics(t, np.zeros_like(t), np.zeros_like(t)).mse == 0.0


def test_format_table() -> None:
    rows = [
        ("Example 1, fixed-time", TrackingMetrics(0.1375, 0.0027, 0.0517, 0.0209, 1.25, 772.9, 771.0)),
        ("a | b", TrackingMetrics(0.5, 1.5e-4, 0.0122, 0.01, math.inf)),
    ]
    lines = format_table(rows).splitlines()
    assert len(lines) == 4
    assert lines[0].startswith("| case | RAE | MSE | RMSE | MAE |")
    assert lines[1].count("|") == lines[0].count("|")
    assert lines[2] == ("| Example 1, fixed-time | 0.1375 | 0.0027 | 0.0517 | 0.0209 | 1.250 | 772.9 | 771.0 "
                        "| - | - | - |")
    assert lines[3] == r"| a \| b | 0.5 | 0.00015 | 0.0122 | 0.01 | never | - | - | - | - | - |"


def test_control_effort_is_the_integral_of_the_held_signal() -> None:
    """Issue 37: the integrals of |v|, v^2 and |uf| of a signal held between samples, against the
    closed form: v = -2 on [0, 0.5), 4 on [0.5, 1) (the last sample covers no time), so int |v| =
    1 + 2 = 3, int v^2 = 2 + 8 = 10; uf = 3 e^(-t) sampled every 1e-4 s: int |uf| -> 3 (1 - e^-1)
    within the step's first-order error."""
    t = np.array([0.0, 0.5, 1.0])
    m = tracking_metrics(t, t, t, v=[-2.0, 4.0, 1e9], uf=[1.0, 1.0, 1.0])
    assert (m.effort_v, m.energy_v, m.effort_uf) == (3.0, 10.0, 1.0)
    fine = np.linspace(0.0, 1.0, 10001)
    m = tracking_metrics(fine, fine, fine, v=0 * fine, uf=3.0 * np.exp(-fine))
    assert m.effort_uf == pytest.approx(3.0 * (1.0 - math.exp(-1.0)), rel=1e-4)
    assert m.effort_v == 0.0 and tracking_metrics(t, t, t).effort_v is None


def test_recovery_time_of_an_exponential_decay() -> None:
    """Issue 37: |e| = 0.01 |sin(40 t)| before the fault (band: 0.01, its peak in the last second),
    A exp(-(t - t_f) / tau) after it: back inside the band at t_f + tau ln(A / 0.01), to within one
    sample (the first sample at or after that instant)."""
    h, t_f, tau, amplitude = 1e-3, 4.0005, 0.3, 2.0
    t = np.arange(0, 12001) * h
    e = np.where(t < t_f, 0.01 * np.sin(40.0 * t), amplitude * np.exp(-(t - t_f) / tau))
    exact = tau * math.log(amplitude / 0.01)  # 1.5895 s
    measured = recovery_time(t, e, t_f, window=1.0)
    assert exact <= measured < exact + h


def test_recovery_time_never_and_at_once() -> None:
    t = np.arange(0, 3001) * 1e-3
    step = np.where(t < 1.0, 0.01, 0.02)  # never back inside 0.01: inf (not an error)
    assert recovery_time(t, step, 1.0) == math.inf
    assert recovery_time(t, 0.01 * np.cos(t), 1.0) == 0.0  # |e| shrinks: never leaves its band
    with pytest.raises(ValueError, match="no sample at or after"):
        recovery_time(t, step, 4.0)
    with pytest.raises(ValueError, match="pre-fault window"):
        recovery_time(t, step, 0.0)
