# SPDX-License-Identifier: BSD-2-Clause
"""Issue 37, item 1: the plants' fail-fast bounds end no run that the closed loop settles (no false
divergence), and still end a finite escape.

Oracles: the continuous closed loop of the paper without any bound (``solve_ivp`` of
:mod:`orchestrator.experiments.closed_loop`'s right-hand side, :func:`reference_outcome`), and the
plant FMUs themselves. On main 5287c35 every state of :data:`ISSUE_STATES` ended at t = 0 with
fmi2Discard (the rate bound, y_limit 20 or the step budget), and on the wide grid 290 (Example 1)
and 110 (pendulum) of 441 states that the loop without bounds settles ended as diverged
(``make check-fail-fast`` in a checkout of main da039de).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from fmu_helpers import compiled_extension

from controller.params import EXPLICIT, FINITE_TIME, FIXED_TIME, SEMI_IMPLICIT
from fmu_src.models.examples import EXAMPLE1
from fmu_src.models.plants import STATE_LIMIT, StateLimitError, carried_beyond, dopri_hold_step, example1_rhs
from fmu_src.models.reference import reference_signal
from orchestrator import RunOptions, run
from orchestrator.experiments.campaigns import BAND
from orchestrator.experiments.escape_check import grid, reference_outcome, sampled_outcome
from orchestrator.experiments.metrics import settling_time

# The states of the issue: the continuous loop settles them in 0.05-0.08 s, main's plants ended
# them at t = 0 (x1 of Example 1 overshoots to 22-31 on the way).
ISSUE_STATES = [(2, (10.0, 8000.0)), (2, (-10.0, -8000.0)), (2, (15.0, 5000.0)), (2, (19.9, 100.0)),
                (1, (10.0, 9500.0)), (1, (-10.0, -9500.0)), (1, (19.0, 6000.0))]
IDS = [f"{n}:{a:g},{b:g}" for n, (a, b) in ISSUE_STATES]
SCENARIOS = {1: "example1_smooth", 2: "pendulum_smooth"}  # semi-implicit fixed-time law, no fault before 2 s


@functools.cache
def _reference(number: int, x0: tuple[float, float]):
    """The continuous loop without bounds over 0.2 s (Example 1 from x2(0) ~ 1e4: about 10 s of CPU,
    the solver resolving sin(x1^2 x2^2); computed once per state)."""
    return reference_outcome(number, x0, FIXED_TIME, horizon=0.2)


@pytest.fixture(scope="module")
def dopri(tmp_path_factory: pytest.TempPathFactory):
    """_dopri.c compiled as the FMU build compiles it (the plants' own step, fast)."""
    return compiled_extension("fmu_src.models._dopri", tmp_path_factory.mktemp("dopri"))


@pytest.mark.system
@pytest.mark.parametrize(("number", "x0"), ISSUE_STATES, ids=IDS)
def test_the_issues_states_settle_in_the_fmus_as_in_the_reference(built, number, x0) -> None:
    """The scenario's FMUs (default bounds) run from the state to 0.2 s and settle as the continuous
    law without bounds does: within 2 ms on the pendulum, 30 ms on Example 1 (the semi-implicit
    cap's transient; measured 5-23 ms) (main: fmi2Discard at t = 0)."""
    result = run(built / "ssp" / f"{SCENARIOS[number]}.ssp",
                 RunOptions(stop_time=0.2, overrides={"plant.x1_0": x0[0], "plant.x2_0": x0[1]}))
    rows = result.rows
    assert rows["time"][-1] == pytest.approx(0.2)
    error = rows["plant.y"] - np.array([reference_signal(t, EXAMPLE1.reference if number == 1 else
                                                         _pendulum_reference())[0] for t in rows["time"]])
    cosim = settling_time(rows["time"], error, BAND)
    reference = _reference(number, x0)
    assert reference.outcome == "settled"
    # the semi-implicit law's cap modifies the transient from far states (the study's finding):
    # measured 5-23 ms apart on Example 1, within 2 ms on the pendulum
    assert cosim == pytest.approx(reference.settling, abs=2e-3 if number == 2 else 0.03)


def _pendulum_reference():
    from fmu_src.models.examples import EXAMPLE2

    return EXAMPLE2.reference


@pytest.mark.parametrize("number", [1, 2])
def test_no_false_divergence_on_the_wide_grid(dopri, number) -> None:
    """The semi-implicit fixed-time loop (the smooth scenarios' law) with the plants' own step and
    default bounds from every state of the 11 x 11 grid over |x1(0)| <= 20, |x2(0)| <= 1e4 (every
    other point of the 21 x 21 grid, which ``make check-fail-fast`` runs; main's bounds falsely
    ended 290 (Example 1) and 110 (pendulum) of its 441 states, dense enough here too): none
    ends on a bound, and every one settles within 0.1 s; at the issue's states on the grid and the
    pendulum's corners (Example 1: at (10, 9000); its reference from a corner costs 20 s of CPU)
    its settling time is the continuous reference's (no bound) within 2 ms. About 75 s of CPU for
    Example 1 (its integrator resolves sin(x1^2 x2^2) at rtol 1e-10 in the first milliseconds), 8 s
    for the pendulum."""
    outcomes = {x0: sampled_outcome(number, x0, FIXED_TIME, SEMI_IMPLICIT, 0.15, compiled=dopri)
                for x0 in grid(11)}
    diverged = {x0: o.reason for x0, o in outcomes.items() if o.outcome == "diverged"}
    assert not diverged
    assert max(o.settling for o in outcomes.values()) <= 0.1
    checked = [(20.0, 1e4), (-20.0, -1e4), (20.0, -1e4), (-20.0, 1e4)] if number == 2 else [(10.0, 9000.0)]
    checked += [x0 for n, x0 in ISSUE_STATES if n == number and x0 in outcomes]
    for x0 in checked:
        if x0 not in outcomes:  # (10, 9000): on the 21 x 21 grid, between this one's points
            outcomes[x0] = sampled_outcome(number, x0, FIXED_TIME, SEMI_IMPLICIT, 0.15, compiled=dopri)
            assert outcomes[x0].outcome != "diverged", x0
        reference = _reference(number, x0)
        assert reference.outcome == "settled", x0
        tolerance = 2e-3 if number == 2 else 0.03  # the cap's modified transient on Example 1
        assert outcomes[x0].settling == pytest.approx(reference.settling, abs=tolerance), x0


@pytest.mark.parametrize(("number", "x0"), [(1, (6.0, 0.0)), (1, (-8.0, 4.0))])
def test_a_finite_escape_still_ends_on_a_bound(dopri, number, x0) -> None:
    """The finite-time law from states where the continuous loop escapes (the reference passes
    1e8): the sampled loop ends on a bound, before the reference's escape time plus 50 ms."""
    reference = reference_outcome(number, x0, FINITE_TIME, horizon=2.0)
    assert reference.outcome == "diverged" and "event" in reference.reason.lower() or reference.reached < 2.0
    sampled = sampled_outcome(number, x0, FINITE_TIME, EXPLICIT, 2.0, compiled=dopri)
    assert sampled.outcome == "diverged"
    assert "y_limit" in sampled.reason or "state_limit" in sampled.reason
    assert sampled.reached <= reference.reached + 0.05


def test_the_rate_bound_moves_the_state_on_at_its_rate() -> None:
    """main compared |dx/dt| h with the bound: x2 = 8000 brought back at 2e7 per second over 0.5 ms
    (to -2000) ended the step. The state carried on at its rate is what leaves the bound or not."""
    assert not carried_beyond((10.0, 8000.0, 0.0), (0.0, -2e7, 0.0), 5e-4, 100.0, 1e4)
    assert carried_beyond((10.0, 8000.0, 0.0), (0.0, 2e7, 0.0), 5e-4, 100.0, 1e4)
    assert carried_beyond((10.0, 0.0, 0.0), (1e6, 0.0, 0.0), 1e-3, 100.0, 1e4)  # x1 to 1010
    assert not carried_beyond((10.0, 0.0, 0.0), (1e6, 0.0, 0.0), 0.0, 100.0, 1e4)  # rate_horizon 0: off
    # a held input that drives x2 beyond the bound within the step ends it at the first evaluation,
    # the message saying where the state would be carried
    with pytest.raises(StateLimitError, match=r"would carry x2 from -10 to 3\.\d+e\+06, beyond the plant's "
                                              r"state_limit 1e\+06"):
        dopri_hold_step(example1_rhs, 0.0, (-10.0, -10.0, 0.0), 1.07e9, 1e-3, 1e-10, 1e-12, 0.0, STATE_LIMIT,
                        50_000, 100.0, 1.0)
    assert math.isfinite(STATE_LIMIT)
