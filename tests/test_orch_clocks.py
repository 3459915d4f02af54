# SPDX-License-Identifier: BSD-2-Clause
"""FMI 3.0 clocks driven by both masters: a periodic input clock ticked on schedule, in event mode.

The FMU is ``Sampler`` (tests/clocked_fmu.py, C, compiled here): its clocked output ``y`` is its
input ``u`` sampled at every tick of its input clock (interval T = 0.1 s), ``ticks`` counts the
ticks, and ``y_grid`` is the unclocked sample-and-hold an FMI 2.0 FMU with a sample time makes: at
the first communication point at or after each k T. With u(t) = t (an input file), the oracles
are analytic: ``y(t) = T floor(t / T)`` and ``ticks(t) = floor(t / T) + 1`` (a tick at t0), and the
unclocked sampler samples u at ``h ceil(k T / h)`` on the master's grid of step h. The second
oracle is fmusim (the Modelica Reference FMUs' importer) running the same FMU with
``--event-mode-used``, the clock activated from its CSV input at each tick.

The case the issue asks to see: h = 0.03 s does not divide T. The clocked FMU samples at 0.1,
0.2, ... exactly (the master cuts its step at each tick); the unclocked one at 0.12, 0.21, 0.3,
0.42, ... (wrong by up to h).
"""

from __future__ import annotations

import csv
import math
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from clocked_fmu import FEEDTHROUGH, INTERVAL, SHARED, build_sampler, scenario
from fmpy import read_model_description
from fmpy.util import read_csv

import orchestrator
from orchestrator import RunOptions
from orchestrator.clocks import InputClock, due, input_clocks, next_tick
from orchestrator.export import export

HERE = Path(__file__).resolve().parent
FMUSIM = SHARED / "tools" / "fmusim" / "bin" / "fmusim"
STEP = 0.03  # does not divide T = 0.1
pytestmark = [pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler"),
              pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning"),
              pytest.mark.filterwarnings("ignore::orchestrator.EngineNote")]

@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The clocked Sampler and its unclocked twin (the same C code, no clock declared)."""
    folder = tmp_path_factory.mktemp("sampler")
    return {"clocked": build_sampler(folder / "clocked"),
            "unclocked": build_sampler(folder / "plain", clocked=False)}


def run(folder: Path, ramp: Path, **options: object) -> np.ndarray:
    options.setdefault("step", STEP)
    return orchestrator.run(folder, RunOptions(input_file=ramp, **options)).rows  # type: ignore[arg-type]


def assert_array_equal_rows(mine: np.ndarray, theirs: np.ndarray) -> None:
    assert mine.dtype.names == theirs.dtype.names and len(mine) == len(theirs)
    for column in theirs.dtype.names or ():
        np.testing.assert_array_equal(mine[column], theirs[column], err_msg=column)


def sampled_at_ticks(t: np.ndarray) -> np.ndarray:
    """u(t) = t sampled at the ticks k T and held: T floor(t / T) (to a nanosecond, as the grid)."""
    return np.array([INTERVAL * math.floor(round(x / INTERVAL, 9)) for x in t])


def sampled_on_grid(t: np.ndarray) -> np.ndarray:
    """What the unclocked sampler holds at each row of the grid ``t``: u (= time) at the first grid
    point at or after each k T, taken in the step that starts there, so seen from the next row."""
    points = {min(s for s in t if s >= k * INTERVAL - 1e-12) for k in range(int(t[-1] / INTERVAL) + 1)}
    return np.array([max((p for p in points if p < x - 1e-12), default=0.0) for x in t])


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_clocked_fmu_samples_at_the_ticks_when_the_step_does_not_divide_the_interval(
        fmus: dict[str, Path], tmp_path: Path, master: str) -> None:
    rows = run(*scenario(tmp_path / "s", fmus["clocked"]), master=master)
    t = rows["time"]
    assert len(t) == round(0.99 / STEP) + 1  # rows on the master's grid only
    np.testing.assert_allclose(rows["s.y"], sampled_at_ticks(t), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rows["s.ticks"], [math.floor(round(x / INTERVAL, 9)) + 1 for x in t])


def test_unclocked_sampler_on_the_masters_grid_samples_at_the_wrong_instants(
        fmus: dict[str, Path], tmp_path: Path) -> None:
    """The same C code without the clock, on the grid of 0.03 s: it samples u at 0.12, 0.21, 0.3,
    0.42 ... (analytic: the first grid point at or after each k T), off the ticks by up to 0.02 s."""
    rows = run(*scenario(tmp_path / "plain", fmus["unclocked"], clocked=False))
    t = rows["time"]
    np.testing.assert_allclose(rows["s.y_grid"], sampled_on_grid(t), rtol=0, atol=1e-12)
    clocked = run(*scenario(tmp_path / "clocked", fmus["clocked"]))
    error = np.abs(rows["s.y_grid"] - clocked["s.y"])
    assert error.max() == pytest.approx(INTERVAL, abs=1e-12)  # at 0.12 it still holds u(0), not u(0.1)


def test_where_the_grids_coincide_the_clocked_run_equals_the_unclocked_one(fmus: dict[str, Path],
                                                                          tmp_path: Path) -> None:
    """Step 0.02 s divides T: no step is cut, the unclocked output of the clocked run equals the
    unclocked twin's bit for bit, and the clocked y equals it one row earlier (the event samples u
    at the tick itself; the unclocked sampler in the step that starts there)."""
    clocked = run(*scenario(tmp_path / "c", fmus["clocked"], stop=1.0), step=0.02)
    plain = run(*scenario(tmp_path / "p", fmus["unclocked"], clocked=False, stop=1.0), step=0.02)
    np.testing.assert_array_equal(clocked["s.y_grid"], plain["s.y_grid"])
    np.testing.assert_array_equal(clocked["s.y"][:-1], plain["s.y_grid"][1:])


@pytest.mark.skipif(not FMUSIM.is_file(), reason="no fmusim")
def test_agrees_with_fmusim_in_event_mode(fmus: dict[str, Path], tmp_path: Path) -> None:
    """fmusim activates the clock from a CSV column (1 at each tick; it cannot tick at t0, where
    u = 0 = y anyway) and steps from tick to tick; at every row of orchestrate's run on the grid of
    0.03 s, y equals fmusim's y after the last tick at or before it."""
    ticks = [round(k * INTERVAL, 10) for k in range(1, 10)]
    with (tmp_path / "in.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time", "u", "tick"])
        writer.writerow([0.0, 0.0, 0])
        for x in ticks:
            writer.writerows([[x, x, 0], [x, x, 1]])
    subprocess.run([str(FMUSIM), "--interface-type", "cs", "--event-mode-used", "--stop-time", "0.9",
                    "--output-interval", str(INTERVAL), "--input-file", str(tmp_path / "in.csv"),
                    "--output-file", str(tmp_path / "out.csv"), str(fmus["clocked"])], check=True, timeout=60)
    theirs = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    after_tick = {round(float(r["time"]), 9): float(r["y"]) for r in theirs}  # the row after the event wins
    assert [after_tick[x] for x in ticks] == pytest.approx(ticks, abs=1e-15)
    rows = run(*scenario(tmp_path / "s", fmus["clocked"]))
    for x, y in zip(rows["time"], rows["s.y"], strict=True):
        last = max((k for k in after_tick if k <= x + 1e-12), default=0.0)
        assert y == pytest.approx(after_tick[last], abs=1e-12), x


@pytest.mark.skipif(not FEEDTHROUGH.is_file(), reason="no Modelica Reference FMUs (FMI 3.0)")
def test_clocked_output_is_passed_on_at_the_tick(fmus: dict[str, Path], tmp_path: Path) -> None:
    """s.y -> Reference Feedthrough: under gauss-seidel f's output equals y at every row (the value
    set after the tick reaches f at the tick); under jacobi it is y at the start of the step that
    ends at the row, which is the tick where a tick cut the step (0.12: y(0.1) = 0.1)."""
    folder, ramp = scenario(tmp_path / "s", fmus["clocked"], feed=True)
    rows = run(folder, ramp, executor="python")
    assert_array_equal_rows(run(folder, ramp, executor="compiled"), rows)
    np.testing.assert_array_equal(rows["f.Float64_continuous_output"], rows["s.y"])
    jacobi = run(folder, ramp, master="jacobi", executor="python")
    assert_array_equal_rows(run(folder, ramp, master="jacobi", executor="compiled"), jacobi)
    t = jacobi["time"][1:]
    starts = np.maximum(t - STEP, INTERVAL * np.floor(np.round((t - 1e-9) / INTERVAL, 9)))  # a cut step's
    np.testing.assert_allclose(jacobi["f.Float64_continuous_output"][1:], sampled_at_ticks(starts),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("step", [STEP, 0.02, 0.045])
def test_the_compiled_executor_ticks_as_the_python_master(fmus: dict[str, Path], tmp_path: Path, master: str,
                                                          step: float) -> None:
    """The compiled executor (orchestrator/native/core.c) cuts the steps at the ticks and makes the
    events itself: every row equals the Python master's bit for bit, where the step divides T
    (0.02 s) and where it does not (0.03, 0.045 s: the input file is read at every cut), and the
    oracle still holds (y = T floor(t / T))."""
    folder, ramp = scenario(tmp_path / "s", fmus["clocked"], stop=0.9)
    python = run(folder, ramp, step=step, master=master, executor="python")
    compiled = run(folder, ramp, step=step, master=master, executor="compiled")
    assert len(python) == round(0.9 / step) + 1
    assert_array_equal_rows(compiled, python)
    np.testing.assert_allclose(compiled["s.y"], sampled_at_ticks(compiled["time"]), rtol=0, atol=1e-12)


def test_reference_clocks_model_is_refused_in_one_line() -> None:
    """The Reference FMUs' Clocks (Scheduled Execution only, a third-party file): one line."""
    md = read_model_description(str(HERE / "reference_clocks" / "modelDescription.xml"), validate=False)
    clocks, problems = input_clocks("x.ssd: component 'c'", md)
    assert clocks == [] and problems == [
        "x.ssd: component 'c': the FMU has clocks (inClock1, inClock2, inClock3, outClock) but its "
        "Co-Simulation interface has no event mode (hasEventMode): Scheduled Execution is not supported"]


def test_unsupported_clocks_are_refused_one_line_each(fmus: dict[str, Path]) -> None:
    """The Clocks model's variables as if it offered Co-Simulation with event mode: its triggered and
    countdown input clocks and its output clock are each refused, naming the clock."""
    xml = HERE / "reference_clocks" / "modelDescription.xml"
    md = read_model_description(str(xml), validate=False)
    md.coSimulation = read_model_description(str(fmus["clocked"]), validate=False).coSimulation
    clocks, problems = input_clocks("x.ssd: component 'c'", md, fmu=xml)
    assert [(c.name, c.vr, c.interval_ns) for c in clocks] == [("inClock1", 1001, 1_000_000_000)]
    assert [re.search(r"'(\w+)'", p.split(": ", 2)[2]).group(1) for p in problems] == [  # type: ignore[union-attr]
        "inClock2", "inClock3", "outClock"]
    assert all("\n" not in p for p in problems)


def test_ticks_with_a_shift_are_counted_in_nanoseconds() -> None:
    """FMI 3.0: a periodic clock ticks at t0 + shift + k interval; the next tick strictly after a
    time, and the clocks due at a time, in integer nanoseconds (t0 = 1 s, interval 0.3 s, shift 0.1 s:
    1.1, 1.4, 1.7 s ...)."""
    a = InputClock("a", 1, 300_000_000, 100_000_000)
    b = InputClock("b", 2, 200_000_000)
    t0 = 1_000_000_000
    assert [a.tick_at_or_after(t, t0) for t in (0, 1_100_000_000, 1_100_000_001, 1_400_000_000)] == [
        1_100_000_000, 1_100_000_000, 1_400_000_000, 1_400_000_000]
    assert next_tick([a, b], 1_000_000_000, t0) == 1_100_000_000
    assert next_tick([a, b], 1_100_000_000, t0) == 1_200_000_000
    assert next_tick([], 0, t0) is None
    assert [c.name for c in due([a, b], 1_400_000_000, t0)] == ["a", "b"]
    assert [c.name for c in due([a, b], 1_200_000_000, t0)] == ["b"]


def held_from_the_host(t: float, h: float) -> float:
    """y of the exported Sampler at time ``t`` on a host stepping by ``h``, u(t) = t set by the
    host at each of its communication points: the tick k T, inside or at the end of a host step,
    samples the u the host set at that step's start, h (ceil(k T / h) - 1) (0 for k = 0)."""
    k = math.floor(round(t / INTERVAL, 9))
    return 0.0 if k == 0 else h * (math.ceil(round(k * INTERVAL / h, 9)) - 1)


@pytest.mark.parametrize("fixed", [False, True], ids=["interval given", "interval asked"])
@pytest.mark.parametrize("fmi", ["2", "3"])
def test_the_exported_container_ticks_the_clock_behind_plain_co_simulation(
        fmus: dict[str, Path], tmp_path: Path, fmi: str, fixed: bool) -> None:
    """``orchestrate export`` of the clocked Sampler at the step 0.03 s (T = 0.1 s): the container
    cuts its steps at the ticks and makes the events itself, its own interface is plain
    Co-Simulation (no clock, no event mode). FMPy and fmusim, stepping 0.03 s and setting u(t) = t
    at their communication points, see every tick (ticks = floor(t / T) + 1) and y sampled at it
    from the u of the step it falls in (analytic: held_from_the_host). ``fixed``: the clock's
    interval is not in the model description, and the container asks it in Initialization Mode
    itself (core_ask_clocks; the compiled executor is handed the interval Python asked)."""
    sampler = build_sampler(tmp_path / "fixed", fixed=True) if fixed else fmus["clocked"]
    folder, _ = scenario(tmp_path / "s", sampler)
    fmu, _ = export(folder, tmp_path / "out.fmu", step=STEP, stop_time=0.99, fmi=fmi)
    md = zipfile.ZipFile(fmu).read("modelDescription.xml").decode()
    assert "<Clock" not in md and 'hasEventMode="true"' not in md and "clocks=" not in md
    signal = np.array([(0.0, 0.0), (10.0, 10.0)], dtype=[("time", float), ("s.u", float)])
    got = {"fmpy": fmpy.simulate_fmu(str(fmu), stop_time=0.99, step_size=STEP, output_interval=STEP,
                                     input=signal)}
    if FMUSIM.is_file():
        (tmp_path / "u.csv").write_text("time,s.u\n0,0\n10,10\n")
        subprocess.run([str(FMUSIM), "--interface-type", "cs", "--stop-time", "0.99", "--output-interval",
                        str(STEP), "--input-file", str(tmp_path / "u.csv"), "--output-file",
                        str(tmp_path / "out.csv"), str(fmu)], check=True, timeout=60, capture_output=True)
        got["fmusim"] = read_csv(str(tmp_path / "out.csv"))
    for host, rows in got.items():
        t = rows["time"]
        assert len(t) == 34, host
        np.testing.assert_array_equal(rows["s.ticks"], [math.floor(round(x / INTERVAL, 9)) + 1 for x in t],
                                      err_msg=host)
        np.testing.assert_allclose(rows["s.y"], [held_from_the_host(x, STEP) for x in t], rtol=0, atol=1e-12,
                                   err_msg=host)


@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
def test_two_clocks_of_different_intervals_each_tick_on_their_own_schedule(
        fmus: dict[str, Path], tmp_path: Path, master: str) -> None:
    """A second Sampler with T = 0.15 s beside the first (0.1 s), step 0.04 s: the step is cut at
    the ticks of both, each samples at its own k T (0.15 s: 0.15, 0.3, 0.45 ...), and a tick of one
    is no tick of the other (their counts stay floor(t / T) + 1)."""
    other = build_sampler(tmp_path / "slow", interval=0.15)
    folder, ramp = scenario(tmp_path / "s", fmus["clocked"], stop=1.0)
    shutil.copy(other, folder / "resources" / "Slow.fmu")
    text = (folder / "SystemStructure.ssd").read_text()
    end = "</ssd:Component>"
    first = text[text.index('      <ssd:Component name="s"'):text.index(end) + len(end)]
    second = first.replace('name="s"', 'name="r"').replace("resources/Sampler.fmu", "resources/Slow.fmu")
    (folder / "SystemStructure.ssd").write_text(text.replace(first, first + "\n" + second))
    ramp.write_text("time,s.u,r.u\n0,0,0\n10,10,10\n")
    rows = run(folder, ramp, step=0.04, master=master, executor="python")
    assert_array_equal_rows(run(folder, ramp, step=0.04, master=master, executor="compiled"), rows)
    t = rows["time"]
    for name, interval in (("s", 0.1), ("r", 0.15)):
        k = np.floor(np.round(t / interval, 9))
        np.testing.assert_allclose(rows[f"{name}.y"], interval * k, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(rows[f"{name}.ticks"], k + 1)


@pytest.mark.parametrize("interval", [0.1, 0.05])
def test_a_fixed_clock_without_interval_is_asked_in_initialization_mode(tmp_path: Path,
                                                                        interval: float) -> None:
    """A ``fixed`` clock whose model description gives no intervalDecimal (its interval depends on
    parameters): the master asks fmi3GetIntervalDecimal and fmi3GetShiftDecimal in Initialization
    Mode (FMI 3.0, 2.2.8) and ticks on what the FMU answers, here the interval compiled into its
    C code: with u(t) = t, y(t) = interval floor(t / interval) at every row of the 0.03 s grid."""
    fmu = build_sampler(tmp_path / "fixed", interval=interval, fixed=True)
    assert 'intervalVariability="fixed"' in zipfile.ZipFile(fmu).read("modelDescription.xml").decode()
    rows = run(*scenario(tmp_path / "s", fmu))
    # the compiled executor ticks on the interval Python asked (the container asks it itself:
    # test_the_exported_container_ticks_the_clock_behind_plain_co_simulation)
    assert_array_equal_rows(run(*scenario(tmp_path / "c", fmu), executor="compiled"), rows)
    t = rows["time"]
    expected = [interval * math.floor(round(x / interval, 9)) for x in t]
    np.testing.assert_allclose(rows["s.y"], expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rows["s.ticks"], [math.floor(round(x / interval, 9)) + 1 for x in t])


def cut_points(step: float, stop: float) -> list[float]:
    """The points a master stops at: its grid and the ticks k T, in integer nanoseconds as its own."""
    ns = 1_000_000_000
    grid = range(0, round(stop * ns) + 1, round(step * ns))
    ticks = range(0, round(stop * ns) + 1, round(INTERVAL * ns))
    return [c / ns for c in sorted({*grid, *ticks})]


@pytest.mark.skipif(not FEEDTHROUGH.is_file(), reason="no Modelica Reference FMUs (FMI 3.0)")
@pytest.mark.parametrize("master", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("step", [0.02, STEP])
def test_under_jacobi_an_event_sees_the_inputs_of_the_previous_communication_point(
        fmus: dict[str, Path], tmp_path: Path, master: str, step: float) -> None:
    """f (Reference Feedthrough, u(t) = t from the input file) -> s.u. Jacobi: every FMU computes
    what it gives at a communication point from the inputs of the previous one, and the event at
    a tick is how s computes its y there; so f gives at each point c_i the u it held since
    c_(i-1), and s samples at a tick c_i the value transferred at c_(i-1): y(c_i) = c_(i-2), on the
    points of the master's grid and the ticks. Gauss-Seidel: y(k T) = k T (propagated at the
    tick). Both executors, bit for bit."""
    folder, ramp = scenario(tmp_path / "s", fmus["clocked"], stop=0.9, fed=True)
    rows = run(folder, ramp, step=step, master=master, executor="python")
    assert_array_equal_rows(run(folder, ramp, step=step, master=master, executor="compiled"), rows)
    cuts = cut_points(step, 0.9)
    sampled = {c: (cuts[max(i - 2, 0)] if master == "jacobi" else c) for i, c in enumerate(cuts)
               if math.isclose(c / INTERVAL, round(c / INTERVAL), abs_tol=1e-9)}
    for t, y in zip(rows["time"], rows["s.y"], strict=True):
        last = max(k for k in sampled if k <= t + 1e-12)
        assert y == pytest.approx(sampled[last], abs=1e-12), (t, y, sampled[last])


@pytest.mark.parametrize("fault, said", [(1, "discreteStatesNeedUpdate after 100 calls"),
                                         (2, "terminateSimulation")])
def test_an_event_that_never_settles_or_asks_to_terminate_ends_the_run_in_one_line(
        tmp_path: Path, fault: int, said: str) -> None:
    """From the 4th tick (t = 0.3 s) the Sampler's fmi3UpdateDiscreteStates asks for another update
    forever, or to terminate: both executors end the run with the same SimulationError naming the
    component, the call, the verdict and the time, the rows before it kept (up to 0.27 s)."""
    fmu = build_sampler(tmp_path / "bad", fault=fault)
    errors = {}
    for executor in ("python", "compiled"):
        folder, ramp = scenario(tmp_path / executor, fmu)
        with pytest.raises(orchestrator.SimulationError) as caught:
            run(folder, ramp, executor=executor)
        errors[executor] = caught.value
    assert str(errors["compiled"]) == str(errors["python"])
    assert f"s: fmi3UpdateDiscreteStates returned {said} at t=0.3" in str(errors["python"])
    assert errors["compiled"].rows == errors["python"].rows == 10  # t0 .. 0.27 s
