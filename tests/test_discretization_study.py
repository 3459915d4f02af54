# SPDX-License-Identifier: BSD-2-Clause
"""The chattering measures of the discretization study (orchestrator.experiments.discretization) on
signals whose answers are known by hand."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator.experiments.discretization import chattering


def test_smooth_signal_has_its_total_variation_and_no_burst() -> None:
    t = np.arange(0, 3000 + 1) * 1e-3
    v = np.sin(2 * np.pi * t)  # from 1 s to 3 s: two periods, variation 4 each
    c = chattering(t, v)
    assert c.tv_per_second == pytest.approx(4.0, rel=1e-5)
    assert c.peak == pytest.approx(1.0, rel=1e-5)
    assert (c.bursts, c.burst_time, c.longest_burst) == (0, 0.0, 0.0)


def test_two_bursts_counted_and_timed() -> None:
    h = 1e-3
    t = np.arange(0, 10000 + 1) * h
    v = 0.1 * np.sin(t)
    k = np.arange(t.size)
    for start, end in ((2.0, 2.5), (5.0, 5.2), (0.2, 0.5)):  # the last before 1 s: not counted
        inside = (t >= start) & (t < end)
        v[inside] += np.where(k[inside] % 2 == 0, 1.0, -1.0)
    c = chattering(t, v)
    assert c.bursts == 2
    # reversal samples run from the burst's first sample to its last: lengths 0.5 s and 0.2 s
    assert c.longest_burst == pytest.approx(0.5, abs=2 * h)
    assert c.burst_time == pytest.approx(0.7, abs=4 * h)
    assert c.peak == pytest.approx(1 + 0.1 * abs(np.sin(5.0)), abs=1e-4)  # at t = 5.001 s, v = -1 + 0.1 sin t


def test_bursts_closer_than_the_gap_are_one() -> None:
    h = 1e-3
    t = np.arange(0, 4000 + 1) * h
    v = np.zeros_like(t)
    k = np.arange(t.size)
    for start, end in ((2.0, 2.1), (2.15, 2.3)):  # 50 ms apart: under the 0.1 s gap
        inside = (t >= start) & (t < end)
        v[inside] = np.where(k[inside] % 2 == 0, 1.0, -1.0)
    assert chattering(t, v).bursts == 1
