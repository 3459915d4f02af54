# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate validate``: every check before a simulation, every problem at once.

Broken scenarios are made with a known number of faults, one per stage (schema, parameter file,
FMU, connection, parameter value, unconnected input, algebraic loop, unit); the oracle is that
list of injected faults: each must be reported, naming its file, component and connector, and
nothing else may be. fmpy's own ``validate_fmu`` is the oracle for what the FMU check finds.
"""

from __future__ import annotations

import os
import re
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest
from fmpy.validation import validate_fmu
from lxml import etree
from orch_helpers import loop_scenario, without_start

import orchestrator
from orchestrator import RunOptions, ScenarioError
from orchestrator.cli import main
from orchestrator.ssp import NS, SSD_NAME, Connection, Experiment, SystemStructure, component, write_ssd
from orchestrator.validate import validate

pytestmark = pytest.mark.system

REPO = Path(__file__).resolve().parent.parent
SCENARIOS = ["example1", "example1_finite_time", "example1_no_fault", "pendulum", "pendulum_finite_time"]
GAIN = [("u", "input", "Real"), ("y", "output", "Real")]
INTEGRATOR = [("u", "input", "Real"), ("x", "output", "Real")]


def edit_fmu(fmu: Path, dest: Path, edit: Callable[[str], str]) -> Path:
    """Copy of ``fmu`` whose modelDescription.xml is ``edit(text)``."""
    with zipfile.ZipFile(fmu) as zf:
        files = {i.filename: zf.read(i) for i in zf.infolist()}
    files["modelDescription.xml"] = edit(files["modelDescription.xml"].decode()).encode()
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return dest


def with_units(fmu: Path, dest: Path, units: dict[str, str], definitions: str) -> Path:
    """Copy of ``fmu`` whose Real variables carry ``units`` (variable -> unit), defined by the
    ``<Unit>`` elements in ``definitions``."""
    def edit(xml: str) -> str:
        xml = xml.replace("<LogCategories>", f"<UnitDefinitions>{definitions}</UnitDefinitions>"
                          "<LogCategories>", 1)
        for variable, unit in units.items():
            xml = re.sub(rf'(<ScalarVariable name="{variable}"[^>]*>\s*<Real)', rf'\1 unit="{unit}"', xml)
        return xml
    return edit_fmu(fmu, dest, edit)


def scenario(folder: Path, fmus: dict[str, Path], components: list, connections: list[tuple[str, str]],
             stop: float | None = 1.0) -> Path:
    """Write a scenario folder: components from orchestrator.ssp.component, FMUs copied into
    resources/ (name in the SSD -> file)."""
    structure = SystemStructure("s", tuple(components),
                                tuple(Connection.between(a, b) for a, b in connections),
                                Experiment(0.0, stop, 0.01))
    write_ssd(folder, structure)
    (folder / "resources").mkdir()
    for name, path in fmus.items():
        (folder / "resources" / name).write_bytes(path.read_bytes())
    return folder


def snapshot(folder: Path) -> dict[str, tuple[int, bytes]]:
    """Every file under ``folder``: modification time and content."""
    return {str(p.relative_to(folder)): (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(folder.rglob("*")) if p.is_file()}


def errors(report) -> list[str]:
    return [p.message for p in report.errors]


def ssd_counts(ssd: Path) -> tuple[int, int, int]:
    """Components, connections and bound parameter values, counted from the SSD source and its
    .ssv files with lxml (independent of the reader)."""
    root = etree.parse(str(ssd)).getroot()
    components = root.findall("ssd:System/ssd:Elements/ssd:Component", NS)
    parameters = 0
    for binding in root.iterfind(".//ssd:ParameterBinding", NS):
        ssv = etree.parse(str(ssd.parent / binding.get("source"))).getroot()
        parameters += len(ssv.findall("ssv:Parameters/ssv:Parameter", NS))
    return len(components), len(root.findall("ssd:System/ssd:Connections/ssd:Connection", NS)), parameters


@pytest.mark.parametrize("name", SCENARIOS)
def test_shipped_scenarios_validate_clean(built, name, capsys):
    """No error and no warning; the counts are those of the scenario's source files."""
    archive = built / "ssp" / f"{name}.ssp"
    report = validate(archive)
    assert report.problems == ()
    components, connections, parameters = ssd_counts(REPO / "ssp" / name / SSD_NAME)
    assert (report.components, report.connections, report.parameters) == (components, connections, parameters)
    assert main(["validate", str(archive)]) == 0
    assert capsys.readouterr().out == (f"ok: {archive}: {components} components, {connections} connections, "
                                       f"{parameters} parameters checked\n")


def test_project_fmus_pass_fmpy_validation(fmus):
    """fmpy's validate_fmu finds nothing in the FMUs the project builds (nine since issue 35)."""
    assert len(fmus) == 9
    for path in fmus.values():
        assert validate_fmu(str(path)) == [], path.name


def test_every_stage_reported_at_once(tmp_path, test_fmus):
    """Seven faults in seven stages, one of them an unreadable FMU: all seven are reported (and
    nothing else), including the connections and parameters that do not involve the broken FMU;
    ``run`` refuses the scenario with the same list."""
    fmus = {
        "Source.fmu": edit_fmu(test_fmus["Source"], tmp_path / "Source.fmu", lambda xml: xml[:-60]),
        "Gain.fmu": edit_fmu(test_fmus["Gain"], tmp_path / "Gain.fmu", lambda xml: xml.replace(
            '<Real start="1"/>', '<Real start="1" min="0" max="10"/>')),
        "Integrator.fmu": test_fmus["Integrator"],
        "GainNoStart.fmu": without_start(test_fmus["Gain"], "u", tmp_path / "GainNoStart.fmu"),
    }
    folder = scenario(tmp_path / "s", fmus, [
        component("source", "Source.fmu", [("y", "output", "Real")], {"amplitude": 2.0}),
        component("gain", "Gain.fmu", GAIN, {"k": 2.0}),
        component("integrator", "Integrator.fmu", INTEGRATOR, {"x00": 1.0}),   # (1) no such variable
        component("a", "Gain.fmu", GAIN),
        component("b", "Gain.fmu", GAIN),
        component("c", "GainNoStart.fmu", GAIN),                                # (2) c.u: no value
    ], [
        ("integrator.x", "gain.u"), ("gain.y", "integrator.u"),
        ("a.y", "b.u"), ("b.y", "a.u"),                                          # (3) loop: a warning
        ("source.y", "c.y"),                                                     # (4) c.y is an output
    ])
    ssd = folder / SSD_NAME
    text = ssd.read_text()
    ssd.write_text(text.replace('<ssd:System name="s"', '<ssd:System colour="red" name="s"'))  # (5) schema
    # (6) the FMU source has a truncated modelDescription; (7) gain.k above its max
    before = snapshot(tmp_path)
    report = validate(folder, overrides={"gain.k": "20"})
    assert snapshot(tmp_path) == before

    label = str(ssd)
    found = errors(report)
    expected = [
        r"^integrator\.ssv: component 'integrator' has no variable 'x00'$",
        rf"^{re.escape(label)}: component 'c', input 'u' is neither connected nor has a start value$",
        rf"^{re.escape(label)}: connection source\.y -> c\.y: c\.y is an output, not an input$",
        rf"^{re.escape(label)} line \d+: .*System.*'colour'",
        rf"^{re.escape(label)}: component 'source': FMU 'Source\.fmu': cannot read modelDescription\.xml",
        r"^overrides: gain\.k = 20\.0 is above the FMU's max 10$",  # the API's field (issue 36)
    ]
    for pattern in expected:
        assert sum(bool(re.search(pattern, p)) for p in found) == 1, (pattern, found)
    assert len(found) == len(expected), found
    assert not report.ok
    assert [p for p in report.problems if p.severity == "warning" and "loop: a.u -> a.y" in p.message]

    with pytest.raises(ScenarioError) as info:
        orchestrator.run(folder, RunOptions(overrides={"gain.k": "20"}))
    assert info.value.problems == found


def test_broken_model_descriptions(tmp_path, test_fmus):
    """Three broken FMUs (not XML; an illegal causality/variability, which fmpy refuses to read; an
    undefined unit) are reported by component and FMU file, in fmpy's own words; the parameters
    of a fourth, sound component are still checked."""
    fmus = {
        "Gain.fmu": edit_fmu(test_fmus["Gain"], tmp_path / "Gain.fmu", lambda xml: "<fmiModelDescription"),
        "Integrator.fmu": edit_fmu(test_fmus["Integrator"], tmp_path / "Integrator.fmu",
                                   lambda xml: re.sub(r'(name="x0"[^>]*)variability="\w+"',
                                                      r'\1variability="continuous"', xml)),
        "Source.fmu": edit_fmu(test_fmus["Source"], tmp_path / "Source.fmu",
                               lambda xml: xml.replace("<Real/>", '<Real unit="furlong"/>')),
        "Good.fmu": test_fmus["Gain"],
    }
    folder = scenario(tmp_path / "s", fmus, [
        component("gain", "Gain.fmu", GAIN, {"k": 2.0}),
        component("integrator", "Integrator.fmu", INTEGRATOR),
        component("source", "Source.fmu", [("y", "output", "Real")]),
        component("good", "Good.fmu", GAIN, {"kk": 2.0}),
    ], [("integrator.x", "gain.u"), ("gain.y", "integrator.u"), ("source.y", "good.u")])
    (illegal,) = validate_fmu(str(fmus["Integrator.fmu"]))
    (furlong,) = [p for p in validate_fmu(str(fmus["Source.fmu"])) if "furlong" in p]
    label = str(folder / SSD_NAME)
    undefined = f"{label}: component 'source': FMU 'Source.fmu': {furlong}"
    report = validate(folder)
    found = errors(report)
    assert len(found) == 3, found
    unreadable = "cannot read modelDescription.xml"
    assert found[0].startswith(f"{label}: component 'gain': FMU 'Gain.fmu': {unreadable}: ")
    assert found[1] == f"{label}: component 'integrator': FMU 'Integrator.fmu': {unreadable}: {illegal}"
    assert found[2] == "good.ssv: component 'good' has no variable 'kk'"
    # an undefined unit does not stop the FMU (OMSimulator and libcosim load it): a warning since
    # issue 32, an error with strict_fmus (--strict-fmus, for CI)
    assert [p.severity for p in report.problems if p.message == undefined] == ["warning"]
    assert errors(validate(folder, strict_fmus=True))[2] == undefined
    assert main(["validate", str(folder)]) == 1


def test_pythonfmu_without_initial_unknowns_is_a_warning(tmp_path, test_fmus, capsys):
    """pythonfmu writes no ModelStructure/InitialUnknowns: fmpy's validate_fmu flags it, validate
    reports it as a warning (exit 0), and run does not need it: the scenario runs."""
    for name, path in test_fmus.items():
        assert [p for p in validate_fmu(str(path)) if "InitialUnknowns" in p], name
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    report = validate(folder)
    assert report.ok and report.errors == []
    label = str(folder / SSD_NAME)
    warned = sorted(p.message.split(":")[1].strip() for p in report.problems)
    assert warned == ["component 'gain'", "component 'integrator'", "component 'source'"]
    assert all(p.severity == "warning" and "InitialUnknowns" in p.message and p.message.startswith(label)
               for p in report.problems)
    assert main(["validate", str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in out] == ["warning"] * 3 + ["ok"]
    assert len(orchestrator.run(folder, RunOptions(stop_time=0.05)).rows) == 6


def test_units_where_both_sides_declare_them(tmp_path, test_fmus):
    """m -> s is a mismatch; m -> metre (the same SI definition) is not; a side without unit is not
    checked. A linear transformation does not make m -> s convertible (SSP 1.0.1 4.5.2.1: the unit
    conversion comes first; issue 43), unless suppressUnitConversion says it is the conversion."""
    metre = '<Unit name="m"><BaseUnit m="1"/></Unit><Unit name="metre"><BaseUnit m="1"/></Unit>'
    second = '<Unit name="s"><BaseUnit s="1"/></Unit>'
    fmus = {
        "IntegratorM.fmu": with_units(test_fmus["Integrator"], tmp_path / "IM.fmu", {"x": "m", "u": "m"},
                                      metre),
        "GainS.fmu": with_units(test_fmus["Gain"], tmp_path / "GS.fmu", {"u": "s", "y": "s"}, second),
        "GainMetre.fmu": with_units(test_fmus["Gain"], tmp_path / "GM.fmu", {"u": "metre"}, metre),
        "Gain.fmu": test_fmus["Gain"],
    }
    folder = scenario(tmp_path / "s", fmus, [
        component("plant", "IntegratorM.fmu", INTEGRATOR),
        component("timer", "GainS.fmu", GAIN),
        component("ruler", "GainMetre.fmu", GAIN),
        component("plain", "Gain.fmu", GAIN),
    ], [("plant.x", "timer.u"), ("plant.x", "ruler.u"), ("plant.x", "plain.u"), ("plain.y", "plant.u")])
    label = str(folder / SSD_NAME)
    assert errors(validate(folder)) == [
        f"{label}: connection plant.x -> timer.u: unit mismatch (plant.x is in m, timer.u in s)"]
    ssd = folder / SSD_NAME
    ssd.write_text(ssd.read_text().replace(
        'endElement="timer" endConnector="u"/>',
        'endElement="timer" endConnector="u"><ssc:LinearTransformation factor="0.5"/></ssd:Connection>'))
    assert errors(validate(folder)) == [
        f"{label}: connection plant.x -> timer.u: unit mismatch (plant.x is in m, timer.u in s) (if the "
        'LinearTransformation is meant as the conversion, set suppressUnitConversion="true" on the '
        "connection)"]
    timer = 'endElement="timer" endConnector="u"'
    ssd.write_text(ssd.read_text().replace(f"{timer}>", f'{timer} suppressUnitConversion="true">'))
    assert errors(validate(folder)) == []


def test_every_algebraic_loop_is_reported(tmp_path, test_fmus):
    """Two separate rings: two loops, each named by its ports, as warnings (gauss-seidel iterates
    them, jacobi has none: no error since issue 32)."""
    folder = scenario(tmp_path / "s", {"Gain.fmu": test_fmus["Gain"]},
                      [component(n, "Gain.fmu", GAIN) for n in "abcd"],
                      [("a.y", "b.u"), ("b.y", "a.u"), ("c.y", "d.u"), ("d.y", "c.u")])
    label = str(folder / SSD_NAME)
    report = validate(folder)
    assert errors(report) == []
    loops = [p.message.split(" (")[0] for p in report.problems if "algebraic loop" in p.message]
    assert loops == [f"{label}: algebraic loop: a.u -> a.y -> b.u -> b.y -> a.u",
                     f"{label}: algebraic loop: c.u -> c.y -> d.u -> d.y -> c.u"]


def test_hostile_archive_and_the_rest_reported_user_files_intact(tmp_path, test_fmus, capsys):
    """A member escaping the folder is refused (the user's file is untouched) and the archive's
    other problems, a broken parameter file and a dangling connection, are reported with it."""
    good = loop_scenario(tmp_path / "s", test_fmus)
    with zipfile.ZipFile(good) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    members["../precious.txt"] = b"overwritten"
    members["gain.ssv"] = b"<ssv:ParameterSet"
    members[SSD_NAME] = members[SSD_NAME].replace(b'endElement="gain" endConnector="u"',
                                                  b'endElement="gain" endConnector="w"')
    bad = tmp_path / "bad.ssp"
    with zipfile.ZipFile(bad, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    (tmp_path / "precious.txt").write_text("mine")
    before = snapshot(tmp_path)
    found = errors(validate(bad))
    assert snapshot(tmp_path) == before
    label = f"{bad}:{SSD_NAME}"
    assert len(found) == 3, found
    assert found[0] == "bad.ssp: member '../precious.txt' points outside the archive folder"
    assert found[1].startswith(f"{label}: gain.ssv: broken XML")
    assert found[2] == (f"{label}: connection integrator.x -> gain.w: component 'gain' declares no "
                        "connector 'w'")
    # gain's parameters were lost with its file: its input u is not reported as lacking a value
    assert main(["validate", str(bad)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[:3] == [f"error: {p}" for p in found]
    assert out[-1] == f"failed: {bad}: 3 error(s), 3 warning(s)"  # the test FMUs' InitialUnknowns


def test_parameter_files_and_overrides_as_for_run(tmp_path, test_fmus, built, monkeypatch, capsys):
    """--parameter-set and --set are checked as run applies them; a built scenario is found by
    name; a malformed --set is a usage error (2)."""
    ssv = tmp_path / "p.ssv"
    ssv.write_text('<?xml version="1.0" encoding="UTF-8"?>\n'
                   f'<ssv:ParameterSet xmlns:ssv="{NS["ssv"]}" version="1.0" name="p"><ssv:Parameters>'
                   '<ssv:Parameter name="controller.k1"><ssv:Real value="12"/></ssv:Parameter>'
                   '<ssv:Parameter name="controller.nothere"><ssv:Real value="1"/></ssv:Parameter>'
                   '</ssv:Parameters></ssv:ParameterSet>\n')
    (tmp_path / "build").symlink_to(built)
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "example1", "--parameter-set", "p.ssv", "--set", "plant.x1=1"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[:2] == ["error: p.ssv: component 'controller' has no variable 'nothere'",
                       "error: --set: plant.x1 is a continuous output, it cannot be set"]
    assert len(out) == 3
    assert main(["validate", "example1", "--set", "controller.k1=12"]) == 0
    components, connections, parameters = ssd_counts(REPO / "ssp" / "example1" / SSD_NAME)
    assert capsys.readouterr().out == (f"ok: {os.path.join('build', 'ssp', 'example1.ssp')}: {components} "
                                       f"components, {connections} connections, {parameters + 1} parameters "
                                       "checked\n")
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", "example1", "--set", "k1"])
    assert exit_info.value.code == 2
    assert main(["validate", "no_such_scenario"]) == 1


def test_experiment_times(tmp_path, test_fmus):
    """A stop time before the start time is an error; no stop time at all is a warning (run then
    needs --stop-time)."""
    fmus = {"Gain.fmu": test_fmus["Gain"]}
    pair = [component("g", "Gain.fmu", GAIN), component("h", "Gain.fmu", GAIN)]
    backwards = scenario(tmp_path / "b", fmus, pair, [("g.y", "h.u")], stop=-1.0)
    label = str(backwards / SSD_NAME)
    assert errors(validate(backwards)) == [f"{label}: the stop time -1.0 s is before the start time 0.0 s"]
    open_ended = scenario(tmp_path / "o", fmus, pair, [("g.y", "h.u")], stop=None)
    report = validate(open_ended)
    assert report.ok
    assert f"{open_ended / SSD_NAME}: no stopTime in DefaultExperiment; 'run' needs --stop-time" in [
        p.message for p in report.problems if p.severity == "warning"]
