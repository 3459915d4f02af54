# SPDX-License-Identifier: BSD-2-Clause
"""Unit tests of the conformance matrix's logic (orchestrate crosscheck) on hand-made signals: the
alignment and difference of two results, each check of a cell and when a cell is red, the
result-file helpers of the adapters, and the written matrix. The tools themselves run in
tests/test_crosscheck_system.py."""

from __future__ import annotations

import csv
import math
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.crosscheck import TOOLS, Scenario, ToolRun, select_tools
from orchestrator.crosscheck.ecos import EcosCliTool, EcospyTool, parameter_set_name
from orchestrator.crosscheck.libcosim import LibcosimTool
from orchestrator.crosscheck.matrix import (
    AFTER,
    Cell,
    deviation,
    evaluate,
    parameter_check,
    reference_master,
    write_csv,
    write_markdown,
)
from orchestrator.crosscheck.omsimulator import OMSimulatorCliTool
from orchestrator.crosscheck.tools import clean_environment, elf_interpreter, last_per_step
from orchestrator.results import structured

H = 1e-3
STOP = 3.0
PARAMETERS = {"plant.x1_0": 0.5, "plant.x2_0": -0.25, "controller.k1": 10.0, "controller.mode": 1}


def scenario(set_names: dict[str, tuple[str, ...]] | None = None) -> Scenario:
    """A scenario as an archive would state it (nothing is read: only the matrix logic runs)."""
    return Scenario("made_up", Path("made_up.ssp"), "made_up", 0.0, STOP, H,
                    ("plant.y", "plant.x1", "plant.x2"), dict(PARAMETERS),
                    {k: "Integer" if k.endswith("mode") else "Real" for k in PARAMETERS},
                    set_names or {"controller": ("controller",), "plant": ("plant",)})


def signals(stop: float = STOP, dy: float = 0.0, t_bump: float | None = None, bump: float = 0.0,
            times: np.ndarray | None = None) -> np.ndarray:
    """plant.y = sin(t) + dy (+ bump at t_bump) on the grid; x1, x2 start at the initial state."""
    t = np.arange(int(round(stop / H)) + 1) * H if times is None else times
    y = np.sin(t) + dy
    if t_bump is not None:
        y[np.argmin(np.abs(t - t_bump))] += bump
    x1 = np.full_like(t, PARAMETERS["plant.x1_0"])
    x2 = np.full_like(t, PARAMETERS["plant.x2_0"])
    return structured(np.column_stack([t, y, x1, x2]), ["time", "plant.y", "plant.x1", "plant.x2"])


def good_run(result: np.ndarray | None = None, **overrides: object) -> ToolRun:
    read_back = {k: float(v) for k, v in PARAMETERS.items()}
    run = ToolRun(signals() if result is None else result, 1.5, None, read_back)
    for key, value in overrides.items():
        setattr(run, key, value)
    return run


def failed(cell: Cell) -> set[str]:
    return {c.name for c in cell.checks if not c.ok}


# -- deviation ----------------------------------------------------------------------------------------

def test_deviation_finds_the_largest_difference_in_and_after_the_first_second() -> None:
    ours = signals()
    theirs = signals(dy=2e-4, t_bump=0.25, bump=0.05)
    d = deviation(theirs, ours, 0.0, H)
    assert d.max == pytest.approx(0.05 + 2e-4, rel=1e-12)
    assert d.at == pytest.approx(0.25)
    assert d.until == d.max
    assert d.after == pytest.approx(2e-4, rel=1e-9)
    late = deviation(signals(t_bump=2.5, bump=0.01), ours, 0.0, H)
    assert (late.until, late.after, late.at) == (0.0, pytest.approx(0.01), pytest.approx(2.5))
    assert d.compared == len(ours)


def test_deviation_aligns_accumulated_times_and_rows_written_twice() -> None:
    """Ecos passes t += h (t drifts by ulps); OMSimulator writes each point twice (before and after
    the exchange): the comparison is by communication point, the last row of each kept."""
    ours = signals()
    accumulated = np.cumsum(np.r_[0.0, np.full(len(ours) - 1, H)])
    assert not np.array_equal(accumulated, ours["time"])  # the drift is real
    theirs = signals(times=accumulated)
    assert deviation(theirs, ours, 0.0, H).max < 1e-12

    doubled_t = np.repeat(ours["time"], 2)
    doubled = signals(times=doubled_t)
    doubled["plant.y"][0::2] += 1.0  # the row before the exchange: stale, must be dropped
    keep = last_per_step(doubled["time"], 0.0, H)
    assert len(keep) == len(ours)
    assert deviation(doubled[keep], ours, 0.0, H).max == 0.0


def test_deviation_of_a_run_that_stopped_early_uses_the_common_points() -> None:
    ours = signals()
    theirs = signals(stop=0.5, dy=1e-3)
    d = deviation(theirs, ours, 0.0, H)
    assert d.compared == 501
    assert d.max == d.until == pytest.approx(1e-3)
    assert d.after == 0.0  # nothing after 1 s to compare


def test_a_non_finite_sample_is_an_infinite_difference() -> None:
    theirs = signals()
    theirs["plant.y"][2000] = np.nan
    d = deviation(theirs, signals(), 0.0, H)
    assert d.max == math.inf and d.after == math.inf and d.at == pytest.approx(2.0)
    assert d.until == 0.0


# -- the checks of a cell and the red-cell rule --------------------------------------------------------

def test_a_cell_is_ok_when_every_check_passes() -> None:
    tool = EcosCliTool()
    theirs = signals(dy=0.5 * tool.tolerance.until, t_bump=20.0 * H + 2.0, bump=0.5 * tool.tolerance.after)
    cell = evaluate(tool, scenario(), good_run(theirs), signals())
    assert not cell.red and cell.status == "ok"
    assert [c.name for c in cell.checks] == ["loads", "parameters", "stop time", f"plant.y until {AFTER:g} s",
                                             f"plant.y after {AFTER:g} s"]
    assert cell.reference == "jacobi"


@pytest.mark.parametrize(("run", "expected"), [
    (good_run(signals()[:0]), {"loads"}),
    (good_run(parameters={**{k: float(v) for k, v in PARAMETERS.items()}, "controller.k1": 25.0}),
     {"parameters"}),
    (good_run(parameters={k: float(v) for k, v in PARAMETERS.items() if k != "controller.mode"}),
     {"parameters"}),
    (good_run(signals(stop=STOP - H)), {"stop time"}),
    (good_run(error="plant: fmi2DoStep returned fmi2Discard"), {"stop time"}),
    (good_run(signals(t_bump=0.03, bump=1e-3)), {f"plant.y until {AFTER:g} s"}),
    (good_run(signals(t_bump=2.0, bump=0.1)), {f"plant.y after {AFTER:g} s"}),
])
def test_a_cell_is_red_when_one_check_fails(run: ToolRun, expected: set[str]) -> None:
    cell = evaluate(EcosCliTool(), scenario(), run, signals())
    assert cell.red and cell.status == "red"
    assert failed(cell) == expected


def test_a_tool_that_modifies_the_archive_fails_loads() -> None:
    cell = evaluate(EcosCliTool(), scenario(), good_run(), signals(), unchanged=False)
    assert failed(cell) == {"loads"} and "modified the archive" in cell.checks[0].detail


def test_the_plant_initial_state_must_show_up_at_t0() -> None:
    """Without a read-back (our own masters) the initial state is the evidence: x1(t0) = x1_0."""
    moved = signals()
    moved["plant.x1"][0] = 0.0
    check = parameter_check(scenario(), moved, None)
    assert not check.ok and "plant.x1(t0) = 0 (plant.x1_0 = 0.5)" in check.detail
    assert parameter_check(scenario(), signals(), None).ok


def test_each_tool_is_compared_with_our_master_of_its_semantics() -> None:
    """Delayed tools (libcosim, Ecos) with jacobi, delay-free ones (OMSimulator, the exported FMU,
    which runs gauss-seidel inside) with gauss-seidel."""
    assert {k: reference_master(t.delayed) for k, t in TOOLS.items()} == {
        "libcosim": "jacobi", "ecospy": "jacobi", "ecos": "jacobi", "omsimulator": "gauss-seidel",
        "omsimulator-nopython": "gauss-seidel", "omsimulator-py": "gauss-seidel",
        "export-fmusim": "gauss-seidel", "export-fmucheck": "gauss-seidel", "export-fmpy": "gauss-seidel"}
    assert [t.key for t in select_tools(["ecos", "libcosim"])] == ["libcosim", "ecos"]


def test_a_tool_that_is_not_installed_is_listed_but_not_red(tmp_path: Path) -> None:
    cells = [Cell("omsimulator", "OMSimulator 3 (CLI)", "made_up", False, "gauss-seidel",
                  missing="not installed (/nowhere/bin/OMSimulator not found)"),
             evaluate(LibcosimTool(), scenario(), good_run(signals(dy=1.0)), signals())]
    assert not cells[0].red and cells[0].status == "not installed"
    assert cells[1].red
    md = write_markdown(cells, tmp_path / "matrix.md", [OMSimulatorCliTool(), LibcosimTool()]).read_text()
    assert "not installed" in md and "🟥" in md
    with open(write_csv(cells, tmp_path / "matrix.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["tool"], r["status"]) for r in rows] == [("omsimulator", "not installed"), ("libcosim", "red")]
    assert float(rows[1]["dy_max"]) == pytest.approx(1.0)
    assert rows[1]["reference"] == "jacobi"


# -- adapters' helpers ----------------------------------------------------------------------------------

def test_ecos_gets_the_parameter_set_name_only_when_every_ssv_shares_it() -> None:
    """Ecos applies ONE named parameter set (the .ssv files of that name, over all components)."""
    assert parameter_set_name(scenario({"controller": ("tuned",), "plant": ("tuned",)})) == ("tuned", None)
    name, note = parameter_set_name(scenario())
    assert name is None and "2 different names (controller, plant): none applied" in note


def test_the_c_api_tools_get_no_python_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LD_PRELOAD", "/some/libpython3.11.so")
    monkeypatch.setenv("PYTHONPATH", "/some/site-packages")
    monkeypatch.setenv("PYTHONHOME", "/some")
    env = clean_environment()
    assert not {"LD_PRELOAD", "PYTHONPATH", "PYTHONHOME"} & set(env)
    assert env["PATH"] == os.environ["PATH"]


def test_elf_interpreter_names_the_dynamic_loader() -> None:
    """Read from the ELF header of this interpreter; the oracle is the loader actually mapped into
    this process (/proc/self/maps)."""
    loader = elf_interpreter(Path(sys.executable).resolve())
    mapped = {line.split()[-1] for line in Path("/proc/self/maps").read_text().splitlines()
              if "/ld-linux" in line}
    assert {os.path.realpath(p) for p in mapped} == {os.path.realpath(loader)}
    with pytest.raises(ValueError, match="not a 64-bit ELF"):
        elf_interpreter(Path(__file__))


def test_the_ecos_command_passes_the_archive_step_and_half_a_step_more_stop_time() -> None:
    """ecos steps while t + h <= stop with t accumulated: the exact stop time loses the last step."""
    if EcospyTool().missing():
        pytest.skip(EcospyTool().missing())
    cmd = EcosCliTool().command(scenario())
    assert cmd[cmd.index("--stepSize") + 1] == repr(H)
    assert float(cmd[cmd.index("--stopTime") + 1]) == pytest.approx(STOP + H / 2)
    assert "--parameterSet" not in cmd  # the made-up sets have two names


def test_crosscheck_usage_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["crosscheck", str(tmp_path / "missing_scenario"), "--output", str(tmp_path)])
    assert exc.value.code == 2
    assert "no scenario" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["crosscheck", "--tools", "simulink"])
    assert exc.value.code == 2


class _NeverRun(LibcosimTool):
    """libcosim as the matrix sees it, installed, but failing the test if the matrix runs it."""

    def missing(self) -> str | None:
        return None

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        raise AssertionError("a tool must not be run on FMUs of an FMI version it does not support")


def test_a_tool_without_fmi3_is_not_supported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A scenario with FMI 3.0 components in a tool that runs FMI 2.0 only (libcosim): not run, the
    cell says "not supported", is not red, and the matrix shows the FMI versions of both."""
    from orchestrator.crosscheck import matrix

    archive = tmp_path / "made_up_fmi3.ssp"
    archive.write_bytes(b"not read")
    fmi3 = replace(scenario(), name="made_up_fmi3", path=archive, fmi_versions=("3.0",))
    monkeypatch.setattr(matrix, "_ours", lambda s, master: (signals(), 0.1, None))
    cells = matrix.run_matrix([fmi3], [_NeverRun()])
    assert [c.status for c in cells] == ["ok", "ok", "not supported"]
    assert not cells[2].red and cells[2].unsupported == "runs FMI 2.0 FMUs only, not FMI 3.0"
    md = write_markdown(cells, tmp_path / "matrix.md", [_NeverRun()]).read_text()
    assert "| tool | master | FMI | clocks | `made_up_fmi3` (FMI 3.0) |" in md
    assert "| libcosim 0.11 (libcosimpy) | delayed (= `jacobi`) | 2.0 | no | not supported (FMI 3.0) |" in md
    with open(write_csv(cells, tmp_path / "matrix.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["status"], r["fmi"], r["tool_fmi"]) for r in rows][2] == ("not supported", "3.0", "2.0")


class _NoClocks(LibcosimTool):
    """libcosim's place in the matrix, its run replaced by what a tool without clocks does with a
    clocked archive: ``result`` (no row: it refused the archive)."""

    def __init__(self, result: np.ndarray, error: str | None) -> None:
        self.result, self.error = result, error

    def missing(self) -> str | None:
        return None

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        return ToolRun(self.result, 0.2, self.error, None)


@pytest.mark.parametrize("result, error, status", [
    (signals()[:0], "Unsupported SSP version: '2.0'!", "no clocks"),  # refused the archive
    (signals(dy=1.0), None, "no clocks"),  # ran, sampling on its own grid: another y
    (signals(), None, "ok")])  # gave our rows: nothing to say
def test_a_clocked_scenario_runs_in_a_tool_without_clocks_and_is_no_clocks_not_red(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, result: np.ndarray, error: str | None,
        status: str) -> None:
    """A scenario with FMI 3.0 clocks runs in a tool that drives none, even one whose FMI versions
    it exceeds (measured, not assumed); what the tool does is "no clocks" with the first check it
    failed, never red; our masters drive the clocks and are held to every check. The matrix says
    which tool drives clocks and which scenario has them."""
    from orchestrator.crosscheck import matrix

    archive = tmp_path / "made_up_clocked.ssp"
    archive.write_bytes(b"not read")
    clocked = replace(scenario(), name="made_up_clocked", path=archive, fmi_versions=("2.0", "3.0"),
                      clocked=("controller",))
    monkeypatch.setattr(matrix, "_ours", lambda s, master: (signals(), 0.1, None))
    tool = _NoClocks(result, error)
    cells = matrix.run_matrix([clocked], [tool])
    assert [c.status for c in cells] == ["ok", "ok", status]
    assert not any(c.red for c in cells) and cells[2].clockless and not cells[0].clockless
    md = write_markdown(cells, tmp_path / "matrix.md", [tool]).read_text()
    assert "| `made_up_clocked` (FMI 2.0, 3.0; clocks) |" in md
    assert "| orchestrate run --master jacobi | delayed (= `jacobi`) | 2.0, 3.0 | periodic input clocks" in md
    row = next(line for line in md.splitlines() if line.startswith("| libcosim"))
    assert row.startswith("| libcosim 0.11 (libcosimpy) | delayed (= `jacobi`) | 2.0 | no | ")
    if error:
        assert f"no clocks: loads: {error}" in row
    with open(write_csv(cells, tmp_path / "matrix.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["status"], r["clockless"]) for r in rows] == [("ok", "False"), ("ok", "False"),
                                                             (status, "True")]
