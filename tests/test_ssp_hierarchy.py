# SPDX-License-Identifier: BSD-2-Clause
"""Nested systems, system-level parameter bindings and SSP parameter mappings (issue 32), on small
pythonfmu gains (``y = k u``) whose values follow by hand from the SSD: connections through system
connectors compose their LinearTransformations, bindings apply in SSP 1.0's precedence (a system's
over its subsystems' and components', later over earlier), a mapping renames and transforms
(``factor * value + offset``), and every mistake is one line naming its file and entry. On main
before issue 32 each of these SSDs was refused ("nested systems are not supported", "parameter
bindings on the system are not supported"), and a component's mapping was ignored."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import pytest

import orchestrator
from orchestrator import RunOptions, ScenarioError
from orchestrator.cli import main
from orchestrator.ssp import Parameter, ParameterSet, _mapped, _Mapping
from orchestrator.validate import validate

# other tools' files leave inputs unconnected: the warnings are theirs, and validate's are asserted
pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")]

HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription version="1.0" name="nested" '
        'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
        'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
        'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping">')
GAIN = ('<ssd:Connectors><ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>'
        '<ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>')


def _values(**values: float) -> str:
    """An inline ssv:ParameterSet."""
    parameters = "".join(f'<ssv:Parameter name="{k.replace("__", ".")}"><ssv:Real value="{v!r}"/>'
                         '</ssv:Parameter>' for k, v in values.items())
    return (f'<ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>{parameters}'
            '</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>')


SSD = HEAD + f"""
<ssd:System name="top">
  <ssd:ParameterBindings>
    <ssd:ParameterBinding>{_values(src__u=3.0, src__k=2.0, sub__g__k=0.5)}</ssd:ParameterBinding>
    <ssd:ParameterBinding source="p.ssv"><ssd:ParameterMapping source="p.ssm"/></ssd:ParameterBinding>
  </ssd:ParameterBindings>
  <ssd:Elements>
    <ssd:Component name="src" source="resources/Gain.fmu">{GAIN}</ssd:Component>
    <ssd:System name="sub">
      <ssd:Connectors>
        <ssd:Connector name="in" kind="input"><ssc:Real/></ssd:Connector>
        <ssd:Connector name="out" kind="output"><ssc:Real/></ssd:Connector>
      </ssd:Connectors>
      <ssd:ParameterBindings><ssd:ParameterBinding>{_values(g__k=100.0)}</ssd:ParameterBinding>
      </ssd:ParameterBindings>
      <ssd:Elements>
        <ssd:Component name="g" source="resources/Gain.fmu">{GAIN}
          <ssd:ParameterBindings><ssd:ParameterBinding>{_values(k=7.0)}</ssd:ParameterBinding>
          </ssd:ParameterBindings>
        </ssd:Component>
      </ssd:Elements>
      <ssd:Connections>
        <ssd:Connection startConnector="in" endElement="g" endConnector="u">
          <ssc:LinearTransformation factor="2" offset="1"/></ssd:Connection>
        <ssd:Connection startElement="g" startConnector="y" endConnector="out"/>
      </ssd:Connections>
    </ssd:System>
    <ssd:Component name="sink" source="resources/Gain.fmu">{GAIN}</ssd:Component>
  </ssd:Elements>
  <ssd:Connections>
    <ssd:Connection startElement="src" startConnector="y" endElement="sub" endConnector="in">
      <ssc:LinearTransformation factor="10"/></ssd:Connection>
    <ssd:Connection startElement="sub" startConnector="out" endElement="sink" endConnector="u"/>
  </ssd:Connections>
</ssd:System>
<ssd:DefaultExperiment startTime="0" stopTime="0.1"/>
</ssd:SystemStructureDescription>
"""
SSV = ('<?xml version="1.0"?><ssv:ParameterSet version="1.0" name="p" '
       'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"><ssv:Parameters>'
       '<ssv:Parameter name="gain_a"><ssv:Real value="4"/></ssv:Parameter>'
       '</ssv:Parameters></ssv:ParameterSet>')
SSM = ('<?xml version="1.0"?><ssm:ParameterMapping '
       'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping" '
       'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0">'
       '<ssm:MappingEntry source="gain_a" target="{target}">'
       '<ssc:LinearTransformation factor="0.5" offset="1"/>'
       '</ssm:MappingEntry></ssm:ParameterMapping>')


def _scenario(folder: Path, gain: Path, ssd: str = SSD, target: str = "sink.k") -> Path:
    (folder / "resources").mkdir(parents=True)
    shutil.copy(gain, folder / "resources" / "Gain.fmu")
    (folder / "SystemStructure.ssd").write_text(ssd)
    (folder / "p.ssv").write_text(SSV)
    (folder / "p.ssm").write_text(SSM.format(target=target))
    return folder


def test_nested_system_flattened_with_bindings_in_precedence(tmp_path, test_fmus) -> None:
    """src.y = 2 * 3 = 6; sub.g.u = 2 * (10 * 6) + 1 = 121 (two transformations composed through the
    system connector); sub.g.k = 0.5 (the top system's binding over sub's 100 and g's own 7);
    sink.k = 0.5 * 4 + 1 = 3 (p.ssv through p.ssm); sink.y = 3 * 0.5 * 121 = 181.5. --set comes last."""
    folder = _scenario(tmp_path / "s", test_fmus["Gain"])
    rows = orchestrator.run(folder, RunOptions(step=0.05)).rows
    assert set(rows.dtype.names) == {"time", "src.u", "sub.g.u", "sink.u", "src.y", "sub.g.y", "sink.y"}
    assert (rows["sub.g.u"][-1], rows["sub.g.y"][-1], rows["sink.y"][-1]) == (121.0, 60.5, 181.5)
    with orchestrator.open_system(folder) as system:
        assert system.components["sub.g"].origins["k"].endswith("(inline values of 'the system')")
        assert system.components["sink"].origins["k"] == "p.ssm: MappingEntry 'gain_a' -> 'sink.k'"
    rows = orchestrator.run(folder, RunOptions(step=0.05, overrides={"sub.g.k": 1})).rows
    assert rows["sub.g.y"][-1] == 121.0
    assert main(["validate", str(folder)]) == 0


def test_a_mapping_target_that_does_not_exist_is_one_line_naming_the_entry(tmp_path, test_fmus) -> None:
    folder = _scenario(tmp_path / "a", test_fmus["Gain"], target="sink.kk")
    assert [e.message for e in validate(folder).errors] == [
        "p.ssm: MappingEntry 'gain_a' -> 'sink.kk': component 'sink' has no variable 'kk'"]
    folder = _scenario(tmp_path / "b", test_fmus["Gain"], target="nowhere.k")
    assert [e.message for e in validate(folder).errors] == [
        "p.ssm: MappingEntry 'gain_a' -> 'nowhere.k': the target 'nowhere.k' names no element or connector "
        "of system 'top'"]


def test_a_components_own_mapping_applies(tmp_path, test_fmus) -> None:
    """The issue's report: an .ssm on a component was ignored, then 'gain' reported as a missing
    variable; mapped (gain_a -> k, 0.5 * 4 + 1), sink's k is 3."""
    ssd = SSD.replace('<ssd:Component name="sink" source="resources/Gain.fmu">' + GAIN,
                      '<ssd:Component name="sink" source="resources/Gain.fmu">' + GAIN +
                      '<ssd:ParameterBindings><ssd:ParameterBinding source="p.ssv"><ssd:ParameterMapping '
                      'source="p.ssm"/></ssd:ParameterBinding></ssd:ParameterBindings>')
    ssd = ssd.replace('<ssd:ParameterBinding source="p.ssv"><ssd:ParameterMapping source="p.ssm"/>'
                      '</ssd:ParameterBinding>\n  </ssd:ParameterBindings>', '</ssd:ParameterBindings>', 1)
    folder = _scenario(tmp_path / "s", test_fmus["Gain"], ssd, target="k")
    with orchestrator.open_system(folder) as system:
        assert system.components["sink"].start_values["k"] == 3.0


def test_a_name_matching_nothing_in_a_system_binding_is_ignored_with_a_note(tmp_path, test_fmus) -> None:
    """SSP 1.0: names a system's parameter source has that match nothing are ignored (OMSimulator's
    embrace files carry such names); not silently: a warning naming the file and the name."""
    ssd = SSD.replace(_values(src__u=3.0, src__k=2.0, sub__g__k=0.5),
                      _values(src__u=3.0, src__k=2.0, sub__g__k=0.5, other__x=1.0))
    folder = _scenario(tmp_path / "s", test_fmus["Gain"], ssd)
    report = validate(folder)
    assert report.ok
    assert [p.message for p in report.problems if "'other.x' names no element" in p.message]


def test_mapping_tables_and_their_faults() -> None:
    """Boolean and Integer MapEntry tables map values; a value without an entry, or a linear
    transformation on an Integer, is one problem naming the entry."""
    ps = ParameterSet("v.ssv", (Parameter("on", "Boolean", True), Parameter("n", "Integer", 2)))
    mapping = {"on": [_Mapping("flag", "m.ssm: on", table=(("true", "false"), ("false", "true")))],
               "n": [_Mapping("count", "m.ssm: n", table=(("1", "10"), ("2", "20")))]}
    problems: list[str] = []
    assert _mapped(ps, mapping, problems).parameters == (
        Parameter("flag", "Boolean", False, None, "m.ssm: on"),
        Parameter("count", "Integer", 20, None, "m.ssm: n"))
    assert problems == []
    mapping = {"n": [_Mapping("count", "m.ssm: n", table=(("1", "10"),))],
               "on": [_Mapping("flag", "m.ssm: on", 2.0, 0.0, None, True)]}
    _mapped(ps, mapping, problems)
    assert problems == ["m.ssm: on: a LinearTransformation applies to Real values ('on' is Boolean)",
                        "m.ssm: n: value 2 of 'n' is not in the mapping table (1)"]


def _edited(fmu: Path, dest: Path, drop: str = "", xml: tuple[str, str] | None = None) -> Path:
    """A copy of ``fmu`` without the members under ``drop``, ``xml`` replaced in its model description."""
    with zipfile.ZipFile(fmu) as zf, zipfile.ZipFile(dest, "w") as out:
        for info in zf.infolist():
            if drop and info.filename.startswith(drop):
                continue
            data = zf.read(info)
            if xml and info.filename == "modelDescription.xml":
                data = data.decode().replace(*xml).encode()
            out.writestr(info, data)
    return dest


def test_fmi1_model_exchange_and_missing_binaries_are_one_line_each(tmp_path) -> None:
    """libcosim's FMI 1.0 identity FMU made Model Exchange (no Implementation element), and without
    its linux64 binary: what the engine cannot run, said in one line with the platforms it has."""
    from ssp_conformance.conformance import HERE

    source = HERE / "libcosim"
    folder = tmp_path / "libcosim"
    shutil.copytree(source, folder)
    identity, original = folder / "fmi1" / "identity.fmu", source / "fmi1" / "identity.fmu"
    with zipfile.ZipFile(original) as zf:
        text = zf.read("modelDescription.xml").decode()
    end = "</Implementation>"
    _edited(original, identity, xml=(text[text.index("<Implementation"):text.index(end) + len(end)], ""))
    scenario = folder / "ssp" / "linear_transformation"
    errors = [e.message for e in validate(scenario, root=folder).errors]
    ssd = scenario / "SystemStructure.ssd"
    assert errors == [f"{ssd}: component '{c}': FMU is an FMI 1.0 Model Exchange FMU: orchestrate runs "
                      "Co-Simulation FMUs only" for c in ("identity1", "identity2")]
    _edited(original, identity, drop="binaries/linux64/")
    errors = [e.message for e in validate(scenario, root=folder).errors]
    assert len(errors) == 2 and errors[0].endswith(
        "FMU 'identity.fmu': no binary for this platform (linux64: binaries/linux64/identity.so); it has "
        "binaries for linux32, win32, win64; it has C sources, which orchestrate does not compile")
    with pytest.raises(ScenarioError):  # and run says the same, before any FMU is loaded
        orchestrator.run(scenario, RunOptions(root=folder, stop_time=0.1))
