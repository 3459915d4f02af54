# SPDX-License-Identifier: BSD-2-Clause
"""One plan, three executors (issue 34): the Python master, the compiled executor and the exported
container step the engine's one Plan and give the same rows, bit for bit.

Oracles: the Python master (the reference every earlier test and baseline checks) for the compiled
executor, and both for the container, which a host nobody here wrote (FMPy's ``simulate_fmu``)
runs. Every shipped scenario, both masters, FMI 2.0 and 3.0, for the two engine executors; the
container for one case of each kind (master x FMI version, its FMI 3.0 API for the FMI 3.0 twins)
in ``make test`` and for every case with ``ORCHESTRATE_ALL_EXECUTORS=1`` (``make executors``).

Also the compiled executor's own paths, against the Python master: a failed call and a value that
is not finite (the same error, the same rows kept), an input file, and the fallback to the Python
master with one note where the compiled executor cannot serve (``--fmi-log``, a loop iterated to a
fixed point, FMI 1.0)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import fmpy
import numpy as np
import pytest
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import EngineNote, NonFiniteError, RunOptions, SimulationError, UsageError
from orchestrator.experiments.scenarios import FMI3_SUFFIX, SCENARIO_DIR, all_scenarios
from orchestrator.export import export
from orchestrator.master import MASTERS
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, pack_ssp, write_ssd

SHORT = 0.5  # s: 500 steps of the 1 ms scenarios, 1000 of the pendulum's 0.5 ms
ALL = os.environ.get("ORCHESTRATE_ALL_EXECUTORS") == "1"
CASES = [(f"{name}{suffix}", master) for name in all_scenarios(SCENARIO_DIR) for suffix in ("", FMI3_SUFFIX)
         for master in MASTERS]
# one exported container of each kind in make test: master x FMI version (of the FMUs and the container)
CONTAINED = {("example1", "gauss-seidel"), ("pendulum_fmi3", "jacobi"), ("pendulum_smooth", "jacobi"),
             ("example1_finite_time_fmi3", "gauss-seidel")}


def bits(rows: np.ndarray, columns: list[str] | None = None) -> dict[str, list[int]]:
    """Each column as the integers of its doubles' bits (nan, -0.0 and every last bit compared)."""
    return {c: rows[c].view(np.int64).tolist() for c in (columns or list(rows.dtype.names or ()))}


def run(scenario: Path, executor: str, **options: object) -> np.ndarray:
    return orchestrator.run(scenario, RunOptions(executor=executor, **options)).rows  # type: ignore[arg-type]


@pytest.mark.system
@pytest.mark.xdist_group("export")
@pytest.mark.parametrize("scenario, master", CASES, ids=[f"{s}-{m}" for s, m in CASES])
def test_the_three_executors_agree_bit_for_bit(built: Path, tmp_path: Path, scenario: str,
                                               master: str) -> None:
    archive = built / "ssp" / f"{scenario}.ssp"
    python = run(archive, "python", stop_time=SHORT, master=master)
    compiled = run(archive, "compiled", stop_time=SHORT, master=master)
    assert len(python) == len(compiled) and python.dtype == compiled.dtype
    assert bits(compiled) == bits(python)
    if not (ALL or (scenario, master) in CONTAINED):
        return
    fmi = "3" if scenario.endswith(FMI3_SUFFIX) else "2"
    fmu, exposed = export(archive, tmp_path / f"{scenario}.fmu", master=master, fmi=fmi)
    h = fmpy.read_model_description(str(fmu)).defaultExperiment.stepSize
    contained = fmpy.simulate_fmu(str(fmu), stop_time=SHORT, output_interval=float(h))
    outputs = [str(e.port) for e in exposed if e.kind == "output"]
    assert outputs and set(outputs) <= set(python.dtype.names or ())
    assert bits(contained, outputs) == bits(python, outputs)
    # the host's own time column (FMPy sums its steps): the container steps on t0 + k h itself
    np.testing.assert_allclose(contained["time"], python["time"], rtol=1e-12, atol=0)


@pytest.fixture(scope="module")
def loop(test_fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    return loop_scenario(tmp_path_factory.mktemp("loop") / "loop", test_fmus, stop=1.0, step=0.01,
                         factor=0.5, offset=0.25)


@pytest.mark.parametrize("master", list(MASTERS))
def test_a_failed_step_is_the_same_error_and_rows_in_c(test_fmus: dict[str, Path], tmp_path: Path,
                                                      master: str) -> None:
    """The integrator fails its step at t = 0.5 s: the compiled executor reports the failure the
    Python master reports, after the same rows (failures cross from C as data)."""
    archive = loop_scenario(tmp_path / "fails", test_fmus, fail_at=0.5)
    errors = {}
    for executor in ("python", "compiled"):
        with pytest.raises(SimulationError) as info:
            orchestrator.run(archive, RunOptions(executor=executor, master=master))
        errors[executor] = info.value
    assert str(errors["compiled"]) == str(errors["python"])
    assert "integrator: fmi2DoStep returned fmi2" in str(errors["python"])
    assert bits(errors["compiled"].result.rows) == bits(errors["python"].result.rows)
    assert errors["python"].result.count > 10


def test_a_value_that_is_not_finite_stops_c_where_it_stops_python(loop: Path) -> None:
    """gain.k = nan: the first row holding nan ends the run with the NonFiniteError naming the same
    component, variable and time, and the same rows kept."""
    errors = {}
    for executor in ("python", "compiled"):
        with pytest.raises(NonFiniteError) as info:
            orchestrator.run(loop, RunOptions(executor=executor, overrides={"gain.k": "nan"}))
        errors[executor] = info.value
    assert str(errors["compiled"]) == str(errors["python"])
    assert bits(errors["compiled"].result.rows) == bits(errors["python"].result.rows)


@pytest.mark.parametrize("master", list(MASTERS))
def test_an_input_file_drives_the_compiled_executor_as_it_drives_python(test_fmus: dict[str, Path],
                                                                      tmp_path: Path, master: str) -> None:
    """The loop with its source replaced by a file (uneven rows, linear interpolation between them):
    the inputs of each block are computed in Python, set by C at each point; the same bits."""
    folder = tmp_path / "driven"
    gain = component("gain", "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": 3.0})
    write_ssd(folder, SystemStructure("driven", (gain,), (), Experiment(0.0, 0.7, 0.01)))
    archive = pack_ssp(folder, {"Gain.fmu": test_fmus["Gain"]}, tmp_path / "driven.ssp")
    inputs = tmp_path / "u.csv"
    t = np.array([0.0, 0.013, 0.1, 0.33, 0.5, 0.71])
    inputs.write_text("time,gain.u\n" + "".join(f"{float(a)!r},{float(np.sin(7 * a))!r}\n" for a in t))
    python = run(archive, "python", input_file=inputs, master=master)
    compiled = run(archive, "compiled", input_file=inputs, master=master)
    assert bits(compiled) == bits(python)
    expected = np.interp(python["time"], t, np.sin(7 * t))
    assert bits(python, ["gain.u"])["gain.u"] == expected.view(np.int64).tolist()


def _notes(scenario: Path, **options: object) -> tuple[list[str], dict]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = orchestrator.run(scenario, RunOptions(**options))  # type: ignore[arg-type]
    return [str(w.message) for w in caught if issubclass(w.category, EngineNote)], result.provenance


def test_the_python_master_serves_what_c_cannot_with_one_note(loop: Path, test_fmus: dict[str, Path],
                                                               tmp_path: Path) -> None:
    notes, record = _notes(loop)
    assert notes == [] and record["executor"] == "compiled"
    notes, record = _notes(loop, fmi_log=["gain"])
    # the Python API names fields (fmi_log), the command line its options (--fmi-log)
    assert notes == ["the Python master ran this scenario: fmi_log traces the calls the Python master makes"]
    assert record["executor"] == "python"
    with pytest.raises(UsageError, match="executor compiled cannot run this scenario: fmi_log"):
        orchestrator.run(loop, RunOptions(fmi_log=["gain"], executor="compiled"))
    # two gains in a loop (0.5 * 0.25 < 1: it converges): gauss-seidel iterates it in Python
    folder = tmp_path / "alg"
    gains = [component(n, "Gain.fmu", [("u", "input", "Real"), ("y", "output", "Real")], {"k": k})
             for n, k in (("a", 0.5), ("b", 0.25))]
    write_ssd(folder, SystemStructure("alg", tuple(gains), (Connection.between("a.y", "b.u"),
                                                             Connection.between("b.y", "a.u")),
                                      Experiment(0.0, 0.1, 0.01)))
    archive = pack_ssp(folder, {"Gain.fmu": test_fmus["Gain"]}, tmp_path / "alg.ssp")
    notes, record = _notes(archive)
    assert notes == ["the Python master ran this scenario: an algebraic loop is iterated to a fixed point"]
    notes, record = _notes(archive, master="jacobi")  # jacobi delays the loop: C steps it
    assert notes == [] and record["executor"] == "compiled"


def test_fmi1_components_run_in_the_python_master_with_one_note() -> None:
    """libcosim's own FMI 1.0 test scenario (tests/ssp_conformance): the values of libcosim's unit
    test, stepped by the Python master, which binds FMI 1.0's prefixed functions."""
    libcosim = Path(__file__).parent / "ssp_conformance" / "libcosim"
    notes, record = _notes(libcosim / "ssp" / "linear_transformation", root=libcosim, stop_time=0.1,
                           step=0.01)
    assert notes == ["the Python master ran this scenario: FMI 1.0 components identity1, identity2"]
    assert record["executor"] == "python"


def _copies(archive: Path, n: int, dest: Path) -> Path:
    """``archive`` with its components and connections written ``n`` times (``plant_2`` ...), the
    same FMU files (benchmarks/many_copies.py's scenario)."""
    import zipfile

    from lxml import etree

    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    with zipfile.ZipFile(archive) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
    root = etree.fromstring(members["SystemStructure.ssd"])
    system = root.find("ssd:System", ns)
    elements, connections = system.find("ssd:Elements", ns), system.find("ssd:Connections", ns)
    components, links = list(elements), list(connections)
    for i in range(2, n + 1):
        for c in components:
            elements.append(etree.fromstring(etree.tostring(c)))
            elements[-1].set("name", f"{c.get('name')}_{i}")
        for link in links:
            twin = etree.fromstring(etree.tostring(link))
            for end in ("startElement", "endElement"):
                twin.set(end, f"{twin.get(end)}_{i}")
            connections.append(twin)
    members["SystemStructure.ssd"] = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    target = dest / f"{archive.stem}_x{n}.ssp"
    with zipfile.ZipFile(target, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return target


@pytest.mark.system
def test_copies_of_one_fmu_share_its_bindings_and_give_its_rows(built: Path, tmp_path: Path) -> None:
    """Issue 46: the components of one FMU share one model description and fmpy's bindings of its
    library (the slaves are copies of the first). Each of 4 copies of example1 gives the rows of
    example1 alone, bit for bit, and after the run no FMU library is left loaded (each slave gave
    its reference back), as before."""
    import gc

    from orchestrator import fmi

    def libraries() -> set[str]:
        with open("/proc/self/maps") as maps:
            paths = [line.split()[-1] for line in maps if "/binaries/" in line]
        return {p for p in paths if p.endswith(".so")}

    loaded = libraries()
    alone = run(built / "ssp" / "example1.ssp", "compiled", stop_time=SHORT)
    many = run(_copies(built / "ssp" / "example1.ssp", 4, tmp_path), "compiled", stop_time=SHORT)
    for name in alone.dtype.names or ():
        if name == "time":
            continue
        component, _, connector = name.partition(".")
        for i in range(2, 5):
            assert bits(many, [f"{component}_{i}.{connector}"])[f"{component}_{i}.{connector}"] == \
                bits(alone, [name])[name], name
    assert bits(many, list(alone.dtype.names or ())) == bits(alone)
    gc.collect()  # the run's objects in reference cycles (its slaves among them) are gone
    left = {p for p in libraries() - loaded if not p.endswith("_pythonfmu.so")}  # pythonfmu's stays
    assert not fmi._TEMPLATES and left == set()
