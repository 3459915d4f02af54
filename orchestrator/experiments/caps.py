# SPDX-License-Identifier: BSD-2-Clause
"""How often the semi-implicit cap, or an actuator limit, replaced the paper's law (issue 45).

The semi-implicit law (``discretization = 1``) gives each backstepping step the feedback
-sign(z_i) min(phi_i(|z_i|), |z_i| / (b_max h)) (:func:`controller.law.semi_implicit_feedback`):
at a sample where the cap |z_i| / (b_max h) is the smaller, the step's output zeta_i (v for the
last step) is the cap, not the paper's law. The controller FMUs output z_i, zeta_i (i < n) and v,
so the share of samples with the cap binding is measured from the run's own outputs:
|zeta_i| = |z_i| / (b_max h) to a relative 1e-12 (the FMU computes it as that quotient; a phi equal
to the cap to that precision is the same value either way). Samples with z_i = 0 (no feedback
either way) are left out. An explicit run has no cap (NaN). Behind an actuator limit u_max the
share of samples with |v| > u_max is the limit's.

The cap's b_max and h are the scenario's (``ssp/<scenario>/controller.ssv``) unless the run's
overrides set them, so :func:`metrics_for` binds one scenario's values into a campaign's metrics.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, cast

import numpy as np
from lxml import etree

from controller.params import SEMI_IMPLICIT, ControllerParameters

from ..campaign import Metrics

__all__ = ["CAP_NAMES", "LIMIT_NAME", "MAX_STEPS", "Sampling", "cap_cell", "cap_fractions", "metrics_for",
           "rows_cap_cell",
           "scenario_sampling"]

MAX_STEPS = 4  # the controller FMUs' orders 1-4
CAP_NAMES = tuple(f"cap{i}_active" for i in range(1, MAX_STEPS + 1))
LIMIT_NAME = "limit_active"
RELATIVE = 1e-12
MetricFunction = Callable[[np.ndarray, Mapping[str, object]], Mapping[str, float]]
SSP = Path("ssp")


@dataclass(frozen=True)
class Sampling:
    """A scenario's controller sampling: discretization (0 explicit, 1 semi-implicit), h and b_max."""

    discretization: int
    sample_time: float
    b_max: float


def scenario_sampling(scenario: str, root: Path = SSP) -> Sampling:
    """The controller's discretization, sample_time and b_max of ``ssp/<scenario>/controller.ssv``
    (the controller FMU's defaults where the scenario sets none)."""
    defaults = ControllerParameters(k=(1.0,), q=(1.0,), a=(1.0,), kappa=(1.0,), rho=(1.0,), rho_bar=(1.0,))
    values: dict[str, float] = {"discretization": int(defaults.discretization),
                                "sample_time": defaults.sample_time, "b_max": defaults.b_max}
    path = root / scenario / "controller.ssv"
    if path.is_file():
        for parameter in etree.parse(str(path)).getroot().iterfind(".//{*}Parameter"):
            name = parameter.get("name")
            if name in values:
                value = next(iter(parameter)).get("value")
                assert value is not None, f"{path}: parameter {name} has no value"
                values[name] = float(value)
    return Sampling(int(values["discretization"]), values["sample_time"], values["b_max"])


def _number(params: Mapping[str, object], name: str, default: float) -> float:
    return float(cast("float | str", params[name])) if name in params else default


def cap_fractions(result: np.ndarray, params: Mapping[str, object], sampling: Sampling) -> dict[str, float]:
    """``cap<i>_active`` per step i (NaN beyond the plant's order, or for an explicit run) and
    ``limit_active`` (NaN without ``actuator.u_max`` in ``params``) of one run's rows."""
    row = dict.fromkeys((*CAP_NAMES, LIMIT_NAME), math.nan)
    names = result.dtype.names or ()
    n = sum(f"controller.z{i}" in names for i in range(1, MAX_STEPS + 1))
    semi = int(_number(params, "controller.discretization", sampling.discretization)) == SEMI_IMPLICIT
    if semi and n:
        bh = _number(params, "controller.b_max", sampling.b_max) * _number(
            params, "controller.sample_time", sampling.sample_time)
        for i in range(1, n + 1):
            z = np.abs(result[f"controller.z{i}"])
            zeta = np.abs(result[f"controller.zeta{i}" if i < n else "controller.v"])
            acting = z != 0.0
            if acting.any():
                cap = z[acting] / bh
                row[CAP_NAMES[i - 1]] = float(np.mean(np.abs(zeta[acting] - cap) <= RELATIVE * cap))
    if "actuator.u_max" in params:
        u_max = _number(params, "actuator.u_max", math.inf)
        row[LIMIT_NAME] = float(np.mean(np.abs(result["controller.v"]) > u_max))
    return row


def metrics_for(metrics: Metrics, sampling: Sampling) -> Metrics:
    """``metrics`` with the columns of :func:`cap_fractions` for a scenario sampled as ``sampling``
    (kept by a failed run too: the share over the samples it reached)."""
    return Metrics(names=(*metrics.names, *CAP_NAMES, LIMIT_NAME),
                   function=partial(_with_caps, metrics.function, sampling),
                   partial=(*metrics.partial, *CAP_NAMES, LIMIT_NAME), events=metrics.events)


def _with_caps(base: MetricFunction, sampling: Sampling, result: np.ndarray,
               params: Mapping[str, object]) -> dict[str, float]:
    """``base``'s columns and :func:`cap_fractions` (a module-level function: the workers unpickle it)."""
    return {**base(result, params), **cap_fractions(result, params, sampling)}


def cap_cell(fractions: list[list[float]]) -> str:
    """A table cell: per step i the mean share of samples with the cap binding over a row's runs
    (``fractions[i]``: one value per run), "step 1 / step 2 / ..."; ``-`` without a cap (explicit
    sampling, continuous law); the row says when the last step was the cap at every sample of every
    run (v never came from the paper's law)."""
    steps = [[f for f in runs if math.isfinite(f)] for runs in fractions]
    if not steps or not all(steps):
        return "-"
    means = [float(np.mean(s)) for s in steps]
    text = " / ".join(_share(m) for m in means)
    if min(steps[-1]) == 1.0:
        text += " (v = the cap at every sample: the paper's law never acted)"
    return text


def rows_cap_cell(rows: Sequence[Mapping[str, Any]]) -> str:
    """:func:`cap_cell` of campaign rows (their ``cap<i>_active`` columns, the steps the plant has)."""
    fractions = [[_column(r, name) for r in rows] for name in CAP_NAMES]
    while fractions and not any(math.isfinite(f) for f in fractions[-1]):
        fractions.pop()
    return cap_cell(fractions)


def _column(row: Mapping[str, Any], name: str) -> float:
    value = row.get(name)
    return math.nan if value is None else float(value)


def _share(value: float) -> str:
    return "0" if value == 0.0 else "1" if value == 1.0 else f"{value:.3g}"
