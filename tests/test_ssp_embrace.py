# SPDX-License-Identifier: BSD-2-Clause
"""OMSimulator's Embrace file (four Dymola 2020 FMUs with their own variable-step solvers and one
Simulink FMU) against OMSimulator 3 running the same archive: why the two differed by up to
1.4e-3 at t = 1 s (ECS_HW.consumerFeed.m), and that they agree at every point of the run when the
engine makes OMSimulator's calls.

Three causes, each shown with OMSimulator as the oracle (tests/ssp_conformance/omsimulator/embrace,
OMSimulator's ``testsuite/tests/resources/embrace`` at 2940ef11, unchanged):

* The FMUs' tolerance (fixed here). OMSimulator passes every FMU its system's relative tolerance
  in ``fmi2SetupExperiment`` (``toleranceDefined``; the SSD's ``oms:FixedStepMaster
  relativeTolerance``, 1e-4); the engine passed none, so ECS_HW's solver ran at its own default
  and the first step already differed by 1.9e-4 (``ECS_HW.LHexTout``). Now it passes the file's.
* OMSimulator's result writer reads every variable of every FMU (1105 Real ones here, the state
  derivatives among them) at every communication point. A Dymola FMU evaluates its model on such
  reads, and its solver then takes other steps: without them the values part at t = 2 ms.
* OMSimulator advances its communication time by adding the step (``time = tNext; tNext = time +
  h``), so its points drift from k h (t = 0.010000000000000002 for 10 steps of 1 ms, and
  ``fmi2DoStep`` then gets h = 0.0010000000000000009); this engine steps on the exact grid k h
  (integer nanoseconds, as libcosim). A variable-step solver inside an FMU sees the other time:
  with the reads but our grid the values part at t = 11 ms.

The last two are OMSimulator's choices, not the standard's (FMI lets ``fmi2GetReal`` compute; a
grid that does not drift is this engine's design), and this stiff model (pressure nodes) turns
any such difference into percents within a step. With all three, all 1105 values agree with
OMSimulator's at every one of the 1000 points of the 1 s run.
"""

from __future__ import annotations

import csv
import ctypes
import json
import os
import shutil
import subprocess
import sys
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

import pytest
from ssp_conformance.conformance import HERE, OMSIMULATOR, Case, pack

import orchestrator
from orchestrator.fmi import InstanceBase, MessageLog
from orchestrator.master import MASTERS, InstanceFactory, open_instance
from orchestrator.system import ComponentModel
from orchestrator.validate import check_scenario

pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")]

CASE = Case("embrace", "omsimulator/embrace", "OpenModelica/OMSimulator testsuite/tests/resources/embrace",
            {}, step=1e-3)
FMI2_ERROR = 3
TO_THE_BIT = 1e-10  # OMSimulator's result file prints 12 significant digits
needs_omsimulator = pytest.mark.skipif(not OMSIMULATOR.is_dir(), reason="OMSimulator 3 is not installed")


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder packed into an archive as OMSimulator's CMake packs it."""
    return pack(CASE, tmp_path_factory.mktemp("embrace"))


def omsimulator_rows(scenario: Path, stop: float, tmp: Path) -> dict[float, dict[str, float]]:
    """OMSimulator 3's result file (every variable of every FMU, rows at each communication point;
    of the two it writes at a point, before and after the inputs are updated, the second)."""
    package = OMSIMULATOR / "lib" / "x86_64-linux-gnu"
    subprocess.run([sys.executable, str(HERE / "oms_probe.py"), str(package), str(scenario), repr(stop),
                    repr(CASE.step), str(tmp), json.dumps([])], check=True, capture_output=True, cwd=tmp,
                   timeout=600, env={**os.environ, "TMPDIR": str(tmp)})  # it unpacks the FMUs there
    with (tmp / "result.csv").open(newline="") as file:
        table = list(csv.reader(file))
    names = [n.removeprefix("root.") for n in table[0]]
    return {round(float(r[0]), 9): dict(zip(names[1:], map(float, r[1:]), strict=True)) for r in table[1:]}


def as_omsimulator(oms_time: bool) -> InstanceFactory:
    """Instances that read every Real variable before each step, as OMSimulator's result writer
    reads them at each communication point (after the inputs are set), and with ``oms_time`` step
    at OMSimulator's communication times (each the previous plus the step, in floating point)."""
    def open_reading(comp: ComponentModel, workdir: str, messages: MessageLog, time: float) -> InstanceBase:
        instance = open_instance(comp, workdir, messages, time)
        vrs = [v.valueReference for v in comp.model.modelVariables if v.type == "Real"]
        array, values = (ctypes.c_uint * len(vrs))(*vrs), (ctypes.c_double * len(vrs))()
        step, clock = instance.do_step, [time]

        def read_then_step(c: object, t: float, h: float, new_step: int) -> int:
            instance.get_real(c, array, len(vrs), values)  # Simulink's FMU refuses some: as in OMSimulator
            if oms_time:
                t, t_next = clock[0], clock[0] + CASE.step
                h, clock[0] = t_next - t, t_next
            return int(step(c, t, h, new_step))

        instance.do_step = read_then_step
        return instance
    return open_reading


Rows = dict[float, dict[str, float]]  # time -> variable -> value


def ours(scenario: Path, stop: float, tolerance: bool = True, reads: bool = False,
         oms_time: bool = False) -> Rows:
    """Our rows (the Python master, gauss-seidel as the file's annotation says); ``reads``: every
    Real variable of every FMU, read as OMSimulator reads them (else the connectors the run records,
    and nothing else read); ``oms_time``: at OMSimulator's communication times (with ``reads``);
    ``tolerance`` False: as before, none passed to the FMUs."""
    found: Rows = {}
    with orchestrator.open_system(scenario) as system:
        if not tolerance:
            system.structure = replace(system.structure, experiment=replace(system.structure.experiment,
                                                                            tolerance=None))
        master = MASTERS["gauss-seidel"](system, 0.0, stop, CASE.step,
                                         instances=as_omsimulator(oms_time) if reads else open_instance)
        step = master.step
        one = (ctypes.c_uint * 1)()
        value = ctypes.c_double()

        def step_and_read(k: int) -> None:
            step(k)
            row = found.setdefault(round(master.time(k + 1), 9), {})
            for inst, (name, comp) in zip(master.instances, system.components.items(), strict=True):
                for v in comp.model.modelVariables:
                    one[0] = v.valueReference
                    if v.type == "Real" and inst.get_real(inst.c, one, 1, ctypes.byref(value)) < FMI2_ERROR:
                        row[f"{name}.{v.name}"] = value.value

        if reads:
            master.step = step_and_read
        rows = master.run()
    if reads:
        return found
    names = [n for n in rows.dtype.names if n != "time"]
    return {round(float(r["time"]), 9): {n: float(r[n]) for n in names} for r in rows[1:]}


def first_difference(mine: dict[float, dict[str, float]], theirs: dict[float, dict[str, float]]) -> tuple:
    """(time, largest relative difference, variable, count) at the first time any common value
    differs by more than 1e-10 relative (OMSimulator's CSV holds 12 digits: "to the bit" is to
    those); (None, 0, '', common values) when none does."""
    common = 0
    for t in sorted(mine):
        gaps = [(abs(a - theirs[t][n]) / max(abs(a), abs(theirs[t][n]), 1e-300), n)
                for n, a in mine[t].items() if n in theirs.get(t, {})]
        common = max(common, len(gaps))
        worst = max(gaps, default=(0.0, ""))
        if worst[0] > TO_THE_BIT:
            return t, worst[0], worst[1], sum(g > TO_THE_BIT for g, _ in gaps)
    return None, 0.0, "", common


def test_the_files_tolerance_is_read(scenario: Path) -> None:
    with orchestrator.open_system(scenario) as system:
        assert system.structure.experiment.tolerance == 1e-4  # oms:FixedStepMaster relativeTolerance
        assert system.structure.experiment.step == 1e-3


@pytest.mark.parametrize("text", ["-1e-4", "0", "abc", "inf"])
def test_a_tolerance_that_is_no_positive_number_is_one_error(text: str, tmp_path: Path) -> None:
    """A tolerance no FMU can take is refused before anything runs, naming the file and the value."""
    source = HERE / "omsimulator" / "toplevelparameter1"
    shutil.copytree(source, tmp_path / "case")
    ssd = tmp_path / "case" / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('relativeTolerance="0.000100"', f'relativeTolerance="{text}"'))
    with ExitStack() as stack:
        _, errors, _ = check_scenario(tmp_path / "case", stack)
    assert len(errors) == 1, errors
    assert "SystemStructure.ssd" in errors[0] and f"relativeTolerance='{text}'" in errors[0]


@needs_omsimulator
def test_the_first_step_agrees_with_omsimulator_only_with_the_files_tolerance(scenario: Path,
                                                                             tmp_path: Path) -> None:
    """The same calls up to t = 1 ms (the reads of every variable come after it): with the SSD's
    tolerance all 1105 values at t = 1 ms are OMSimulator's to the bit; without it (before) ECS_HW's
    solver takes other steps."""
    theirs = omsimulator_rows(scenario, 0.001, tmp_path)
    when, gap, name, common = first_difference(ours(scenario, 0.001, reads=True), theirs)
    assert when is None, (when, gap, name)
    assert common == 1105
    when, gap, name, _ = first_difference(ours(scenario, 0.001, tolerance=False, reads=True), theirs)
    assert when == 0.001 and gap > 1e-5, (when, gap, name)


@needs_omsimulator
def test_with_omsimulators_calls_every_value_agrees_at_every_point(scenario: Path, tmp_path: Path) -> None:
    """With OMSimulator's reads and its communication times all 1105 Real values of the five FMUs
    agree at all 1000 points of the 1 s run; without the reads they part at t = 2 ms, with them but
    on the exact grid at t = 11 ms (the first point whose summed time differs from k h)."""
    theirs = omsimulator_rows(scenario, 1.0, tmp_path)
    when, gap, name, common = first_difference(ours(scenario, 1.0, reads=True, oms_time=True), theirs)
    assert when is None, (when, gap, name)
    assert common == 1105
    when, gap, name, _ = first_difference(ours(scenario, 0.012, reads=True), theirs)
    assert when == 0.011 and gap > 1e-9, (when, gap, name)
    when, gap, name, _ = first_difference(ours(scenario, 0.012), theirs)
    assert when == 0.002 and gap > 1e-7, (when, gap, name)
