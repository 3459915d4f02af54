# SPDX-License-Identifier: BSD-2-Clause
"""Pieces of the fixed-time study (issue 24): the paper's bound (83) against its formula worked by
hand, the actuator's saturation against its definition (SPEC section 10), the plants' fail-fast
bounds on a diverging step (issue 20), and the study's table and figure helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.params import FINITE_TIME, ControllerParameters
from fmu_src.models.actuator import ActuatorParameters, actuator_output, actuator_problems, dead_zone
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2
from fmu_src.models.plants import (
    MAX_STEPS,
    StateLimitError,
    dopri_hold_step,
    example1_rhs,
    hold_step,
    pendulum_rhs,
)
from orchestrator.campaign import read_design
from orchestrator.campaign.report import colour_norm
from orchestrator.campaign.table import Journal, read_rows
from orchestrator.experiments.campaigns import PARTIAL, tracking_row
from orchestrator.experiments.fixed_time_bound import fixed_time_bound
from orchestrator.experiments.fixed_time_study import (
    Cell,
    cap_binds,
    cells_from_rows,
    draw_maps,
    study_table,
    summarize,
)

# -- the bound (83) ---------------------------------------------------------------------------------


@pytest.mark.parametrize("phi", [0.25, 0.5, 0.9])
def test_bound_of_the_papers_gains_by_hand(phi: float) -> None:
    """Example 1 without fault (b_m = m_bar = 1): c = min(2^1.5 * 20, 2^1.5 * 10, rho = 2, a_bar = 1)
    = 1 and c_hat = min(2^0.75 * 16, 2^0.75 * 8, rho_bar = 1, a_bar = 1) = 1, so eq. (83) gives
    1 / (phi * 0.5) + 1 / (phi * 0.25) = 6 / phi; the pendulum's rho = 1, rho_bar >= 1 give the same."""
    for example in (EXAMPLE1, EXAMPLE2):
        bound = fixed_time_bound(example.controller, b_m=1.0, m_bar=1.0, phi=phi)
        assert bound.constant("c") == 1.0 and bound.constant("c_hat") == 1.0
        assert bound.t_m == pytest.approx(6.0 / phi, rel=1e-15)
        assert bound.infimum == pytest.approx(6.0, rel=1e-15)


def test_bound_where_the_gains_bind() -> None:
    """Small k and q, large rho, rho_bar and a_bar: the z-terms set c and c_hat. With k = q =
    (0.1, 0.1), b_m = 1, m_bar = 0.4: c_1 = 0.1 + 0.04, c_2 = 0.04 (likewise c_tilde), so
    c = 2^alpha 0.04 and c_hat = 2^beta 0.04, and eq. (83) at alpha = 2, beta = 0.6, Phi = 0.5."""
    params = ControllerParameters(
        k=(0.1, 0.1), q=(0.1, 0.1), a=(1, 1), kappa=(1, 1), rho=(5, 5), rho_bar=(5, 5), alpha=2.0, beta=0.6,
        a_bar=10.0,
    )
    bound = fixed_time_bound(params, b_m=1.0, m_bar=0.4, phi=0.5)
    c, c_hat = 4.0 * 0.04, 2.0**0.6 * 0.04
    assert bound.constant("c") == pytest.approx(c, rel=1e-15)
    assert bound.constant("c_hat") == pytest.approx(c_hat, rel=1e-15)
    assert bound.t_m == pytest.approx(1 / (c * 0.5 * 1.0) + 1 / (c_hat * 0.5 * 0.4), rel=1e-14)
    assert all(constant.source for constant in bound.constants)


def test_bound_refuses_what_the_theorem_does_not_cover() -> None:
    with pytest.raises(ValueError, match="finite-time"):
        fixed_time_bound(EXAMPLE1.controller.with_changes(mode=FINITE_TIME), 1.0, 1.0)
    with pytest.raises(ValueError, match="Phi"):
        fixed_time_bound(EXAMPLE1.controller, 1.0, 1.0, phi=1.0)
    with pytest.raises(ValueError, match="positive"):
        fixed_time_bound(EXAMPLE1.controller, 0.0, 1.0)


# -- saturation -------------------------------------------------------------------------------------


@pytest.mark.parametrize("v", [-2e4, -150.0, -100.0, -3.0, 0.0, 0.55, 99.9, 100.0, 1e7])
@pytest.mark.parametrize("t", [0.0, 10.0, 12.5])
def test_saturation_acts_before_the_dead_zone_and_the_fault(v: float, t: float) -> None:
    """SPEC section 10: v_sat = clip(v, -u_max, u_max), then uf of section 2 with v_sat, written out
    here from the paper's eq. (2)-(6), (86)-(87) with Example 1's numbers."""
    p = ActuatorParameters(u_max=100.0)
    v_sat = -100.0 if v < -100.0 else 100.0 if v > 100.0 else v
    u = 1.0 * (v_sat - 0.5) if v_sat >= 0.5 else 1.2 * (v_sat + 0.6) if v_sat <= -0.6 else 0.0
    x1, x2 = 0.3, -0.7
    expected = v_sat if t < 10.0 else (0.4 + 0.6 * math.exp(-0.2 * t)) * u + x2 * math.cos(x1) ** 2
    uf, u_dz = actuator_output(t, v, x1, x2, p)
    assert uf == pytest.approx(expected, rel=1e-15, abs=1e-15)
    assert u_dz == pytest.approx(u, rel=1e-15, abs=1e-15)


def test_no_limit_by_default_and_the_limit_is_checked() -> None:
    p = ActuatorParameters()
    for v in (-1.07e7, -0.3, 15218.0, 1e299):
        assert actuator_output(0.0, v, 0.1, 0.2, p) == (v, dead_zone(v, p))
    assert actuator_output(0.0, math.inf, 0.0, 0.0, ActuatorParameters(u_max=math.inf))[0] == math.inf
    for bad in (0.0, -1.0, math.nan):
        assert any("u_max" in problem for problem in actuator_problems(ActuatorParameters(u_max=bad)))
    assert actuator_problems(ActuatorParameters(u_max=math.inf)) == []


# -- fail fast --------------------------------------------------------------------------------------


def test_an_escaping_state_stops_at_the_state_limit() -> None:
    """Example 1 under a held uf = 1e4: x2' >= (2 - 1) 1e4 - 0.5 - x1^2 |z| with x1 ~ 1, so x2 passes
    100 within about 10 ms; with state_limit 100 the step ends there, the state just past 100."""
    with pytest.raises(StateLimitError, match="state_limit 100") as raised:
        dopri_hold_step(example1_rhs, 0.0, (1.0, 0.0, 0.0), 1e4, 0.1, 1e-10, 1e-12, 0.0, limit=100.0)
    assert "t = " in str(raised.value)
    message = str(raised.value)
    t = float(message.split("t = ")[1].split(" ")[0])
    # x2 grows at a rate between 1e4 - 10 and 3e4 + 10 while x1, z stay small: 100 is passed by
    # t in [100 / (3e4 + 10), 100 / (1e4 - 10)]
    assert 100 / (3e4 + 10) <= t <= 100 / (1e4 - 10)


def test_an_escaping_output_stops_at_y_limit() -> None:
    """The same held uf = 1e4 from x1 = 1: x1' = (2 + sin x1) x2 with x2 ~ 1e4 t, so x1 passes 5
    (|x1| > y_limit = 5) while x2 is still far below state_limit; the message names y_limit."""
    with pytest.raises(StateLimitError, match="y_limit 5 "):
        dopri_hold_step(example1_rhs, 0.0, (1.0, 0.0, 0.0), 1e4, 0.1, 1e-10, 1e-12, 0.0, 1e4, y_limit=5.0)


@pytest.mark.system
def test_the_plant_fmu_fails_fast_on_a_diverging_run(fmus: dict, caplog: pytest.LogCaptureFixture) -> None:
    """The explicit fixed-time law's first sample from (-10, -10), 1.07e7, held on the Example 1 FMU:
    a doStep within the first few ends in fmi2Discard (the message says which bound); a finite
    escape of the output ends at y_limit."""
    import logging

    from fmpy import simulate_fmu

    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        result = simulate_fmu(fmus["Example1Plant"], stop_time=0.01, output_interval=1e-3,
                              start_values={"uf": 1.07e7, "x1_0": -10.0, "x2_0": -10.0})
    # issue 37: with the wider bounds (state_limit 1e6, the rate bound on the moved state) the held
    # control carries x2 by 3e4 per step, so the run ends a few steps in, not at the first
    assert len(result) <= 4
    assert "step rejected (fmi2Discard)" in caplog.text
    bounds = ("state_limit 1e+06", "y_limit 100", "step budget of 2000000")
    assert any(bound in caplog.text for bound in bounds)
    caplog.clear()
    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        result = simulate_fmu(fmus["Example1Plant"], stop_time=1.0, output_interval=1e-3,
                              start_values={"uf": 100.0, "y_limit": 3.0})
    assert "y_limit 3" in caplog.text and "step rejected (fmi2Discard)" in caplog.text
    assert np.all(np.abs(result["x1"]) <= 3.0) and result["time"][-1] < 1.0


@pytest.mark.system
def test_the_plant_fmu_names_the_rate_bound(fmus: dict, caplog: pytest.LogCaptureFixture) -> None:
    """main: the Example 1 FMU under the explicit fixed-time law's first sample from (-10, -10),
    1.07e7, spent its step budget of 50 000 integrator steps (0.2-0.3 s of CPU) in its first doStep.
    Now the rate bound ends that doStep at its first evaluation (the message names x2, the bound and
    the communication step), the states stay at the initial ones; rate_horizon = 0 turns it off and
    the step budget ends it as before."""
    import logging

    from fmpy import simulate_fmu

    start = {"uf": 1.07e7, "x1_0": -10.0, "x2_0": -10.0, "state_limit": 1e4}
    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        result = simulate_fmu(fmus["Example1Plant"], stop_time=0.01, output_interval=1e-3, start_values=start)
    assert "would carry x2 from -10 to 3" in caplog.text
    assert "beyond the plant's state_limit 10000, within 0.001 s" in caplog.text
    assert "step rejected (fmi2Discard)" in caplog.text
    assert np.all(result["time"] == 0.0) and np.all(result["x2"] == -10.0)  # no step was taken
    caplog.clear()
    with caplog.at_level(logging.ERROR, logger="fixed_time_cosim.fmu"):
        simulate_fmu(fmus["Example1Plant"], stop_time=0.001, output_interval=1e-3,
                     start_values={**start, "rate_horizon": 0.0, "max_steps": 500})
    assert "step budget of 500 integrator steps" in caplog.text


def test_the_step_budget_ends_a_crawling_step() -> None:
    """A held uf of 1e7 from (-10, -10) (the explicit fixed-time law's first sample): the integrator
    needs more than 100 000 steps for the first millisecond; a budget of 500 ends it after 500."""
    with pytest.raises(ValueError, match="step budget of 500 integrator steps") as raised:
        dopri_hold_step(example1_rhs, 0.0, (-10.0, -10.0, 0.0), 1.07e7, 1e-3, 1e-10, 1e-12, 0.0,
                        max_steps=500)
    accepted, rejected = (int(w) for w in str(raised.value).split("(")[1].split()[::2][:2])
    assert accepted + rejected == 500


def test_the_limits_leave_an_ordinary_step_alone() -> None:
    state = (0.5, 0.5, 0.0)
    plain = dopri_hold_step(example1_rhs, 0.0, state, 770.0, 1e-3, 1e-10, 1e-12, 0.0, math.inf, 10**9)
    assert plain.accepted + plain.rejected < 1000
    assert dopri_hold_step(example1_rhs, 0.0, state, 770.0, 1e-3, 1e-10, 1e-12, 0.0, 1e4, 1000) == plain
    bounded = dopri_hold_step(example1_rhs, 0.0, state, 770.0, 1e-3, 1e-10, 1e-12, 0.0, 1e4, 1000, 20.0, 1.0)
    assert bounded == plain


class Counted:
    """A right-hand side that counts its evaluations."""

    def __init__(self, rhs) -> None:
        self.rhs, self.calls = rhs, 0

    def __call__(self, t, state, uf):
        self.calls += 1
        return self.rhs(t, state, uf)


def test_a_held_input_that_drives_the_state_out_ends_at_the_first_evaluation() -> None:
    """main: the explicit fixed-time law's first sample from (-10, -10), 1.07e7, held on Example 1
    crawled through 50 000 integrator steps (about 300 000 evaluations, 0.2-0.3 s) before the step
    budget ended it. x2' = (2 + cos(x1 x2)) uf + 0.5 sin(x1^2 x2^2) + x1^2 z >= 1.07e7 - 0.5 at the
    start, so x2 moves by more than 1e4 = state_limit within h = 1 ms at that rate: the rate bound
    (rate_horizon 1) ends the step on the first evaluation, naming x2 and state_limit."""
    rhs = Counted(example1_rhs)
    with pytest.raises(StateLimitError, match=r"dx2/dt = 3\.0\d+e\+07 at t = 0\.0 would carry x2 from -10 to "
                       r"3\d{4}\.?\d*, beyond the plant's state_limit 10000, within 0\.001 s") as raised:
        dopri_hold_step(rhs, 0.0, (-10.0, -10.0, 0.0), 1.07e7, 1e-3, 1e-10, 1e-12, 0.0, 1e4, MAX_STEPS, 20.0,
                        1.0)
    assert rhs.calls == 1 and "rate_horizon" in str(raised.value)
    assert (2 + math.cos(100.0)) * 1.07e7 * 1e-3 > 1e4  # the oracle: the bound holds
    # the same with RK4, and x1's bound is y_limit: x1' = (2 + sin x1) x2 >= 1 * 1e4 at x2 = 1e4,
    # y_limit 5 passed within 1 ms at that rate (1e4 * 1e-3 = 10 > 5)
    rhs = Counted(example1_rhs)
    with pytest.raises(StateLimitError,
                       match=r"dx1/dt = .* would carry x1 from 1 to .*, beyond the plant's y_limit 5,"):
        hold_step(rhs, 0.0, (1.0, 1e4, 0.0), 0.0, 1e-3, 2.5e-5, 1e6, 5.0, 1.0)
    assert rhs.calls == 1


def test_the_rate_bound_leaves_the_largest_settling_transients_alone() -> None:
    """The largest held controls of the study's runs that settle, at their step: Example 1,
    semi-implicit, |uf| 3.45e5 at 1 ms (x2' h <= 3 * 3.45e5 * 1e-3 + 1 ~ 1.04e3), the pendulum,
    semi-implicit, |uf| 5.1e6 at 0.5 ms (x2' h ~ uf h / (M L) = 2.6e3), both below state_limit 1e4:
    the step with the rate bound equals the step without it, bit for bit."""
    cases = (
        (example1_rhs, (10.0, 10.0, 0.0), -3.45e5, 1e-3),
        (lambda t, x, u: pendulum_rhs(t, x, u, EXAMPLE2.plant), (10.0, 10.0, 0.0), -5.1e6, 5e-4),
    )
    for rhs, state, uf, h in cases:
        plain = dopri_hold_step(rhs, 0.0, state, uf, h, 1e-10, 1e-12, 0.0, 1e4, 10**6, 20.0, 0.0)
        assert dopri_hold_step(rhs, 0.0, state, uf, h, 1e-10, 1e-12, 0.0, 1e4, 10**6, 20.0, 1.0) == plain


# -- the study's rows, table and figures ----------------------------------------------------------


def _result(times: list[float], v: list[float]) -> np.ndarray:
    n = len(times)
    columns = ("time", "plant.y", "reference.yd", "controller.v", "actuator.uf")
    data = np.zeros(n, dtype=[(c, float) for c in columns])
    data["time"], data["controller.v"], data["actuator.uf"] = times, v, v
    data["plant.y"] = 0.5
    return data


def test_a_failed_runs_rows_keep_its_peak_and_the_time_it_reached() -> None:
    """A run that failed in its first step has one row: its peak |v| is that row's |v|."""
    row = tracking_row(_result([0.0], [-1.07e7]), {})
    assert row["peak_v"] == 1.07e7 and row["time_reached"] == 0.0
    assert math.isnan(row["settling_time"])
    row = tracking_row(_result([0.0, 0.001, 0.002], [3.0, -7.0, 1.0]), {})
    assert (row["peak_v"], row["time_reached"], row["max_error"]) == (7.0, 0.002, 0.5)
    assert set(PARTIAL) <= set(row)


def test_integer_parameters_stay_integers_in_the_table(tmp_path) -> None:
    columns = ["run", "run_id", "scenario", "controller.mode", "plant.x1_0", "status", "reason", "peak_v"]
    journal = Journal(tmp_path, columns, {})
    journal.start([])
    journal.append({"run": 0, "run_id": "a", "scenario": "s", "controller.mode": 1, "plant.x1_0": -10.0,
                    "status": "ok", "reason": "", "peak_v": 3.0})
    journal.finish()
    _, rows = read_rows(tmp_path / "runs.csv")
    assert rows[0]["controller.mode"] == 1 and isinstance(rows[0]["controller.mode"], int)
    assert rows[0]["plant.x1_0"] == -10.0 and isinstance(rows[0]["plant.x1_0"], float)
    import pyarrow.parquet as pq

    schema = pq.read_schema(tmp_path / "runs.parquet")
    assert str(schema.field("controller.mode").type) == "int64"
    assert str(schema.field("plant.x1_0").type) == "double"


def test_cells_and_summary_count_each_outcome() -> None:
    rows = [
        {"plant.x1_0": 0.0, "plant.x2_0": 0.0, "status": "ok", "settling_time": 0.04, "peak_v": 10.0},
        {"plant.x1_0": 1.0, "plant.x2_0": 0.0, "status": "ok", "settling_time": 0.08, "peak_v": 30.0},
        {"plant.x1_0": 2.0, "plant.x2_0": 0.0, "status": "ok", "settling_time": math.inf, "peak_v": 20.0},
        {"plant.x1_0": 3.0, "plant.x2_0": 0.0, "status": "failed", "settling_time": None, "peak_v": 1e7,
         "time_reached": 0.0},
    ]
    cells = cells_from_rows(rows)
    assert [c.outcome for c in cells] == ["settled", "settled", "never", "diverged"]
    s = summarize(cells)
    assert (s.runs, s.diverged, s.never) == (4, 1, 1)
    assert (s.settling_median, s.settling_max) == (pytest.approx(0.06), 0.08)
    assert (s.peak_v_median, s.peak_v_max) == (25.0, 1e7)  # the diverged state keeps its peak


def test_table_shows_the_bound_and_where_it_is_exceeded() -> None:
    bound = fixed_time_bound(EXAMPLE1.controller, 1.0, 1.0, phi=0.5)
    slow = [Cell(0.0, 0.0, "settled", 13.0, 5.0, 20.0)]
    fast = [Cell(0.0, 0.0, "settled", 0.05, 5.0, 2.0)]
    text = study_table({(1, "fixed-time", "a"): slow, (1, "fixed-time", "b"): fast,
                        (1, "finite-time", "a"): fast}, {1: bound})
    lines = text.splitlines()
    assert "| 12 | **no**: 13 s, 1 of 1 settled |" in lines[2]
    assert "| 12 | yes, 1 of 1 settled |" in lines[3]
    assert "(settled runs only)" in lines[0]
    # issue 37: a row where most runs diverge says how few runs the verdict covers
    mostly_diverged = fast + [Cell(1.0, 0.0, "diverged", math.inf, 1e7, 0.0)] * 3
    row = study_table({(1, "fixed-time", "c"): mostly_diverged}, {1: bound}).splitlines()[2]
    assert row.endswith("| yes, 1 of 4 settled | - |")  # no cap shares: no cap column value
    assert "none (k = 0)" in lines[4]
    # issue 45: the cap column, the mean over the row's runs per step, and a row whose v was the
    # cap at every sample of every run says that the paper's law never acted
    capped = [Cell(0.0, 0.0, "settled", 0.05, 5.0, 2.0, caps=(0.5, 1.0)),
              Cell(1.0, 0.0, "settled", 0.05, 5.0, 2.0, caps=(0.25, 1.0))]
    row = study_table({(1, "fixed-time", "d"): capped}, {1: bound}).splitlines()[2]
    assert row.endswith("| 0.375 / 1 (v = the cap at every sample: the paper's law never acted) |")
    limited = [Cell(0.0, 0.0, "settled", 0.05, 5.0, 2.0, caps=(math.nan, math.nan), limit=0.1),
               Cell(1.0, 0.0, "settled", 0.05, 5.0, 2.0, caps=(math.nan, math.nan), limit=0.3)]
    row = study_table({(1, "fixed-time", "e"): limited}, {1: bound}).splitlines()[2]
    assert row.endswith("| limit abs(v) > u_max: 0.2 |")


def test_colour_scale_has_no_impossible_values() -> None:
    """A panel of equal settling times gets a range from 0 to them, never below 0; a log scale takes
    only the positive finite values, widened around a single one."""
    def limits(values: list[float], log: bool) -> tuple[float, float]:
        norm = colour_norm(values, log)
        return norm.vmin, norm.vmax

    assert limits([0.05, 0.05, math.inf], log=False) == (0.0, 0.05)
    assert limits([0.0, 0.0], log=False) == (0.0, 1.0)
    assert limits([-2.0, -2.0], log=False) == (-2.0, 0.0)
    assert limits([2.0, 2.0], log=True) == (1.0, 4.0)
    assert limits([0.0, 10.0, 1e7, math.inf, math.nan], log=True) == (10.0, 1e7)


def test_each_map_panel_has_its_own_colour_scale(tmp_path) -> None:
    """Issue 37: panels of 0.04-0.1 s beside one of 0.5-2 s each span their own colour map, one
    colour bar per panel (main: one shared power-law bar, the fast panel all one dark blue); a
    panel of peaks gets a log scale over its own values."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    fast = [Cell(x, y, "settled", 0.04 + 0.02 * (x + y), 1.0, 2.0) for x in range(4) for y in range(4)]
    slow = [Cell(x, y, "settled", 0.5 + 0.25 * (x + y), 1e3 * 10**x, 2.0) for x in range(4) for y in range(4)]
    b = [Cell(x, y, "diverged" if x else "never", math.inf, 1.0, 0.0) for x in (0.0, 1.0) for y in (0.0, 1.0)]
    created = []
    original = plt.Figure.colorbar

    def spy(self, mappable, *args, **kwargs):  # type: ignore[no-untyped-def]
        created.append(mappable.norm)
        return original(self, mappable, *args, **kwargs)

    plt.Figure.colorbar = spy  # type: ignore[method-assign]
    try:
        draw_maps([("fast", fast), ("slow", slow), ("b", b)], "settling", "s", tmp_path / "m.png")
        draw_maps([("slow", slow)], "peak_v", "peak", tmp_path / "p.png", log=True)
    finally:
        plt.Figure.colorbar = original  # type: ignore[method-assign]
    assert len(created) == 4
    assert (created[0].vmin, created[0].vmax) == (pytest.approx(0.04), pytest.approx(0.16))
    assert (created[1].vmin, created[1].vmax) == (pytest.approx(0.5), pytest.approx(2.0))
    assert type(created[3]).__name__ == "LogNorm" and (created[3].vmin, created[3].vmax) == (1e3, 1e6)
    assert (tmp_path / "m.png").stat().st_size > 0


def _cap_oracle(x1: float, x2: float, k: float, q: float, bh: float) -> bool:
    """The cap of SPEC's semi-implicit law written out for t = 0 (yd = 0, eta_hat = 0, so the RBF
    term vanishes; alpha = 1.5, beta = 0.75): step i binds iff phi(|z_i|) = k|z_i|^2 + q|z_i|^0.5
    exceeds |z_i| / (b_max h); zeta_1 is the capped or the paper's value, z_2 = x2 - zeta_1."""
    z1 = x1
    phi1, cap1 = k * z1 * z1 + q * abs(z1) ** 0.5, abs(z1) / bh
    zeta1 = -math.copysign(min(phi1, cap1), z1) if z1 else 0.0
    z2 = x2 - zeta1
    phi2, cap2 = k * z2 * z2 + q * abs(z2) ** 0.5, abs(z2) / bh
    return (z1 != 0.0 and phi1 > cap1) or (z2 != 0.0 and phi2 > cap2)


def test_the_cap_region_follows_the_definition() -> None:
    """Example 1 (k = 10, q = 8, b_max = 3, h = 1 ms) and the pendulum (k = 25, q = 20, b_max = 1,
    h = 0.5 ms) at t = 0 over a grid that crosses the region's edges, fixed-time law; the
    finite-time law (k = 0) against the same formula with k = 0."""
    values = [-40.0, -10.0, -1.0, -0.01, 0.0, 0.3, 2.0, 30.0, 34.0]
    for example, k, q, bh in ((EXAMPLE1, 10.0, 8.0, 3e-3), (EXAMPLE2, 25.0, 20.0, 5e-4)):
        for x1 in values:  # yd(0) = 0 in both examples (0.5 sin 0, sin(0.5 * 0)): z1 = x1
            for x2 in values:
                assert cap_binds(example, 0, x1, x2) == _cap_oracle(x1, x2, k, q, bh), (x1, x2)
                assert cap_binds(example, 1, x1, x2) == _cap_oracle(x1, x2, 0.0, q, bh), (x1, x2)
    assert not cap_binds(EXAMPLE1, 0, 0.0, 0.0)


def test_campaign_heat_maps_share_one_scale_and_name_failures_below(tmp_path) -> None:
    """``campaign-report`` on a table of two facets with different ranges: one colour bar for the
    figure spanning both, from 0; the failed and the never-settled cells in the legend below."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from orchestrator.campaign.report import write_report

    columns = ["run", "run_id", "scenario", "plant.x1_0", "controller.mode", "status", "reason",
               "settling_time"]
    plot = {"kind": "heatmap", "x": "plant.x1_0", "y": "controller.mode", "metric": "settling_time",
            "facet": "controller.mode"}
    meta = {"plots": [plot], "metrics": ["settling_time"], "columns": columns[3:5]}
    journal = Journal(tmp_path, columns, meta)
    journal.start([])
    values = [(0, 0.0, 0, "ok", 0.05), (1, 1.0, 0, "ok", 0.05), (2, 0.0, 1, "ok", 1.5),
              (3, 1.0, 1, "failed", None), (4, 2.0, 1, "ok", math.inf), (5, 2.0, 0, "ok", 0.05)]
    for run, x, mode, status, settling in values:
        journal.append({"run": run, "run_id": str(run), "scenario": "s", "plant.x1_0": x,
                        "controller.mode": mode, "status": status, "reason": "", "settling_time": settling})
    journal.finish()
    bars, legends = [], []
    colorbar, legend = plt.Figure.colorbar, plt.Figure.legend

    def spy_bar(self, mappable, *args, **kwargs):  # type: ignore[no-untyped-def]
        bars.append(mappable.norm)
        return colorbar(self, mappable, *args, **kwargs)

    def spy_legend(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        legends.append([h.get_label() for h in kwargs["handles"]])
        return legend(self, *args, **kwargs)

    plt.Figure.colorbar, plt.Figure.legend = spy_bar, spy_legend  # type: ignore[method-assign]
    try:
        write_report(tmp_path / "runs.parquet", tmp_path / "report")
    finally:
        plt.Figure.colorbar, plt.Figure.legend = colorbar, legend  # type: ignore[method-assign]
    assert len(bars) == 1 and (bars[0].vmin, bars[0].vmax) == (0.0, 1.5)
    assert legends == [["failed (x): 1", "settling_time infinite (o): 1"]]


def test_a_subgrid_keeps_the_designs_runs_on_every_other_state() -> None:
    """--states 11 on the shipped 21 x 21 design: the states -10, -8, ..., 10 on both axes, each with
    all four (law, sampling) variants, and nothing else; 21 keeps the design."""
    from orchestrator.campaign import read_design
    from orchestrator.experiments.fixed_time_study import STUDY_DESIGN, on_grid

    design = read_design(STUDY_DESIGN)
    sub = on_grid(design, 11)
    i, j = design.columns.index("plant.x1_0"), design.columns.index("plant.x2_0")
    assert len(design) == 21 * 21 * 4 and len(sub) == 11 * 11 * 4
    assert {p[i] for p in sub.points} == {p[j] for p in sub.points} == {float(v) for v in range(-10, 11, 2)}
    assert set(sub.points) <= set(design.points)
    assert on_grid(design, 21) == design


def test_integer_values_of_a_design_reach_the_table_as_integers(tmp_path) -> None:
    """The journal test above wrote ints by hand; the design itself made every value a float, so
    the study's table said controller.mode = 0.0 (issue 24, item 4)."""
    design = tmp_path / "d.toml"
    design.write_text('[grid]\n"controller.mode" = [0, 1]\n"plant.x1_0" = [-1, 0.5]\n')
    points = read_design(design).points
    assert [type(p[0]) for p in points] == [int, int, int, int]
    assert [p[1] for p in points] == [-1, 0.5, -1, 0.5]


def test_a_campaign_row_keeps_an_integer_parameter_an_integer() -> None:
    """The sweep wrote float(value) for every varied parameter (controller.mode = 0.0 in the
    study's runs.csv, measured on the 21 x 21 run)."""
    from orchestrator.campaign.sweep import _row
    from orchestrator.campaign.worker import RunOutcome, RunSpec

    spec = RunSpec(0, "a", "s", "d", {"controller.mode": 1, "plant.x1_0": -10}, 2.0, 0.001)
    row = _row(spec, RunOutcome(0, "ok", "", 0.1), ["controller.mode", "plant.x1_0"])
    assert row["controller.mode"] == 1 and isinstance(row["controller.mode"], int)
