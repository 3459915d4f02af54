# SPDX-License-Identifier: BSD-2-Clause
"""The project's scenarios with the real FMUs: build, run every scenario, compare the masters with
each other and with libcosim on the same archives."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv

import orchestrator
from orchestrator import RunOptions, SimulationError
from orchestrator.cli import main
from orchestrator.crosscheck import LibcosimError, run_libcosim

REPO = Path(__file__).resolve().parent.parent
# scenario -> the communication step it ships with
SCENARIOS = {"example1": 1e-3, "example1_finite_time": 1e-3, "example1_no_fault": 1e-3, "pendulum": 5e-4,
             "pendulum_finite_time": 1e-3}
OUTPUTS = ["reference.yd", "reference.yd_dot", "reference.yd_ddot", "controller.v", "controller.z1",
           "controller.z2", "controller.zeta1", "controller.eta1_hat", "controller.eta2_hat", "controller.r",
           "actuator.uf", "actuator.u_dz", "plant.x1", "plant.x2", "plant.z", "plant.y"]

pytestmark = pytest.mark.system


def test_build_packs_ssd_ssv_and_fmus(built):
    import zipfile

    with zipfile.ZipFile(built / "ssp" / "pendulum.ssp") as zf:
        names = set(zf.namelist())
    assert names == {"SystemStructure.ssd", "reference.ssv", "controller.ssv", "actuator.ssv", "plant.ssv",
                     "resources/Reference.fmu", "resources/FixedTimeController.fmu", "resources/Actuator.fmu",
                     "resources/PendulumPlant.fmu"}


@pytest.mark.parametrize("name", SCENARIOS)
def test_every_scenario_runs(built, name):
    r = orchestrator.run(built / "ssp" / f"{name}.ssp", RunOptions(stop_time=0.5)).rows
    assert len(r) == round(0.5 / SCENARIOS[name]) + 1 and r["time"][-1] == 0.5
    assert set(OUTPUTS) <= set(r.dtype.names)
    assert all(np.isfinite(r[c]).all() for c in r.dtype.names)
    x1_0 = 0.5 if name.startswith("example1") else 0.6
    assert r["plant.y"][0] == x1_0 and r["controller.x1"][0] == x1_0
    # t0 is a real sample: the controller has already acted on the initial state
    assert abs(r["controller.v"][0]) > 10 and r["actuator.uf"][0] == r["controller.v"][0]


def test_libcosim_honours_parameter_sets_and_step(built, tmp_path):
    """A copy of example1 with the reference amplitude 0.25 (in reference.ssv) and a 0.5 ms step
    (in both tool annotations): libcosim and we both follow it."""
    import shutil

    from orchestrator.ssp import pack_ssp

    folder = tmp_path / "variant"
    shutil.copytree(REPO / "ssp" / "example1", folder)
    ssv = folder / "reference.ssv"
    ssv.write_text(ssv.read_text().replace('name="amplitude">\n      <ssv:Real value="0.5"',
                                           'name="amplitude">\n      <ssv:Real value="0.25"'))
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('"0.001"', '"0.0005"'))
    fmus = {p.name: p for p in (built / "fmus").glob("*.fmu")}
    names = ("Reference.fmu", "FixedTimeController.fmu", "Actuator.fmu", "Example1Plant.fmu")
    archive = pack_ssp(folder, {n: fmus[n] for n in names}, tmp_path / "variant.ssp")
    theirs, _ = run_libcosim(archive, 0.1, ["time", "reference.yd", "plant.y"])
    ours = orchestrator.run(archive, RunOptions(stop_time=0.1, master="jacobi")).rows
    assert theirs["time"].tolist() == ours["time"].tolist() == [k / 2000 for k in range(201)]
    np.testing.assert_allclose(theirs["reference.yd"], 0.25 * np.sin(theirs["time"]), rtol=0, atol=1e-15)
    assert (theirs["plant.y"] == ours["plant.y"]).all()


def test_masters_differ_by_the_coupling_delay(built):
    """Before the fault uf = v: gauss-seidel passes v to the plant at the same instant,
    jacobi one step later (libcosim's semantics)."""
    ssp = built / "ssp" / "example1.ssp"
    gs = orchestrator.run(ssp, RunOptions(stop_time=1.0)).rows
    jac = orchestrator.run(ssp, RunOptions(stop_time=1.0, master="jacobi")).rows
    assert (gs["actuator.uf"] == gs["controller.v"]).all()
    assert (gs["plant.uf"] == gs["actuator.uf"]).all() and (gs["controller.x1"] == gs["plant.x1"]).all()
    assert (jac["actuator.uf"][1:] == jac["controller.v"][:-1]).all()
    assert np.max(np.abs(gs["plant.y"] - jac["plant.y"])) > 1e-3


def test_jacobi_equals_libcosim_example1(built):
    ssp = built / "ssp" / "example1.ssp"
    ours = orchestrator.run(ssp, RunOptions(stop_time=2.0, master="jacobi")).rows
    theirs, _ = run_libcosim(ssp, 2.0, ["time"] + OUTPUTS)
    assert ours["time"].tolist() == theirs["time"].tolist()
    worst = max(np.max(np.abs(ours[c] - theirs[c])) for c in OUTPUTS)
    assert worst <= 1e-12


def pendulum_at(step: str, built: Path, tmp_path: Path, state_limit: float | None = None) -> Path:
    """The shipped pendulum scenario with its communication step replaced by ``step`` (both tool
    annotations) and, if given, the plant's ``state_limit`` set in its parameter file, packed into
    ``tmp_path``."""
    from orchestrator.ssp import pack_ssp

    folder = tmp_path / f"pendulum_{step}"
    shutil.copytree(REPO / "ssp" / "pendulum", folder)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    assert text.count('"0.0005"') == 2, "the shipped pendulum step moved: update this test"
    ssd.write_text(text.replace('"0.0005"', f'"{step}"'))
    if state_limit is not None:  # read by every tool that reads the scenario's parameters
        ssv = folder / "plant.ssv"
        entry = f'<ssv:Parameter name="state_limit"><ssv:Real value="{state_limit!r}"/></ssv:Parameter>'
        ssv.write_text(ssv.read_text().replace("</ssv:Parameters>", entry + "</ssv:Parameters>"))
    fmus = {p.name: p for p in (built / "fmus").glob("*.fmu")}
    names = ("Reference.fmu", "FixedTimeController.fmu", "Actuator.fmu", "PendulumPlant.fmu")
    return pack_ssp(folder, {n: fmus[n] for n in names}, tmp_path / f"pendulum_{step}.ssp")


def test_jacobi_and_libcosim_fail_alike_on_the_pendulum_at_1_ms(built, tmp_path):
    """Why the pendulum ships with a 0.5 ms step: at 1 ms the two steps of coupling delay of a
    delayed master make its stiff start (|v| ~ 15000) diverge within 30 ms; both tools stop at
    the same step with the same trajectory up to there, while the delay-free master runs it. The
    plant's state_limit, set to 1e4 (the default before issue 37 widened it to 1e6), ends the run
    when x2 passes it, at 28 ms (before it, the non-finite state at 31 ms)."""
    ssp = pendulum_at("0.001", built, tmp_path, state_limit=1e4)
    expected = r"^plant: fmi2DoStep returned fmi2Discard at t=0\.028 s"
    with pytest.raises(SimulationError, match=expected) as ours:
        orchestrator.run(ssp, RunOptions(stop_time=0.1, master="jacobi"))
    with pytest.raises(LibcosimError) as theirs:
        run_libcosim(ssp, 0.1, ["time"] + OUTPUTS)
    ours, theirs = ours.value.result.rows, theirs.value.result
    assert len(ours) == len(theirs) == 29
    assert max(np.max(np.abs(ours[c] - theirs[c])) for c in OUTPUTS) == 0.0
    gs = orchestrator.run(ssp, RunOptions(stop_time=0.1)).rows  # no delay: stable
    assert np.isfinite(gs["plant.y"]).all()


def test_gauss_seidel_close_to_libcosim_example1(built):
    """The one-step delays of libcosim's algorithm change the stiff first 50 ms noticeably; from 1 s
    on the outputs agree within 0.01 (measured over 30 s: 0.049 at t = 0.029 s, 0.0053 after 1 s)."""
    ssp = built / "ssp" / "example1.ssp"
    ours = orchestrator.run(ssp, RunOptions(stop_time=3.0)).rows
    theirs, _ = run_libcosim(ssp, 3.0, ["time", "plant.y"])
    deviation = np.abs(ours["plant.y"] - theirs["plant.y"])
    assert deviation.max() <= 0.06
    assert deviation[ours["time"] >= 1.0].max() <= 0.01


def test_fault_and_override_through_cli(built, tmp_path):
    """--set moves the fault to 0.2 s: from then on uf differs from v; before, it equals v."""
    out = tmp_path / "r.csv"
    assert main(["run", str(built / "ssp" / "example1.ssp"), "--stop-time", "0.4", "--set",
                 "actuator.t_fault=0.2", "--output", str(out), "--no-plot", "--quiet"]) == 0
    r = read_csv(out)
    before, after = r["time"] < 0.2, r["time"] >= 0.2
    assert (r["actuator.uf"][before] == r["controller.v"][before]).all()
    assert (r["actuator.uf"][after] != r["controller.v"][after]).all()
    assert main(["metrics", str(out)]) == 0


def test_pendulum_as_shipped_runs_in_libcosim(built):
    """At its 0.5 ms step the shipped pendulum runs in libcosim, equal to our jacobi master, and
    close to the delay-free default master (measured over 30 s: 0.071 during the stiff start,
    1.6e-3 after 1 s; over 3 s: 9.4e-4 after 1 s)."""
    archive = built / "ssp" / "pendulum.ssp"
    theirs, _ = run_libcosim(archive, 3.0, ["time"] + OUTPUTS)
    ours = orchestrator.run(archive, RunOptions(stop_time=3.0)).rows
    jacobi = orchestrator.run(archive, RunOptions(stop_time=3.0, master="jacobi")).rows
    assert theirs["time"].tolist() == ours["time"].tolist() == jacobi["time"].tolist()
    assert max(np.max(np.abs(jacobi[c] - theirs[c])) for c in OUTPUTS) == 0.0
    deviation = np.abs(ours["plant.y"] - theirs["plant.y"])
    late = ours["time"] >= 1.0
    print(f"pendulum at 0.5 ms, libcosim vs gauss-seidel: max |delta plant.y| {deviation.max():.2e}, "
          f"after 1 s {deviation[late].max():.2e}")
    assert deviation.max() <= 0.1
    assert deviation[late].max() <= 2e-3


def test_invalid_parameter_fails_cleanly_without_crashing_the_process(built, tmp_path):
    """k1 = 0 under the fixed-time law (inside the FMU's declared range, which the finite-time law
    needs; beta = 1.0 before issue 36 declared its open range) makes the controller FMU return
    fmi2Fatal; the CLI reports it on one line and the process survives its garbage collection (it
    used to die with SIGSEGV: freeing a fatal pythonfmu instance). Run three times in one fresh
    interpreter, since the crash came at a random GC."""
    import subprocess
    import sys

    code = (
        "import gc, sys\n"
        "from orchestrator.cli import main\n"
        "codes = [main(['run', sys.argv[1], '--set', 'controller.k1=0', '--stop-time', '0.01',\n"
        "               '--quiet', '--no-plot', '--output', sys.argv[2]]) for _ in range(3)]\n"
        "gc.collect()\n"
        "print(codes)\n"
    )
    archive, output = str(built / "ssp" / "example1.ssp"), str(tmp_path / "r.csv")
    done = subprocess.run([sys.executable, "-c", code, archive, output], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[1, 1, 1]"
    errors = done.stderr.strip().splitlines()
    assert len(errors) == 3 and "Traceback" not in done.stderr
    assert errors[0].startswith("orchestrate: error: controller: ")
    assert "fmi2Fatal" in errors[0] and "k1 must satisfy k1 > 0 (got 0.0)" in errors[0]
