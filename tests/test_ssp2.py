# SPDX-License-Identifier: BSD-2-Clause
"""SSP 2.0 as its own schemas say (modelica/ssp-standard, tag v2.0, in orchestrator/schemas/ssp2).

Oracles: the standard's schemas themselves (a file using an SSP 2.0 element is valid as version
"2.0" and invalid as "1.0", which is what the two schema sets say), files another tool wrote
(OMSimulator's ``version="2.0"`` SSD, SSV and SSM, read now as 2.0 with no note), and the
Modelica Reference FMUs' FMI 3.0 Feedthrough (its Float64 output equals its input: the value an
SSP 2.0 ``ssv:Float64`` binds reaches the second FMU through an ``ssc:Float64`` connection).
What the engine does not support is refused in one line naming the SSD, component and connector.
"""

from __future__ import annotations

import re
import shutil
from contextlib import ExitStack
from pathlib import Path

import pytest
from ssp_conformance.conformance import HERE

import orchestrator
from orchestrator import RunOptions
from orchestrator.ssp import SSD_NAME, scan_scenario, write_ssd
from orchestrator.validate import check_scenario

# /work/shared beside a checkout of /work/main, or seen from a worktree below /work/wt
SHARED = next((p for p in (Path(__file__).resolve().parents[2] / "shared", Path("/work/shared"))
               if p.is_dir()), Path("/work/shared"))
FEEDTHROUGH = SHARED / "tools" / "reference-fmus" / "3.0" / "Feedthrough.fmu"
needs_feedthrough = pytest.mark.skipif(not FEEDTHROUGH.is_file(),
                                       reason="no Modelica Reference FMUs (FMI 3.0)")
pytestmark = [pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning"),
              pytest.mark.filterwarnings("ignore::orchestrator.EngineNote")]

SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="{version}" name="two"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="two">
    <ssd:Elements>
      <ssd:Component name="a" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Float64/></ssd:Connector>
          <ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Float64/></ssd:Connector>{extra}
        </ssd:Connectors>
        <ssd:ParameterBindings>
          <ssd:ParameterBinding>
            <ssd:ParameterValues>
              <ssv:ParameterSet version="{version}" name="values">
                <ssv:Parameters>
                  <ssv:Parameter name="Float64_continuous_input"><ssv:Float64 value="3.5"/></ssv:Parameter>
                </ssv:Parameters>
              </ssv:ParameterSet>
            </ssd:ParameterValues>
          </ssd:ParameterBinding>
        </ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="b" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Float64/></ssd:Connector>
          <ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Float64/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="a" startConnector="Float64_continuous_output" endElement="b"
          endConnector="Float64_continuous_input"{indices}/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.1"/>
</ssd:SystemStructureDescription>
"""


def scenario(folder: Path, version: str = "2.0", extra: str = "", indices: str = "") -> Path:
    """Two Reference Feedthrough FMUs, a -> b, in an SSD of ``version``."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(FEEDTHROUGH, folder / "resources")
    (folder / SSD_NAME).write_text(SSD.format(version=version, extra=extra, indices=indices))
    return folder


def test_omsimulator_version_2_files_are_read_as_ssp_2() -> None:
    """OMSimulator's files (SSD, and an SSV and SSM of version 2.0) pass the SSP 2.0 schemas with no
    note; before, they were read as SSP 1.0 with a warning naming each file."""
    for case in ("LinearTransformation", "LinearTransformation3"):
        folder = HERE / "omsimulator" / case
        assert 'version="2.0"' in (folder / SSD_NAME).read_text()
        reading = scan_scenario(folder)
        assert reading.problems == () and reading.notes == (), (reading.problems, reading.notes)


def test_an_ssp_2_element_is_valid_in_2_0_only(tmp_path: Path) -> None:
    """OMSimulator's SSD with one connector typed ``ssc:Float64`` (SSP 2.0's GTypeChoice): valid as
    the file says, version 2.0; the same file claiming 1.0 breaks the SSP 1.0 schema."""
    text = (HERE / "omsimulator" / "LinearTransformation" / SSD_NAME).read_text()
    declared = 'kind="output" description="Connector of Real output signal">\n            <ssc:{}/>'
    text = text.replace(declared.format("Real"), declared.format("Float64"), 1)
    assert "<ssc:Float64/>" in text
    for version, valid in (("2.0", True), ("1.0", False)):
        folder = tmp_path / version
        shutil.copytree(HERE / "omsimulator" / "LinearTransformation", folder)
        (folder / SSD_NAME).write_text(text.replace('version="2.0"', f'version="{version}"', 1))
        problems = scan_scenario(folder).problems
        schema_errors = [p for p in problems if "Float64" in p and "line" in p]
        assert (schema_errors == []) is valid, problems


@needs_feedthrough
def test_float64_connectors_and_values_of_ssp_2_run(tmp_path: Path) -> None:
    """ssc:Float64 connectors and an ssv:Float64 value: the value bound on a's input comes out of b."""
    rows = orchestrator.run(scenario(tmp_path / "s"), RunOptions(step=0.05)).rows
    assert list(rows["b.Float64_continuous_output"]) == [3.5, 3.5, 3.5]
    assert list(rows["a.Float64_continuous_output"]) == [3.5, 3.5, 3.5]


@needs_feedthrough
@pytest.mark.parametrize(("extra", "indices", "expected"), [
    ('<ssd:Connector name="Float32_continuous_output" kind="output"><ssc:Float32/></ssd:Connector>',
     "", "component 'a', connector 'Float32_continuous_output': the FMU's variable is Float32, an FMI 3.0 "
         "type orchestrate does not support"),
    ('<ssd:Connector name="Binary_output" kind="output"><ssc:Binary/></ssd:Connector>',
     "", "component 'a', connector 'Binary_output': the FMU's variable is Binary"),
    ('<ssd:Connector name="n" kind="structuralParameter"><ssc:UInt64/></ssd:Connector>',
     "", "component 'a': connector 'n' is a structural parameter (SSP 2.0): not supported"),
    ('<ssd:Connector name="v" kind="output"><ssc:Float64/><ssc:Dimension size="3"/></ssd:Connector>',
     "", "component 'a': connector 'v' is an array (1 ssc:Dimension): array connectors are not supported"),
    ("", ' startIndices="1" endIndices="1"',
     "connection a.Float64_continuous_output -> b.Float64_continuous_input joins elements of array "
     "connectors"),
])
def test_what_is_not_supported_is_refused_in_one_line(tmp_path: Path, extra: str, indices: str,
                                                      expected: str) -> None:
    folder = scenario(tmp_path / "s", extra=extra, indices=indices)
    with ExitStack() as stack:
        _, errors, _ = check_scenario(folder, stack)
    matching = [e for e in errors if expected in e]
    assert len(matching) == 1 and "\n" not in matching[0] and SSD_NAME in matching[0], errors


def test_clock_connectors_are_read(tmp_path: Path) -> None:
    """An ssc:Clock connector keeps its interval, a connector its ssd:Clock associations."""
    (tmp_path / SSD_NAME).write_text(SSD.format(version="2.0", indices="", extra="""
          <ssd:Connector name="tick" kind="input"><ssc:Clock intervalVariability="constant"
              intervalDecimal="0.1"/></ssd:Connector>
          <ssd:Connector name="y" kind="output"><ssc:Float64/><ssd:Clock name="tick"/></ssd:Connector>"""))
    reading = scan_scenario(tmp_path)
    assert reading.structure is not None
    a = {k.name: k for k in reading.structure.components[0].connectors}
    assert (a["tick"].type, a["tick"].interval, a["tick"].clocks) == ("Clock", 0.1, ())
    assert (a["y"].type, a["y"].clocks) == ("Float64", ("tick",))
    assert [p for p in reading.problems if "schema" in p or " line " in p] == []


def test_a_structure_with_ssp_2_connectors_is_written_as_2_0_and_reads_back(tmp_path: Path) -> None:
    """Read, written, read again: the SSD written is version 2.0 (its ssc:Float64 and ssc:Clock would
    break the 1.0 schema), valid against the 2.0 schemas, with the same connectors."""
    (tmp_path / "a").mkdir()
    text = SSD.format(version="2.0", indices="", extra="""
          <ssd:Connector name="tick" kind="input"><ssc:Clock intervalDecimal="0.1"/></ssd:Connector>
          <ssd:Connector name="y" kind="output"><ssc:Float64/><ssd:Clock name="tick"/></ssd:Connector>""")
    bindings = re.compile(r"<ssd:ParameterBindings>.*</ssd:ParameterBindings>", re.DOTALL)
    (tmp_path / "a" / SSD_NAME).write_text(bindings.sub("", text))  # connectors only
    first = scan_scenario(tmp_path / "a").structure
    assert first is not None
    write_ssd(tmp_path / "a", first)  # over the file read
    assert 'version="2.0"' in (tmp_path / "a" / SSD_NAME).read_text()
    again = scan_scenario(tmp_path / "a")
    assert [p for p in again.problems if " line " in p] == []
    assert again.structure is not None
    assert again.structure.components[0].connectors == first.components[0].connectors


def test_ssc_float64_on_an_fmi_2_real_is_accepted(tmp_path: Path) -> None:
    """FMI 2.0's Real is a 64-bit double: an SSP 2.0 file may type its connector ssc:Float64 (the
    OMSimulator file with its Gain's output so typed runs to the values its test prints)."""
    folder = tmp_path / "s"
    shutil.copytree(HERE / "omsimulator" / "LinearTransformation", folder)
    text = (folder / SSD_NAME).read_text()
    declared = 'kind="output" description="Output signal connector">\n            <ssc:{}/>'
    assert text.count(declared.format("Real")) == 1
    (folder / SSD_NAME).write_text(text.replace(declared.format("Real"), declared.format("Float64")))
    rows = orchestrator.run(folder, RunOptions(stop_time=1.0, step=0.01)).rows
    assert (rows["Gain1.y"][-1], rows["Add1.u1"][-1]) == (0.0, 3.0)  # the conformance case's oracle
