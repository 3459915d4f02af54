# SPDX-License-Identifier: BSD-2-Clause
"""SSPs other tools wrote run here as those tools run them (issue 32): the conformance set of
``tests/ssp_conformance/`` (copies of OMSimulator's and libcosim's own SSP test files).

Oracles, each independent of this engine: the values OMSimulator's and libcosim's own test scripts
print for these files, OMSimulator 3 and libcosim running the same file now, and closed forms (the
algebraic loop). On main before issue 32 every one of these files was refused (nested systems,
system bindings, version 2.0, FMI 1.0, '..' references, loops); the before/after table of both
tools' whole test resources is docs/ssp-conformance.md (``make conformance``).
"""

from __future__ import annotations

import math
import shutil
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from ssp_conformance.conformance import (
    CASES,
    HERE,
    OMSIMULATOR,
    Case,
    columns_of,
    differences,
    libcosim,
    omsimulator,
    ours,
    pack,
)

import orchestrator
from orchestrator import LoopError, RunOptions
from orchestrator.cli import main
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, write_ssd
from orchestrator.validate import check_scenario, validate

# other tools' files leave inputs unconnected: the warnings are theirs, and validate's are asserted
pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")]

BY_NAME = {c.name: c for c in CASES}


def _root(case: Case) -> Path | None:
    return HERE / case.root if case.root else None


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, dict[str, float]]]:
    """Every case packed and run once: its scenario and our values at the stop time."""
    folder = tmp_path_factory.mktemp("conformance")
    found = {}
    for case in CASES:
        scenario = pack(case, folder)
        found[case.name] = (scenario, ours(scenario, case))
    return found


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_checks_pass_with_the_notes_expected(case: Case, results) -> None:
    """The checks a run makes (validate's, but fmpy's full FMU validation, 28 s on libcosim's crane
    FMUs) find no error, and the warnings the case expects (version 2.0, the loop)."""
    scenario, _ = results[case.name]
    with ExitStack() as stack:
        _, errors, warnings = check_scenario(scenario, stack, root=_root(case))
    assert errors == []
    for text in case.warnings:
        assert any(text in w for w in warnings), (text, warnings)


@pytest.mark.parametrize("case", [c for c in CASES if c.oracle], ids=lambda c: c.name)
def test_runs_to_the_values_the_tools_own_tests_print(case: Case, results) -> None:
    _, mine = results[case.name]
    for column, expected in case.oracle.items():
        assert math.isclose(mine[column], expected, rel_tol=1e-12, abs_tol=1e-12), (column, mine[column])


@pytest.mark.parametrize("case", [c for c in CASES if not c.omsimulator], ids=lambda c: c.name)
def test_agrees_with_omsimulator(case: Case, results) -> None:
    if not (OMSIMULATOR / "lib").is_dir():
        pytest.skip(f"OMSimulator 3 not installed ({OMSIMULATOR})")
    scenario, mine = results[case.name]
    with orchestrator.open_system(scenario, root=_root(case)) as system:
        names, name = columns_of(system), system.structure.name
    theirs = omsimulator(scenario, case, names, name)
    compared = [k for k, v in theirs.items() if isinstance(v, float) and k in mine]
    assert len(compared) >= len(case.oracle) and compared, theirs
    # where OMSimulator 3 differs, it is by the documented fault (case.oms_why), nothing else
    assert {k: theirs_v for k, (_, theirs_v) in differences(mine, theirs).items()} == case.oms_differs


def test_libcosim_runs_the_demo_loop_as_our_jacobi_master(results) -> None:
    """libcosim's demo (a cycle of connections, run by libcosim's fixed-step algorithm): the same
    outputs as our jacobi master at every communication point, bit for bit; an input libcosim
    reports at t is the one the FMU used in the step ending at t, ours at t the one transferred at
    t for the next step (so libcosim's input at t_k+1 is ours at t_k)."""
    pytest.importorskip("libcosimpy")
    case = BY_NAME["libcosim_demo"]
    scenario, _ = results[case.name]
    output, input_ = "KnuckleBoomCrane.p_Crane.f[3]", "CraneController.p_Crane.f[3]"
    theirs = libcosim(scenario, case, [output, input_])
    rows = orchestrator.run(scenario, RunOptions(stop_time=case.stop, step=case.step, master="jacobi",
                                                 root=_root(case))).rows
    assert len(theirs[output]) == len(rows) and abs(rows[output]).max() > 0.1
    assert (np.array(theirs[output][1:]) == rows[output][1:]).all()
    assert (np.array(theirs[input_][2:]) == rows[input_][1:-1]).all()


def test_libcosim_refuses_the_fmi1_file_we_run(results) -> None:
    """libcosim's own FMI 1.0 test file: libcosimpy here ends with a signal (it crashed the process
    with a segmentation fault), where we run it to the values of libcosim's unit test."""
    pytest.importorskip("libcosimpy")
    case = BY_NAME["libcosim_linear_transformation"]
    scenario, mine = results[case.name]
    with pytest.raises(RuntimeError, match="libcosim failed"):
        libcosim(scenario, case, ["identity2.realIn"])
    assert mine["identity2.realIn"] == 1.3 * mine["identity1.realOut"] + 50


def test_refused_where_the_engine_cannot_run_it(tmp_path) -> None:
    """A folder reaching outside itself without --root, and a proxy FMU on another host, are one
    line each."""
    demo = HERE / "libcosim" / "ssp" / "demo"
    folder = tmp_path / "libcosim"
    shutil.copytree(HERE / "libcosim", folder)
    report = validate(folder / "ssp" / "demo")
    assert [e.message for e in report.errors if "climbs out" in e.message and "--root" in e.message]
    ssd = folder / "ssp" / "demo" / "SystemStructure.ssd"
    proxy = 'source="proxyfmu://example.org:9090?file=../../fmi2/CraneController.fmu"'
    ssd.write_text(ssd.read_text().replace('source="../../fmi2/CraneController.fmu"', proxy))
    errors = [e.message for e in validate(ssd.parent, root=folder).errors]
    assert len(errors) == 1 and "proxy FMU on another host" in errors[0], errors
    assert demo.is_dir()


def test_a_proxy_fmu_on_this_host_runs_its_fmu_in_process(tmp_path, results) -> None:
    """libcosim's demo/proxy (``proxyfmu://localhost?file=...``: libcosim runs that FMU in a child
    process): a warning, and the same values as the demo that references the FMU directly, which
    libcosim's own run matches (test_libcosim_runs_the_demo_loop_as_our_jacobi_master)."""
    case = BY_NAME["libcosim_demo"]
    folder = tmp_path / "libcosim"
    shutil.copytree(HERE / "libcosim", folder)
    ssd = folder / "ssp" / "demo" / "SystemStructure.ssd"
    proxy = 'source="proxyfmu://localhost?file=../../fmi2/CraneController.fmu"'
    ssd.write_text(ssd.read_text().replace('source="../../fmi2/CraneController.fmu"', proxy))
    report = validate(ssd.parent, root=folder)
    assert report.ok, report.errors
    assert [p.message for p in report.problems if "runs in this process" in p.message]
    options = RunOptions(stop_time=case.stop, step=case.step, root=folder)
    proxied = orchestrator.run(ssd.parent, options).rows
    direct = orchestrator.run(HERE / case.path, replace(options, root=_root(case))).rows
    assert proxied.tobytes() == direct.tobytes()


def _loop(folder: Path, gain: float) -> Path:
    """Add1.y = k1 u1 + k2 u2 with u2 = Gain1.y = gain * Add1.y: an algebraic loop through two
    OpenModelica FMUs (their ModelStructure says y depends on the inputs); u1 = 1 bound."""
    resources = HERE / "omsimulator" / "LinearTransformation" / "resources"
    add = component("Add1", "Add.fmu",
                    [("u1", "input", "Real"), ("u2", "input", "Real"), ("y", "output", "Real")], {"u1": 1.0})
    gain_c = component("Gain1", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": gain})
    write_ssd(folder, SystemStructure("loop", (add, gain_c), (Connection.between("Add1.y", "Gain1.u"),
                                                               Connection.between("Gain1.y", "Add1.u2")),
                                      Experiment(0.0, 0.1, 0.01)))
    (folder / "resources").mkdir()
    for fmu in ("Add.fmu", "Gain.fmu"):
        shutil.copy(resources / fmu, folder / "resources" / fmu)
    return folder


def test_gauss_seidel_solves_an_algebraic_loop_to_its_fixed_point(tmp_path) -> None:
    """y = 1 + 0.5 y: y = 2 at every communication point (closed form) under gauss-seidel, within the
    loop tolerance; under jacobi the same value is approached one delayed step at a time."""
    folder = _loop(tmp_path / "loop", 0.5)
    rows = orchestrator.run(folder, RunOptions(loop_tolerance=1e-12)).rows
    assert abs(rows["Add1.y"] - 2.0).max() <= 1e-11
    delayed = orchestrator.run(folder, RunOptions(master="jacobi")).rows["Add1.y"]
    assert delayed[0] != 2.0 and abs(delayed[-1] - 2.0) < abs(delayed[1] - 2.0)


def test_a_loop_that_does_not_converge_is_one_line_with_its_residual(tmp_path) -> None:
    """y = 1 + 2 y has the fixed point -1, which the iteration leaves (gain 2): LoopError naming the
    loop's components, the time and the residual, after the iteration limit."""
    folder = _loop(tmp_path / "loop", 2.0)
    with pytest.raises(LoopError, match=r"algebraic loop through Add1, Gain1 did not converge at t=0\.000 s: "
                                        r"residual \S+ after 7 iterations") as info:
        orchestrator.run(folder, RunOptions(loop_iterations=7))
    assert info.value.residual > 0.1


def test_nested_names_through_the_export_container(tmp_path) -> None:
    """The archive OMSimulator wrote with a nested system, exported as one FMU and simulated by fmpy:
    its variables carry the nested names (``sub-system1.Gain1.y``) and the values of our run; a
    loop is refused by the container under gauss-seidel (it does not iterate), named."""
    from fmpy import simulate_fmu

    from orchestrator.errors import ScenarioError
    from orchestrator.export.container import export

    case = BY_NAME["NestedSystemSimulation1"]
    fmu, exposed = export(HERE / case.path, tmp_path / "nested.fmu", stop_time=1.0, step=0.5)
    names = [str(e.port) for e in exposed]
    assert {"sub-system1.Gain1.y", "sub-system1.Add1.y", "Gain1.y", "Add1.y"} <= set(names)
    result = simulate_fmu(str(fmu), stop_time=1.0, output_interval=0.5, output=names)
    for column, expected in case.oracle.items():
        if column in names:
            assert result[column][-1] == expected, column
    loop = "algebraic loop: Add1.u2 -> Add1.y -> Gain1.u -> Gain1.y -> Add1.u2"
    with pytest.raises(ScenarioError, match=f"{loop}: the container does not iterate"):
        export(_loop(tmp_path / "loop", 0.5), tmp_path / "loop.fmu")


def test_an_input_file_drives_a_nested_input_by_its_nested_name(tmp_path) -> None:
    """``--input-file`` columns name nested inputs as the results do: sub-system1.Add1.u2 held at 5
    gives sub-system1.Add1.y = u1 + u2 = 10 + 5 (k1 = k2 = 1)."""
    inputs = tmp_path / "u.csv"
    inputs.write_text("time,sub-system1.Add1.u2\n0,5\n1,5\n")
    case = BY_NAME["NestedSystemSimulation1"]
    rows = orchestrator.run(HERE / case.path, RunOptions(step=0.5, input_file=inputs)).rows
    assert list(rows["sub-system1.Add1.y"]) == [15.0, 15.0, 15.0]


def test_inspect_lists_the_values_given_to_system_connectors(results, capsys) -> None:
    """toplevelparameter1: root.ssv gives the root's own connector Input_cref -20, which OMSimulator's
    test prints as model.root.Input_cref; no component reads it, so inspect is where it shows."""
    scenario, _ = results["toplevelparameter1"]
    assert main(["inspect", str(scenario)]) == 0
    assert "  Input_cref = -20.0 (from resources/root.ssv)" in capsys.readouterr().out.splitlines()
