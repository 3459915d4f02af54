# SPDX-License-Identifier: BSD-2-Clause
"""The monolithic reference runs (30 s, solve_ivp at rtol 1e-10) that several tests compare with,
each computed once per test process. The tests of one example share the xdist group
``monolithic-references-<number>`` (``pytest -n 2 --dist loadgroup``, :func:`group`): one worker
computes each run once, and the two examples' runs (the pendulum's cost most) can go to two
workers."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from controller.params import EXPLICIT, Discretization, Mode
from fmu_src.models.examples import EXAMPLES
from orchestrator.experiments.closed_loop import simulate


def group(number: int) -> pytest.MarkDecorator:
    """The xdist group of the tests that use Example ``number``'s references."""
    return pytest.mark.xdist_group(f"monolithic-references-{number}")


@functools.cache
def reference(number: int, mode: Mode = Mode.FIXED_TIME, sample_time: float | None = None,
              discretization: Discretization = EXPLICIT) -> np.ndarray:
    """Example ``number`` over its 30 s on the 1 ms grid: the continuous law, or sampled and held
    every ``sample_time`` seconds with the law's ``discretization`` (read-only: shared between tests)."""
    example = EXAMPLES[number]
    params = example.controller.with_changes(mode=mode, discretization=discretization,
                                             sample_time=sample_time or 1e-3)
    data = simulate(example, params, sample_time=sample_time, grid=sample_time or 1e-3).data
    data.flags.writeable = False
    return data
