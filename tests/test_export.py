# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate export``: shipped scenarios as one FMU, run by hosts nobody here wrote (fmusim and
the FMU Compliance Checker on a colleague's machine with no Python, FMPy's ``simulate_fmu``) and
checked against ``orchestrate run`` of the same scenario (the oracle: the engine's master),
against the metrics table of docs/results.md (written by ``make report``), and inside a bigger SSP.
Here: the four scenarios of that table; every shipped scenario in the three hosts,
30 s each, is a row of the crosscheck matrix (tests/test_crosscheck_system.py, tolerance 1e-12).

Bounds: fmpy and fmuCheck give plant.y bit for bit (fmuCheck prints 17 significant digits);
fmusim prints 16 (``%.16g``), so its values are the container's rounded to 16 digits: within
FMUSIM_PRINT of them relative. The container computes its grid t0 + k h itself, so the hosts' own
time (fmuCheck sums h) never reaches the FMUs."""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.util import read_csv
from lxml import etree

import orchestrator
from orchestrator import RunOptions, SimulationError
from orchestrator.cli import main
from orchestrator.crosscheck.colleague import hidden, refusal
from orchestrator.errors import ScenarioError
from orchestrator.experiments.metrics import tracking_metrics
from orchestrator.experiments.scenarios import component_sources
from orchestrator.export import export
from orchestrator.export.container import shared_runtimes
from orchestrator.ssp import (
    Connection,
    Experiment,
    SystemStructure,
    component,
    pack_ssp,
    read_parameter_set,
    write_ssd,
)

pytestmark = [pytest.mark.system, pytest.mark.xdist_group("export")]

REPO = Path(__file__).resolve().parent.parent
TOOLS = REPO.parent / "shared" / "tools"
FMUSIM = TOOLS / "fmusim" / "bin" / "fmusim"
FMUCHECK = TOOLS / "fmucheck" / "bin" / "fmuCheck"
SHORT = 1.0  # s: stop time of the checks the metrics table is not involved in
FMUSIM_PRINT = 1e-15  # relative: a value printed with 16 significant digits (%.16g) and read back
NO_NAMESPACE = refusal()
needs_namespace = pytest.mark.skipif(NO_NAMESPACE is not None, reason=str(NO_NAMESPACE))


def run(scenario: Path, **options: object) -> np.ndarray:
    """The rows of ``orchestrate run`` on ``scenario`` (options as RunOptions takes them)."""
    return orchestrator.run(scenario, RunOptions(**options)).rows  # type: ignore[arg-type]


def table_rows() -> dict[str, list[str]]:
    """The co-simulation rows of the metrics table beside the paper's (docs/results.md): scenario ->
    RAE, MSE, RMSE, MAE, settling, peak |v| cells, as printed."""
    rows = {}
    for line in (REPO / "docs" / "results.md").read_text(encoding="utf-8").splitlines():
        match = re.match(r"\| \d \| [\w-]+ \| co-simulation \(`(?:orchestrate run )?(\w+)`[^|]*\|(.*)\|$",
                         line)
        if match:
            rows[match.group(1)] = [c.strip() for c in match.group(2).split("|")]
    return rows


TABLE = table_rows()
SCENARIOS = sorted(TABLE)
assert SCENARIOS, "docs/results.md: no co-simulation rows in the metrics table"  # never an empty set


@pytest.fixture(scope="module")
def exported(built: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every shipped scenario exported (default options), then copied to a fresh folder as a
    colleague receives it; exported on first use."""
    folder = tmp_path_factory.mktemp("exported")

    class Lazy(dict):
        def __missing__(self, name: str) -> Path:
            path, _ = export(built / "ssp" / f"{name}.ssp", folder / "made" / f"{name}.fmu")
            self[name] = Path(shutil.copy(path, folder))
            return self[name]

    return Lazy()


def same(name: str, got: np.ndarray, expected: np.ndarray, rtol: float = 0.0) -> float:
    """max |got - expected| of plant.y, asserted within ``rtol`` (0: bit for bit), times equal."""
    assert len(got) == len(expected), name
    np.testing.assert_allclose(got["time"], expected["time"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(got["plant.y"], expected["plant.y"], rtol=rtol, atol=0, err_msg=name)
    return float(np.max(np.abs(got["plant.y"] - expected["plant.y"])))


def fmusim(fmu: Path, stop: float, out: Path) -> np.ndarray:
    command = [str(FMUSIM), "--interface-type", "cs", "--stop-time", repr(stop), "--output-file", str(out),
               str(fmu)]
    result = subprocess.run(hidden(command), capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    return read_csv(str(out))


@needs_namespace
@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_fmusim_on_a_colleague_machine(exported: dict[str, Path], built: Path, scenario: str,
                                       tmp_path: Path) -> None:
    """fmusim with no Python on the machine runs the exported scenario for its full 30 s with its
    own DefaultExperiment; plant.y equals `run` within fmusim's printing, and `orchestrate metrics`
    on fmusim's CSV gives the table's row."""
    got = fmusim(exported[scenario], 30.0, tmp_path / "fmusim.csv")
    same(scenario, got, run(built / "ssp" / f"{scenario}.ssp"), rtol=FMUSIM_PRINT)
    assert main(["metrics", str(tmp_path / "fmusim.csv")]) == 0
    m = tracking_metrics(got["time"], got["plant.y"], got["reference.yd"], got["controller.v"])
    cells = TABLE[scenario]
    for value, cell in zip((m.rae, m.mse, m.rmse, m.mae), cells[:4], strict=True):
        decimals = len(cell.split(".")[1])
        assert round(value, decimals) == float(cell), (scenario, value, cell)
    if cells[4]:
        assert round(m.settling_time, 3) == float(cells[4])
        assert round(m.peak_v or 0.0) == int(cells[5].replace(" ", ""))


@needs_namespace
@pytest.mark.skipif(not FMUCHECK.is_file(), reason=f"fmuCheck not found at {FMUCHECK}")
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_fmucheck_on_a_colleague_machine(exported: dict[str, Path], built: Path, scenario: str,
                                         tmp_path: Path) -> None:
    """The compliance checker reports nothing, and its CSV (17 digits) holds run's plant.y bit for bit
    although its own time column is h summed."""
    out, log = tmp_path / "out.csv", tmp_path / "check.log"
    h = fmpy.read_model_description(str(exported[scenario])).defaultExperiment.stepSize
    command = [str(FMUCHECK), "-h", str(h), "-n", "0", "-s", repr(SHORT), "-o", str(out), "-e", str(log),
               str(exported[scenario])]
    result = subprocess.run(hidden(command), capture_output=True, text=True, timeout=600)
    report = log.read_text(errors="replace")
    assert result.returncode == 0, result.stdout + result.stderr + report
    assert "\t0 Error(s)" in report and "\t0 Warning(s)" in report, report
    same(scenario, read_csv(str(out)), run(built / "ssp" / f"{scenario}.ssp", stop_time=SHORT))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_fmpy_simulate_fmu(exported: dict[str, Path], built: Path, scenario: str) -> None:
    """FMPy's simulate_fmu (the host's Python; the FMU passes fmpy's validation): bit for bit."""
    fmu = str(exported[scenario])
    assert fmpy.validation.validate_fmu(fmu) == []
    h = fmpy.read_model_description(fmu).defaultExperiment.stepSize
    got = fmpy.simulate_fmu(fmu, stop_time=SHORT, output_interval=float(h))
    same(scenario, got, run(built / "ssp" / f"{scenario}.ssp", stop_time=SHORT))


def test_jacobi_parameters_and_units(built: Path, tmp_path: Path) -> None:
    """--master jacobi, --set with a unit (converted as run converts it), exposed Real and Integer
    parameters set by the host, and a host step of several scenario steps: equal to run bit for bit."""
    scenario = built / "ssp" / "example1.ssp"
    overrides = {"controller.k1": "12", "reference.omega": "2 rad/s"}
    fmu, exposed = export(scenario, tmp_path / "e.fmu", master="jacobi",
                          expose=["plant.y", "actuator.t_fault", "controller.mode"], overrides=overrides)
    kinds = [(str(e.port), e.kind, e.type) for e in exposed]
    assert kinds == [("controller.mode", "parameter", "Integer"), ("actuator.t_fault", "parameter", "Real"),
                     ("plant.y", "output", "Real")]
    with zipfile.ZipFile(fmu) as archive:
        assert b'needsExecutionTool="false"' in archive.read("modelDescription.xml")
    got = fmpy.simulate_fmu(str(fmu), stop_time=SHORT, output_interval=0.005,
                            start_values={"actuator.t_fault": 0.4, "controller.mode": 1})
    expected = run(scenario, stop_time=SHORT, master="jacobi",
                   overrides=overrides | {"actuator.t_fault": 0.4, "controller.mode": 1})
    same("example1 jacobi", got, expected[::5])
    default = run(scenario, stop_time=SHORT, master="jacobi")
    assert not np.array_equal(default["plant.y"][::5], got["plant.y"])  # the values were applied


def test_a_host_step_off_the_grid_fails(exported: dict[str, Path]) -> None:
    """A communication step that is not a multiple of the scenario's step fails the step (one
    message naming the grid) instead of stepping the FMUs on another grid."""
    messages: list[bytes] = []

    def logger(env: object, instance: bytes, status: int, category: bytes, message: bytes) -> None:
        messages.append(message)

    with pytest.raises(Exception, match="fmi2DoStep"):
        fmpy.simulate_fmu(str(exported["example1"]), stop_time=0.01, output_interval=0.0015, logger=logger)
    assert any(b"the step a positive multiple of 0.001 s" in m for m in messages), messages


def test_bad_options_are_refused(built: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One line each, exit status 2, nothing written; a target that cannot be written: one line,
    exit status 1, what is in the way left as it was."""
    target = tmp_path / "x.fmu"
    scenario = str(built / "ssp" / "example1.ssp")
    for extra, message in ((["--fmi", "4"], "argument --fmi: invalid choice: '4'"),
                           (["--expose", "plant.uf"], "plant.uf is an input fed by a connection"),
                           (["--expose", "nothing.*"], "--expose 'nothing.*' matches no output")):
        with pytest.raises(SystemExit) as stop:
            main(["export", scenario, "-o", str(target), *extra])
        assert stop.value.code == 2
        assert message in capsys.readouterr().err
    assert not target.exists() and not list(tmp_path.iterdir())
    blocked = tmp_path / "a file"
    blocked.write_text("kept")
    assert main(["export", scenario, "-o", str(blocked / "x.fmu")]) == 1
    assert f"cannot write {blocked / 'x.fmu'}" in capsys.readouterr().err
    assert blocked.read_text() == "kept"


def test_fmi3(built: Path, tmp_path: Path) -> None:
    """--fmi 3: the same container behind the FMI 3.0 API (the FMUs inside stay FMI 2.0). fmpy
    (FMI 3.0 host, Int32 and Float64 parameters set, jacobi) equals run bit for bit; fmusim on the
    colleague's machine within its printing; fmpy's validation passes."""
    scenario = built / "ssp" / "example1.ssp"
    fmu, _ = export(scenario, tmp_path / "loop3.fmu", fmi="3", master="jacobi",
                    expose=["plant.y", "controller.mode", "actuator.t_fault"])
    md = fmpy.read_model_description(str(fmu))
    assert md.fmiVersion == "3.0" and fmpy.validation.validate_fmu(str(fmu)) == []
    starts = {"controller.mode": 1, "actuator.t_fault": 0.4}
    got = fmpy.simulate_fmu(str(fmu), stop_time=SHORT, output_interval=0.005, start_values=starts)
    same("fmi3 jacobi", got, run(scenario, stop_time=SHORT, master="jacobi", overrides=starts)[::5])
    if NO_NAMESPACE is None and FMUSIM.is_file():
        plain, _ = export(scenario, tmp_path / "plain3.fmu", fmi="3")
        same("fmi3 fmusim", fmusim(plain, SHORT, tmp_path / "fmusim.csv"), run(scenario, stop_time=SHORT),
             rtol=FMUSIM_PRINT)


def test_an_exported_loop_inside_a_bigger_ssp(built: Path, tmp_path: Path) -> None:
    """example1 without its reference is exported (the controller's yd inputs become the FMU's
    inputs); a bigger SSP connects the Reference FMU to that FMU. Run by the engine, it equals
    example1 run flat, bit for bit: the container passes the inputs on and propagates again."""
    inner = tmp_path / "loop"
    shutil.copytree(REPO / "ssp" / "example1", inner)
    ssd = inner / "SystemStructure.ssd"
    tree = etree.parse(str(ssd))
    ns = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
    for element in tree.findall(".//ssd:Component[@name='reference']", ns) + tree.findall(
            ".//ssd:Connection[@startElement='reference']", ns):
        element.getparent().remove(element)
    tree.write(str(ssd))
    (inner / "reference.ssv").unlink()
    fmu, exposed = export(inner, tmp_path / "loop.fmu", fmu_dirs=[built / "fmus"])
    inputs = [str(e.port) for e in exposed if e.kind == "input"]
    assert inputs == ["controller.yd", "controller.yd_dot", "controller.yd_ddot"]
    outputs = [str(e.port) for e in exposed if e.kind == "output"]
    md = fmpy.read_model_description(str(fmu))
    v = next(u for u in md.outputs if u.variable.name == "controller.v")
    assert sorted(d.name for d in v.dependencies) == sorted(inputs)

    bound = read_parameter_set(REPO / "ssp" / "example1" / "reference.ssv")
    reference = {p.name: p.value for p in bound.parameters}
    names = ("yd", "yd_dot", "yd_ddot")
    outer = tmp_path / "outer"
    structure = SystemStructure("outer", (
        component("reference", "Reference.fmu", [(n, "output", "Real") for n in names], reference),
        component("loop", "loop.fmu", [(i, "input", "Real") for i in inputs]
                  + [(o, "output", "Real") for o in outputs]),
    ), tuple(Connection.between(f"reference.{n}", f"loop.controller.{n}") for n in names),
        Experiment(0.0, 2.0, 0.001))
    write_ssd(outer, structure)
    archive = pack_ssp(outer, {"Reference.fmu": built / "fmus" / "Reference.fmu", "loop.fmu": fmu},
                       tmp_path / "outer.ssp")
    got = run(archive)
    flat = run(built / "ssp" / "example1.ssp", stop_time=2.0)
    for column in ("plant.y", "controller.v", "actuator.uf"):
        np.testing.assert_array_equal(got[f"loop.{column}"], flat[column], err_msg=column)


def test_a_failing_fmu_inside_fails_the_step_as_run_reports_it(built: Path, tmp_path: Path) -> None:
    """The pendulum under jacobi at 1 ms diverges (README, "Delay-free and delayed masters"): run
    stops with one line naming component, function, status and time; the exported FMU (--step
    0.001) fails its step with fmi2Error and the same line through the host's logger."""
    scenario = built / "ssp" / "pendulum.ssp"
    with pytest.raises(SimulationError) as failure:
        run(scenario, master="jacobi", step=0.001, stop_time=0.1)
    fmu, _ = export(scenario, tmp_path / "p.fmu", master="jacobi", step=0.001, stop_time=0.1)
    messages: list[tuple[int, bytes]] = []

    def logger(env: object, instance: bytes, status: int, category: bytes, message: bytes) -> None:
        messages.append((status, message))

    with pytest.raises(Exception, match="fmi2DoStep failed with status 3"):
        fmpy.simulate_fmu(str(fmu), logger=logger)
    assert (3, str(failure.value).encode()) in messages, messages


def test_the_container_carries_one_runtime_per_platform(exported: dict[str, Path], built: Path) -> None:
    """example1's four FMUs share one runtime per platform (issue 46: the container was 40.9 MB,
    four copies of each): each interpreter once, under resources/fmus/_runtime/, no FMU with its
    own, and its standard-library zip holds every module each FMU's own zip held (read from the
    built FMUs). That they run on it: fmusim above, on a machine without Python."""
    with zipfile.ZipFile(exported["example1"]) as archive:
        names = archive.namelist()
        union = set(zipfile.ZipFile(io.BytesIO(archive.read(
            "resources/fmus/_runtime/linux64/python/python311.zip"))).namelist())
    assert [n for n in names if "libpython3.11.so" in n] == [
        "resources/fmus/_runtime/linux64/python/lib/libpython3.11.so.1.0.xz"]
    assert [n for n in names if "python311.dll" in n] == [
        "resources/fmus/_runtime/win64/python/python311.dll.xz"]
    assert not [n for n in names if re.match(r"resources/fmus/(?!_runtime/)[^/]+/binaries/[^/]+/python/", n)]
    components = {Path(c).name for c in component_sources(REPO / "ssp" / "example1")}
    for fmu in components:
        with zipfile.ZipFile(built / "fmus" / fmu) as archive:
            own = archive.read("binaries/linux64/python/python311.zip")
        assert set(zipfile.ZipFile(io.BytesIO(own)).namelist()) <= union, fmu


def test_runtimes_of_two_builds_are_not_merged() -> None:
    """Two FMUs whose runtime files differ (built by two builds) cannot share one folder: one line
    naming both FMUs and the file."""
    entries = {f"resources/fmus/{name}/binaries/linux64/python/lib/libpython3.11.so.1.0": data
               for name, data in (("A", b"one build"), ("B", b"another"))}
    with pytest.raises(ScenarioError, match=r"the FMUs A, B carry different lib/libpython3\.11\.so\.1\.0"):
        shared_runtimes(entries)
