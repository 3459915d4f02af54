"""The paper's tracking metrics as campaign columns, and ``orchestrate sweep`` registered with them.

Every run of a campaign gets SPEC section 4's metrics over its whole horizon (RAE, MSE, RMSE, MAE,
settling time in the 0.05 band, peak |v|, peak |uf|), the largest and the final |y - yd|, and,
when the run's parameters name ``actuator.t_fault`` (varied or fixed in the design), MAE and the
largest |y - yd| from the fault on (NaN when the fault lies beyond the run).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping

import numpy as np

from ..campaign import Metrics
from ..campaign import cli as campaign_cli
from .metrics import tracking_metrics

__all__ = ["BAND", "TRACKING", "register", "tracking_row"]

BAND = 0.05


def tracking_row(result: np.ndarray, params: Mapping[str, object]) -> dict[str, float]:
    """The metric columns of one run from its result array and parameters."""
    t, y, yd = result["time"], result["plant.y"], result["reference.yd"]
    m = tracking_metrics(t, y, yd, result["controller.v"], result["actuator.uf"], band=BAND)
    error = np.abs(y - yd)
    row = {
        "rae": m.rae,
        "mse": m.mse,
        "rmse": m.rmse,
        "mae": m.mae,
        "settling_time": m.settling_time,
        "peak_v": m.peak_v,
        "peak_uf": m.peak_uf,
        "max_error": float(error.max()),
        "final_error": float(error[-1]),
        "mae_after_fault": math.nan,
        "max_error_after_fault": math.nan,
    }
    if "actuator.t_fault" in params:
        after = error[t >= float(params["actuator.t_fault"])]
        if after.size:
            row["mae_after_fault"] = float(after.mean())
            row["max_error_after_fault"] = float(after.max())
    return row


TRACKING = Metrics(
    names=(
        "rae",
        "mse",
        "rmse",
        "mae",
        "settling_time",
        "peak_v",
        "peak_uf",
        "max_error",
        "final_error",
        "mae_after_fault",
        "max_error_after_fault",
    ),
    function=tracking_row,
)


def register(sub: argparse._SubParsersAction) -> None:
    """``orchestrate sweep`` and ``campaign-report`` with the tracking metrics as columns."""
    campaign_cli.register(sub, metrics=TRACKING)
