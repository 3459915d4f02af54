# SPDX-License-Identifier: BSD-2-Clause
"""The paper's tracking metrics as campaign columns, and ``orchestrate sweep`` registered with them.

Every run of a campaign gets SPEC section 4's metrics over its whole horizon (RAE, MSE, RMSE, MAE,
settling time in the 0.05 band, peak |v|, peak |uf|), the largest and the final |y - yd|, when
the run's parameters name ``actuator.t_fault`` (varied or fixed in the design), MAE and the
largest |y - yd| from the fault on (NaN when the fault lies beyond the run), and the time reached.
A failed run keeps its peaks, largest error and the time it reached (:data:`PARTIAL`).

:data:`RESEARCH` (the research questions of issue 37, ``make research``) adds the recovery time
after the fault (:func:`~orchestrator.experiments.metrics.recovery_time`, pre-fault window
:data:`RECOVERY_WINDOW`) and the adaptive estimates' statistics per step i: the largest
``eta_hat_i``, its final value and its change over the last :data:`RECOVERY_WINDOW` of the run.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, cast

import numpy as np

from ..campaign import Metrics
from ..campaign import cli as campaign_cli
from .metrics import pre_fault_band, recovery_time, tracking_metrics

__all__ = ["BAND", "ESTIMATES", "PARTIAL", "RECOVERY_WINDOW", "RESEARCH", "TRACKING", "TRACKING_NAMES",
           "claim_headlines", "fault_headlines", "register", "research_row", "tracking_row"]

BAND = 0.05


def tracking_row(result: np.ndarray, params: Mapping[str, object]) -> dict[str, float]:
    """The metric columns of one run from its result array and parameters.

    ``time_reached`` is the last communication point computed: the stop time, or for the rows of a
    failed run (:data:`PARTIAL`, the columns such a row keeps) the last point before it failed.
    A single row (a run that failed in its first step) gives the peaks and ``time_reached`` only.
    """
    t, y, yd = result["time"], result["plant.y"], result["reference.yd"]
    error = np.abs(y - yd)
    row = dict.fromkeys(TRACKING_NAMES, math.nan)
    row.update(
        peak_v=float(np.max(np.abs(result["controller.v"]))),
        peak_uf=float(np.max(np.abs(result["actuator.uf"]))),
        max_error=float(error.max()),
        final_error=float(error[-1]),
        time_reached=float(t[-1]),
    )
    if t.size < 2:
        return row
    m = tracking_metrics(t, y, yd, result["controller.v"], result["actuator.uf"], band=BAND)
    assert m.effort_v is not None and m.energy_v is not None and m.effort_uf is not None  # v, uf given
    row.update(rae=m.rae, mse=m.mse, rmse=m.rmse, mae=m.mae, settling_time=m.settling_time,
               effort_v=m.effort_v, energy_v=m.energy_v, effort_uf=m.effort_uf)
    if "actuator.t_fault" in params:
        after = error[t >= float(cast("float | str", params["actuator.t_fault"]))]
        if after.size:
            row["mae_after_fault"] = float(after.mean())
            row["max_error_after_fault"] = float(after.max())
    return row


TRACKING_NAMES = (
    "rae",
    "mse",
    "rmse",
    "mae",
    "settling_time",
    "peak_v",
    "peak_uf",
    "effort_v",
    "energy_v",
    "effort_uf",
    "max_error",
    "final_error",
    "mae_after_fault",
    "max_error_after_fault",
    "time_reached",
)
# What a failed run's row keeps, computed on the rows before the failure.
PARTIAL = ("peak_v", "peak_uf", "max_error", "time_reached")
# The fault time defines the metrics after the fault: a run that stops before it has none.
AFTER_FAULT = ("mae_after_fault", "max_error_after_fault")
TRACKING = Metrics(names=TRACKING_NAMES, function=tracking_row, partial=PARTIAL,
                   events={"actuator.t_fault": AFTER_FAULT})

# The pre-fault window of the recovery time, and the final window of the estimates' change (s).
RECOVERY_WINDOW = 1.0
# The estimates' statistics for the steps of the study's plants (n = 2): NaN where a step is missing.
ESTIMATES = tuple(f"eta{i}_{what}" for what in ("max", "final", "change") for i in (1, 2))


def research_row(result: np.ndarray, params: Mapping[str, object]) -> dict[str, float]:
    """:func:`tracking_row` with ``recovery_time`` and its pre-fault band ``recovery_band`` (when
    ``actuator.t_fault`` lies inside the run, one window after its start) and, per step i = 1, 2,
    ``eta<i>_max``, ``eta<i>_final`` and
    ``eta<i>_change`` = eta_hat_i(T) - eta_hat_i(T - RECOVERY_WINDOW) (NaN for a shorter run)."""
    row = tracking_row(result, params)
    row.update(dict.fromkeys(("recovery_time", "recovery_band", *ESTIMATES), math.nan))
    t = result["time"]
    if "actuator.t_fault" in params:
        t_fault = float(cast("float | str", params["actuator.t_fault"]))
        if t[0] <= t_fault - RECOVERY_WINDOW and t[-1] >= t_fault:
            error = result["plant.y"] - result["reference.yd"]
            row["recovery_time"] = recovery_time(t, error, t_fault, RECOVERY_WINDOW)
            row["recovery_band"] = pre_fault_band(t, error, t_fault, RECOVERY_WINDOW)
    for i in (1, 2):
        name = f"controller.eta{i}_hat"
        if name not in (result.dtype.names or ()):
            continue
        eta = result[name]
        row[f"eta{i}_max"] = float(np.max(eta))
        row[f"eta{i}_final"] = float(eta[-1])
        if t[-1] - t[0] >= RECOVERY_WINDOW:
            row[f"eta{i}_change"] = float(eta[-1] - np.interp(t[-1] - RECOVERY_WINDOW, t, eta))
    return row


RESEARCH = Metrics(names=(*TRACKING_NAMES, "recovery_time", "recovery_band", *ESTIMATES),
                   function=research_row,
                   partial=(*PARTIAL, "eta1_max", "eta2_max"),
                   events={"actuator.t_fault": (*AFTER_FAULT, "recovery_time", "recovery_band")})


def register(sub: argparse._SubParsersAction) -> None:
    """``orchestrate sweep`` and ``campaign-report`` with the tracking metrics as columns."""
    campaign_cli.register(sub, metrics=TRACKING)


def _mode_name(value: object) -> str:
    return "fixed-time" if int(float(cast("float | str", value))) == 0 else "finite-time"


def claim_headlines(
    rows: Sequence[Mapping[str, Any]], fixed: Mapping[str, object] | None = None
) -> list[str]:
    """Headline findings of the fixed-time claim campaign (``ssp/campaigns/fixed_time_claim.toml``):
    per law, how many initial states diverge (the run fails), never enter the band within the
    horizon, or settle, and by when; the largest square max(|x1(0)|, |x2(0)|) <= R from which every
    run settles; and the states where one law settles and the other does not. ``fixed``: the
    design's fixed overrides (where ``controller.mode`` is when it does not vary)."""
    default_mode = (fixed or {}).get("controller.mode", 0)
    by_state: dict[tuple[float, float], dict[str, Mapping[str, Any]]] = {}
    for r in rows:
        by_state.setdefault((float(r["plant.x1_0"]), float(r["plant.x2_0"])), {})[
            _mode_name(r.get("controller.mode", default_mode))
        ] = r

    lines = []
    for mode in ("fixed-time", "finite-time"):
        runs = [s[mode] for s in by_state.values() if mode in s]
        if runs:
            lines.append(_law_headline(mode, runs))
    if len(lines) < 2:
        return lines
    only_fixed = _only_settles("fixed-time", "finite-time", by_state.values())
    only_finite = _only_settles("finite-time", "fixed-time", by_state.values())
    lines.append(
        f"States where only the fixed-time law settles: {only_fixed}; only the finite-time law: "
        f"{only_finite}."
    )
    return lines


def _settled(r: Mapping[str, Any] | None) -> bool:
    """The run finished and entered the band for good."""
    return r is not None and r["status"] == "ok" and math.isfinite(float(r["settling_time"]))


def _only_settles(law: str, other: str, states: Iterable[Mapping[str, Mapping[str, Any]]]) -> int:
    """How many initial states (each law -> its run) settle under ``law`` and not under ``other``."""
    return sum(_settled(s.get(law)) and not _settled(s.get(other)) for s in states)


def _settling_square(runs: Sequence[Mapping[str, Any]]) -> float:
    """The largest max(|x1(0)|, |x2(0)|) of the runs' initial states below which every run settles."""
    safe = min((_reach(r) for r in runs if not _settled(r)), default=math.inf)
    return max((_reach(r) for r in runs if _reach(r) < safe), default=math.nan)


def _reach(r: Mapping[str, Any]) -> float:
    """The run's initial state's distance from the origin in the max norm."""
    return max(abs(float(r["plant.x1_0"])), abs(float(r["plant.x2_0"])))


def _law_headline(mode: str, runs: Sequence[Mapping[str, Any]]) -> str:
    """One law's line of :func:`claim_headlines`: its runs by outcome, the span of settling times,
    the largest square of initial states that all settle."""
    failed = [r for r in runs if r["status"] != "ok"]
    never = [r for r in runs if r["status"] == "ok" and not _settled(r)]
    times = [float(r["settling_time"]) for r in runs if _settled(r)]
    largest = _settling_square(runs)
    text = (
        f"{mode}: {len(runs)} initial states, {len(failed)} diverge (run fails), {len(never)} never "
        f"enter the band, {len(times)} settle"
    )
    if times:
        text += f" within {min(times):.3f} .. {max(times):.3f} s"
    return text + f"; every state with max(|x1(0)|, |x2(0)|) <= {largest:g} settles."


def fault_headlines(
    rows: Sequence[Mapping[str, Any]], fixed: Mapping[str, object] | None = None
) -> list[str]:
    """Headline findings of the fault-tolerance campaign: per scenario and law, failures and the
    largest MAE and |y - yd| after the fault, with the worst run's fault (``fixed``: as for
    :func:`claim_headlines`)."""
    default_mode = (fixed or {}).get("controller.mode", 0)
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault(
            (str(r["scenario"]), _mode_name(r.get("controller.mode", default_mode))), []
        ).append(r)
    lines = []
    for (scenario, mode), runs in sorted(groups.items()):
        ok = [r for r in runs if r["status"] == "ok"]
        text = f"{scenario}, {mode}: {len(ok)} of {len(runs)} runs ok"
        if ok:
            worst = max(ok, key=lambda r: float(r["max_error_after_fault"]))
            fault = ", ".join(
                f"{k} = {float(worst[f'actuator.{k}']):.2f}"
                for k in ("K_inf", "L_bias", "t_fault", "b_r", "b_l")
            )
            text += (
                f"; MAE after the fault <= {max(float(r['mae_after_fault']) for r in ok):.2g}, "
                f"|y - yd| after the fault <= {float(worst['max_error_after_fault']):.2g} "
                f"(run {worst['run']}: {fault})"
            )
        lines.append(text + ".")
    return lines
