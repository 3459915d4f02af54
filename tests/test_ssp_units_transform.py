# SPDX-License-Identifier: BSD-2-Clause
"""Unit conversion composed with a LinearTransformation, on the Modelica Reference FMUs.

SSP 1.0.1 4.5.2.1 (connections) and 5.3.2 (parameter mappings): "conversions based on different
units are performed, unless prevented by suppressUnitConversion, prior to the application of the
linear transformation". The expected values below are that formula written out by hand
(km -> m with factor 2, offset 1: 2 * 1000 * x + 1); the FMUs are third-party (Feedthrough passes
its input to its output, BouncingBall's velocity is g * t before the first bounce, under its own
explicit Euler), so a value that skips or misorders the conversion cannot pass. Before issue 43
a transformed connection skipped the conversion (3.0 where the standard gives 2001) and a mapped
parameter was transformed first and converted after (2 * -1 + 1 = -1 km/s2 -> -1000 m/s2).
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

import orchestrator
from orchestrator import RunOptions
from orchestrator.validate import validate

REFERENCE_FMUS = Path(__file__).resolve().parents[2] / "shared" / "tools" / "reference-fmus" / "2.0"
pytestmark = [pytest.mark.system,
              pytest.mark.skipif(not (REFERENCE_FMUS / "Feedthrough.fmu").is_file(),
                                 reason=f"no Modelica Reference FMUs in {REFERENCE_FMUS}")]

HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="units"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"
    xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping">
"""
UNITS = """  <ssd:Units>
    <ssc:Unit name="km"><ssc:BaseUnit m="1" factor="1000"/></ssc:Unit>
    <ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit>
    <ssc:Unit name="degC"><ssc:BaseUnit K="1" offset="273.15"/></ssc:Unit>
    <ssc:Unit name="K"><ssc:BaseUnit K="1"/></ssc:Unit>
  </ssd:Units>
"""


def feedthrough_pair(folder: Path, unit_a: str, unit_b: str, connection: str) -> Path:
    """Two Feedthrough FMUs: a's input is 1 (an SSV value), a's output (declared in ``unit_a``)
    feeds b's input (declared in ``unit_b``) through ``connection`` (attributes and content)."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(REFERENCE_FMUS / "Feedthrough.fmu", folder / "resources")
    attributes, _, content = connection.partition(">")

    def element(name: str, unit_in: str, unit_out: str, binding: str = "") -> str:
        return f"""      <ssd:Component name="{name}" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Real{unit_in}/></ssd:Connector>
          <ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Real{unit_out}/></ssd:Connector>
        </ssd:Connectors>{binding}
      </ssd:Component>
"""
    binding = """
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="a"><ssv:Parameters>
            <ssv:Parameter name="Float64_continuous_input"><ssv:Real value="1"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"""
    (folder / "SystemStructure.ssd").write_text(
        HEAD + f"""  <ssd:System name="units">
    <ssd:Elements>
{element("a", "", f' unit="{unit_a}"', binding)}{element("b", f' unit="{unit_b}"', f' unit="{unit_b}"')}
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="a" startConnector="Float64_continuous_output" endElement="b"
          endConnector="Float64_continuous_input"{attributes}>{content}</ssd:Connection>
    </ssd:Connections>
  </ssd:System>
{UNITS}  <ssd:DefaultExperiment startTime="0" stopTime="0.02"/>
</ssd:SystemStructureDescription>
""")
    return folder


LINEAR = ' ><ssc:LinearTransformation factor="2" offset="1"/>'


@pytest.mark.parametrize(("unit_a", "unit_b", "connection", "expected"), [
    ("km", "m", LINEAR, 2 * 1000 * 1.0 + 1),                   # 4.5.2.1: convert, then transform
    ("degC", "K", LINEAR, 2 * (1.0 + 273.15) + 1),             # an offset unit: 549.3
    ("km", "m", ' suppressUnitConversion="true"' + LINEAR, 2 * 1.0 + 1),  # the transformation alone
    ("km", "m", ">", 1000 * 1.0),                              # no transformation: the conversion alone
], ids=["km-m", "degC-K", "suppressed", "plain"])
def test_connection_converts_units_before_the_transformation(tmp_path: Path, unit_a: str, unit_b: str,
                                                             connection: str, expected: float) -> None:
    scenario = feedthrough_pair(tmp_path / "s", unit_a, unit_b, connection)
    rows = orchestrator.run(scenario, RunOptions(step=0.01)).rows
    np.testing.assert_allclose(rows["a.Float64_continuous_output"], 1.0)
    np.testing.assert_allclose(rows["b.Float64_continuous_input"], expected, rtol=1e-14)
    np.testing.assert_allclose(rows["b.Float64_continuous_output"], expected, rtol=1e-14)


def test_validate_names_the_composed_conversion(tmp_path: Path) -> None:
    """Tools differ on this order (OMSimulator 3 passes 3.0): validate says what a run will do."""
    report = validate(feedthrough_pair(tmp_path / "s", "km", "m", LINEAR))
    assert report.ok, report.errors
    said = [p.message for p in report.problems if "before the LinearTransformation" in p.message]
    assert len(said) == 1 and "b.Float64_continuous_input = 2000 * a.Float64_continuous_output + 1" in said[0]


def test_transformed_connection_between_dimensions_is_refused(tmp_path: Path) -> None:
    """km -> K cannot be converted; with a transformation that used to pass unchecked."""
    report = validate(feedthrough_pair(tmp_path / "s", "km", "K", LINEAR))
    assert [p.message for p in report.errors if "unit mismatch" in p.message and "suppressUnitConversion"
            in p.message], report.problems


def test_fmu_units_convert_before_the_transformation(tmp_path: Path) -> None:
    """BouncingBall.h is in m by its own UnitDefinitions; the SSD declares Feedthrough's input in
    km: the input is 2 * h / 1000 + 1 at every communication point (gauss-seidel: same time)."""
    folder = tmp_path / "s"
    (folder / "resources").mkdir(parents=True)
    for name in ("BouncingBall", "Feedthrough"):
        shutil.copy(REFERENCE_FMUS / f"{name}.fmu", folder / "resources")
    (folder / "SystemStructure.ssd").write_text(HEAD + """  <ssd:System name="units">
    <ssd:Elements>
      <ssd:Component name="ball" source="resources/BouncingBall.fmu">
        <ssd:Connectors><ssd:Connector name="h" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
      </ssd:Component>
      <ssd:Component name="f" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Real unit="km"/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="ball" startConnector="h" endElement="f"
          endConnector="Float64_continuous_input">
        <ssc:LinearTransformation factor="2" offset="1"/>
      </ssd:Connection>
    </ssd:Connections>
  </ssd:System>
""" + UNITS + """  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
""")
    rows = orchestrator.run(folder, RunOptions(step=0.01)).rows
    assert rows["ball.h"].min() < 0.5  # the ball fell and bounced: a trajectory, not a constant
    np.testing.assert_allclose(rows["f.Float64_continuous_input"], 2 * rows["ball.h"] / 1000 + 1, rtol=1e-14)


def bouncing_ball_mapped(folder: Path, suppress: bool) -> Path:
    """BouncingBall whose g (m/s2) is bound from an SSV value of -1 km/s2 through an SSM entry with
    factor 2, offset 1."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(REFERENCE_FMUS / "BouncingBall.fmu", folder / "resources")
    flag = ' suppressUnitConversion="true"' if suppress else ""
    (folder / "SystemStructure.ssd").write_text(HEAD + f"""  <ssd:System name="ball">
    <ssd:Elements>
      <ssd:Component name="ball" source="resources/BouncingBall.fmu">
        <ssd:Connectors><ssd:Connector name="v" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding>
          <ssd:ParameterValues>
            <ssv:ParameterSet version="1.0" name="gravity">
              <ssv:Parameters>
                <ssv:Parameter name="gravity"><ssv:Real value="-1" unit="km/s2"/></ssv:Parameter>
              </ssv:Parameters>
              <ssv:Units>
                <ssc:Unit name="km/s2"><ssc:BaseUnit m="1" s="-2" factor="1000"/></ssc:Unit>
              </ssv:Units>
            </ssv:ParameterSet>
          </ssd:ParameterValues>
          <ssd:ParameterMapping>
            <ssm:ParameterMapping version="1.0">
              <ssm:MappingEntry source="gravity" target="g"{flag}>
                <ssc:LinearTransformation factor="2" offset="1"/>
              </ssm:MappingEntry>
            </ssm:ParameterMapping>
          </ssd:ParameterMapping>
        </ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.02"/>
</ssd:SystemStructureDescription>
""")
    return folder


@pytest.mark.parametrize(("suppress", "g"), [(False, 2 * -1000.0 + 1), (True, 2 * -1.0 + 1)],
                         ids=["converted-first", "suppressed"])
def test_parameter_mapping_converts_units_before_the_transformation(tmp_path: Path, suppress: bool,
                                                                    g: float) -> None:
    """5.3.2: -1 km/s2 is -1000 m/s2, then 2 * -1000 + 1 = -1999 m/s2 (suppressed: 2 * -1 + 1); the
    ball's velocity before its first bounce is g * t."""
    scenario = bouncing_ball_mapped(tmp_path / "s", suppress)
    rows = orchestrator.run(scenario, RunOptions(step=0.01)).rows
    np.testing.assert_allclose(rows["ball.v"], g * rows["time"], rtol=1e-9, atol=1e-12)
    report = validate(scenario)
    assert report.ok, report.errors
    said = [p.message for p in report.problems if "5.3.2" in p.message]
    assert bool(said) != suppress and all(f"{g!r}" in m for m in said), report.problems


def test_value_in_a_unit_only_the_fmu_defines(tmp_path: Path) -> None:
    """A value given in ``bar``, which neither the SSD nor the SSV defines but the FMU's
    UnitDefinitions do (OMSimulator's acvs files give values so): converted by the FMU's own
    definitions, 2 bar = 2 * 1e5 Pa = 200 kPa; before issue 43 an "unknown unit" error."""
    folder = tmp_path / "s"
    (folder / "resources").mkdir(parents=True)
    with zipfile.ZipFile(REFERENCE_FMUS / "Feedthrough.fmu") as src, \
            zipfile.ZipFile(folder / "resources" / "Feedthrough.fmu", "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml":
                xml = data.decode().replace("  <TypeDefinitions>", """  <UnitDefinitions>
    <Unit name="kPa"><BaseUnit kg="1" m="-1" s="-2" factor="1000"/></Unit>
    <Unit name="bar"><BaseUnit kg="1" m="-1" s="-2" factor="100000"/></Unit>
  </UnitDefinitions>
  <TypeDefinitions>""", 1)
                xml = xml.replace('variability="fixed">\n      <Real start="0"/>',
                                  'variability="fixed">\n      <Real start="0" unit="kPa"/>', 1)
                data = xml.encode()
            dst.writestr(info, data)
    (folder / "SystemStructure.ssd").write_text(HEAD + """  <ssd:System name="pressure">
    <ssd:Elements>
      <ssd:Component name="f" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>
            <ssv:Parameter name="Float64_fixed_parameter"><ssv:Real value="2" unit="bar"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
    </ssd:Elements>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.02"/>
</ssd:SystemStructureDescription>
""")
    assert validate(folder).ok
    result = orchestrator.run(folder, RunOptions(step=0.01))
    assert result.provenance["start_values"]["f.Float64_fixed_parameter"] == pytest.approx(200.0, rel=1e-15)


def test_a_value_in_a_unit_written_in_brackets(tmp_path: Path) -> None:
    """Embrace's SSVs give values in ``[m]`` and define ``m`` (no file defines ``[m]``; OMSimulator's
    own test prints the pipe lengths they give): read as the unit inside the brackets, with a
    warning, so -1 [km/s2] is -1000 m/s2, then 2 * -1000 + 1 (5.3.2); before, "unknown unit"."""
    scenario = bouncing_ball_mapped(tmp_path / "s", suppress=False)
    ssd = scenario / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('unit="km/s2"/>', 'unit="[km/s2]"/>'))
    report = validate(scenario)
    assert report.ok, report.errors
    assert [p.message for p in report.problems if "'[km/s2]', which no file defines, is read as 'km/s2'"
            in p.message], report.problems
    rows = orchestrator.run(scenario, RunOptions(step=0.01)).rows
    np.testing.assert_allclose(rows["ball.v"], (2 * -1000.0 + 1) * rows["time"], rtol=1e-9, atol=1e-12)


def test_an_empty_unit_attribute_is_no_unit(tmp_path: Path) -> None:
    """``<ssc:Real unit=""/>`` (OMSimulator's acvs file writes it) declares no unit: the connection
    to an input in K is not judged and passes the value unchanged (before: "unit mismatch ... is in
    1"); with a unit on both ends the conversion still applies."""
    scenario = feedthrough_pair(tmp_path / "s", "", "K", ">")
    assert validate(scenario).ok
    rows = orchestrator.run(scenario, RunOptions(step=0.01)).rows
    np.testing.assert_allclose(rows["b.Float64_continuous_input"], 1.0, rtol=0)
