# SPDX-License-Identifier: BSD-2-Clause
"""Reading SSP scenarios: schema validity of what we write, the parts fmpy's reader drops, and
hostile or broken archives (each a clear ScenarioError naming the file, user files untouched)."""

from __future__ import annotations

import zipfile
from contextlib import ExitStack
from pathlib import Path

import pytest
from fmpy.ssp.ssd import read_ssd
from lxml import etree
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions, ScenarioError
from orchestrator.ssp import NS, ParameterSet, open_scenario, read_parameter_set, read_scenario, write_ssv

pytestmark = pytest.mark.system

REPO = Path(__file__).resolve().parent.parent
# scenario -> its communication step as written (the pendulum's 0.5 ms: see ssp/generate.py)
SCENARIOS = {"example1": "0.001", "example1_finite_time": "0.001", "example1_no_fault": "0.001",
             "pendulum": "0.0005", "pendulum_finite_time": "0.001"}


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_sources_follow_the_spec(name):
    """SSP 1.0, literal prefixes, tool namespaces on the root, typed connectors, one binding per
    component, the step in both tool annotations; the schema check is inside read_scenario."""
    ssd = REPO / "ssp" / name / "SystemStructure.ssd"
    text = ssd.read_text()
    root = etree.fromstring(text.encode())
    assert root.get("version") == "1.0"
    assert root.prefix == "ssd" and {"ssd", "ssc", "ssv", "osp", "oms"} <= set(root.nsmap)
    components = root.findall("ssd:System/ssd:Elements/ssd:Component", NS)
    assert [c.get("name") for c in components] == ["reference", "controller", "actuator", "plant"]
    for c in components:
        assert len(c.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)) == 1
        for k in c.findall("ssd:Connectors/ssd:Connector", NS):
            assert k.get("kind") in ("input", "output") and k.find("ssc:Real", NS) is not None
    assert root.find("ssd:System/ssd:ParameterBindings", NS) is None
    step = SCENARIOS[name]
    assert f'baseStepSize="{step}" numWorkerThreads="0"' in text and f'stepSize="{step}"' in text
    for ssv in ssd.parent.glob("*.ssv"):
        assert read_parameter_set(ssv).parameters
    with pytest.raises(ScenarioError, match="is missing"):  # valid XML; only the FMUs are absent
        read_scenario(ssd.parent)


def test_reads_what_fmpy_drops(tmp_path, test_fmus):
    """ssc:LinearTransformation, DefaultExperiment and the step annotation, which
    fmpy.ssp.ssd.read_ssd does not deliver."""
    ssp = loop_scenario(tmp_path / "s", test_fmus, factor=2.5, offset=-0.25, stop=3.0, step=0.02)
    fmpy_view = read_ssd(str(ssp))
    assert not any(hasattr(c, "linearTransformation") for c in fmpy_view.system.connections)
    assert fmpy_view.defaultExperiment is None
    with ExitStack() as stack:
        structure = read_scenario(open_scenario(ssp, stack))
    (link,) = [c for c in structure.connections if c.end.component == "integrator"]
    assert (link.factor, link.offset) == (2.5, -0.25)
    assert (structure.experiment.start_time, structure.experiment.stop_time, structure.experiment.step) == (
        0.0, 3.0, 0.02)


def test_step_from_either_tool_annotation(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, step=0.02, pack=False)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    ssd.write_text(text.replace('stepSize="0.02"', 'stepSize="0.05"'))
    assert read_scenario(folder).experiment.step == 0.02  # libcosim's annotation first
    start = text.index("<ssd:Annotations>\n      <ssc:Annotation type=\"com.opensimulationplatform\"")
    end = text.index("</ssd:Annotations>", start) + len("</ssd:Annotations>")
    ssd.write_text(text[:start] + text[end:])
    assert read_scenario(folder).experiment.step == 0.02  # OMSimulator's annotation
    result = orchestrator.run(folder, RunOptions(stop_time=0.1)).rows
    assert len(result) == 6


def _zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def test_archive_escaping_the_folder_is_refused(tmp_path, test_fmus):
    good = loop_scenario(tmp_path / "s", test_fmus)
    with zipfile.ZipFile(good) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    user_file = tmp_path / "precious.txt"
    user_file.write_text("mine")
    for evil in ("../precious.txt", "/tmp/precious.txt", "resources/../../precious.txt"):
        bad = _zip(tmp_path / "bad.ssp", {**members, evil: b"overwritten"})
        with pytest.raises(ScenarioError, match=r"bad\.ssp: member .* points outside"):
            orchestrator.run(bad)
        assert user_file.read_text() == "mine"


def test_symlink_member_is_refused(tmp_path, test_fmus):
    good = loop_scenario(tmp_path / "s", test_fmus)
    bad = tmp_path / "link.ssp"
    bad.write_bytes(good.read_bytes())
    with zipfile.ZipFile(bad, "a") as zf:
        info = zipfile.ZipInfo("resources/link")
        info.external_attr = (0o120777 << 16)
        zf.writestr(info, "/etc/passwd")
    with pytest.raises(ScenarioError, match="symbolic link"):
        orchestrator.run(bad)


@pytest.mark.parametrize("case, message", [
    ("not_a_zip", r"not a valid SSP \(zip\) archive"),
    ("no_ssd", r"no SystemStructure\.ssd at the root"),
    ("missing_fmu", r"component 'gain': FMU 'resources/Gain\.fmu' is missing"),
    ("broken_ssd", r"SystemStructure\.ssd: broken XML"),
    ("broken_ssv", r"gain\.ssv: broken XML"),
    ("invalid_ssd", r"SystemStructure\.ssd line \d+: .*Connektor"),
    ("missing_ssv", r"gain\.ssv: file is missing"),
])
def test_broken_archives_name_the_file(tmp_path, test_fmus, case, message):
    good = loop_scenario(tmp_path / "s", test_fmus)
    with zipfile.ZipFile(good) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    ssd = members["SystemStructure.ssd"].decode()
    if case == "not_a_zip":
        bad = tmp_path / "bad.ssp"
        bad.write_bytes(b"PK\x03\x04 this is not a zip")
    else:
        if case == "no_ssd":
            del members["SystemStructure.ssd"]
        elif case == "missing_fmu":
            del members["resources/Gain.fmu"]
        elif case == "broken_ssd":
            members["SystemStructure.ssd"] = ssd[:-40].encode()
        elif case == "broken_ssv":
            members["gain.ssv"] = b"<ssv:ParameterSet"
        elif case == "invalid_ssd":
            members["SystemStructure.ssd"] = ssd.replace("ssd:Connector ", "ssd:Connektor ", 1).replace(
                "</ssd:Connector>", "</ssd:Connektor>", 1).encode()
        elif case == "missing_ssv":
            del members["gain.ssv"]
        bad = _zip(tmp_path / "bad.ssp", members)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(ScenarioError, match=message):
        orchestrator.run(bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_parameter_set_prefix_and_types(tmp_path):
    path = tmp_path / "p.ssv"
    write_ssv(path, ParameterSet.of("p.ssv", {"gain.k": 3.0, "integrator.n": 4, "flag": True}))
    ps = read_parameter_set(path)
    assert [(p.name, p.type, p.value) for p in ps.parameters] == [
        ("gain.k", "Real", 3.0), ("integrator.n", "Integer", 4), ("flag", "Boolean", True)]
    with pytest.raises(ScenarioError, match="does not start with the prefix 'gain.'"):
        read_parameter_set(path, prefix="gain.")


def test_object_model_round_trip(tmp_path):
    """Written with lxml, read back by the reader: the same structure (every field, including
    parameter types, a linear transformation, the step in both tool annotations), and writing what
    was read gives the same bytes again."""
    from dataclasses import replace

    from orchestrator.ssp import Connection, Experiment, SystemStructure, component, read_scenario, write_ssd

    written = SystemStructure(
        "rt & <co>", (
            component("a", "A.fmu", [("y", "output", "Real"), ("n", "output", "Integer")],
                      {"k": 2.5, "count": 3, "flag": True, "label": "x < y & z"}),
            component("b", "B.fmu", [("u", "input", "Real"), ("on", "input", "Boolean")]),
        ),
        (Connection.between("a.y", "b.u", 2.5, -0.25), Connection.between("a.n", "b.u")),
        Experiment(0.5, 3.0, 0.02), "quotes \" and 'apostrophes'")
    first = tmp_path / "first"
    write_ssd(first, written)
    (first / "resources").mkdir()
    for name in ("A.fmu", "B.fmu"):
        (first / "resources" / name).write_bytes(b"not read here")
    read = read_scenario(first)
    assert read.ssd_file == str(first / "SystemStructure.ssd")
    resolved = tuple(replace(c, source=first / c.source) for c in written.components)
    assert replace(read, ssd_file="") == replace(written, components=resolved)
    assert [p.type for p in read.components[0].parameter_sets[0].parameters] == [
        "Real", "Integer", "Boolean", "String"]
    second = tmp_path / "second"
    write_ssd(second, replace(read, components=tuple(replace(c, source=c.source.relative_to(first))
                                                         for c in read.components)))
    for name in ("SystemStructure.ssd", "a.ssv"):
        assert (second / name).read_bytes() == (first / name).read_bytes(), name


def test_a_system_without_connections_is_written_schema_valid(tmp_path):
    """SSP's schema wants at least one Connection inside a Connections element: a system of one
    component is written without it and reads back (the schema check is inside read_scenario)."""
    from orchestrator.ssp import Experiment, SystemStructure, component, read_scenario, write_ssd

    alone = SystemStructure("alone", (component("a", "A.fmu", [("y", "output", "Real")]),), (),
                            Experiment(0.0, 1.0, 0.1))
    write_ssd(tmp_path, alone)
    (tmp_path / "resources").mkdir()
    (tmp_path / "resources" / "A.fmu").write_bytes(b"not read here")
    assert "Connections" not in (tmp_path / "SystemStructure.ssd").read_text()
    assert read_scenario(tmp_path).connections == ()
