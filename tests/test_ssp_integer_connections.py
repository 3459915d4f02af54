# SPDX-License-Identifier: BSD-2-Clause
"""Integer and Enumeration connections (issue 43), on the Modelica Reference FMUs.

Stair's ``counter`` (an Integer output) is 1 at t = 0 and grows by 1 at every full second (its
sources, ``sources/model.c``; run to 1.5 s, as Feedthrough's Enumeration has the items 1 and 2
only, and refuses 3 with an error); Feedthrough copies each input to the output of the same type. So in
the chain Stair.counter -> a.Int32_input (Integer -> Integer) and Stair.counter ->
a.Enumeration_input -> a.Enumeration_output -> b.Int32_input (Integer -> Enumeration ->
Integer, as OMSimulator's Embrace and acvs files connect them) every integer column is
1 + floor(t) at the same communication point (gauss-seidel), and the largest 32-bit int given to
d.Int32_input passes d.Int32_output -> c.Int32_input exactly. Both executors (the Python master, the compiled
one) must give it, bit for bit. (OMSimulator 3 ends with a segmentation fault on these two FMUs, with
or without connections; it is compared on Embrace and acvs in ``make conformance``.) Before, such
connections were refused ("only Real connections are supported").
"""

from __future__ import annotations

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

BIG = 2**31 - 1
CONNECTIONS = [("stair", "counter", "a", "Int32_input"), ("stair", "counter", "a", "Enumeration_input"),
               ("a", "Enumeration_output", "b", "Int32_input"), ("d", "Int32_output", "c", "Int32_input")]


def _connector(name: str, kind: str, type_: str) -> str:
    typed = '<ssc:Enumeration name="Option"/>' if type_ == "Enumeration" else f"<ssc:{type_}/>"
    return f'<ssd:Connector name="{name}" kind="{kind}">{typed}</ssd:Connector>'


def integer_chain(folder: Path) -> Path:
    """The archive of the chain described above; d.Int32_input is 2^31 - 1 (an SSV value)."""
    feed = "".join(_connector(n, k, t) for n, k, t in (
        ("Int32_input", "input", "Integer"), ("Int32_output", "output", "Integer"),
        ("Enumeration_input", "input", "Enumeration"), ("Enumeration_output", "output", "Enumeration")))
    values = f"""
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="1.0" name="d"><ssv:Parameters>
            <ssv:Parameter name="Int32_input"><ssv:Integer value="{BIG}"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>
        </ssd:ParameterBindings>"""
    head = '<ssd:Component name="{}" type="application/x-fmu-sharedlibrary" source="resources/{}.fmu">'
    stair = _connector("counter", "output", "Integer")
    elements = (head.format("stair", "Stair") + f"<ssd:Connectors>{stair}</ssd:Connectors></ssd:Component>"
                + "".join(f'{head.format(n, "Feedthrough")}<ssd:Connectors>{feed}</ssd:Connectors>'
                          f'{values if n == "d" else ""}</ssd:Component>' for n in "abcd"))
    connections = "".join(f'<ssd:Connection startElement="{a}" startConnector="{x}" endElement="{b}" '
                          f'endConnector="{y}"/>' for a, x, b, y in CONNECTIONS)
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="integers"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="integers"><ssd:Elements>{elements}</ssd:Elements>
    <ssd:Connections>{connections}</ssd:Connections></ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1.5"/>
</ssd:SystemStructureDescription>
"""
    archive = folder / "integers.ssp"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for fmu in ("Stair", "Feedthrough"):
            zf.write(REFERENCE_FMUS / f"{fmu}.fmu", f"resources/{fmu}.fmu")
    return archive


@pytest.fixture(scope="module")
def chain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return integer_chain(tmp_path_factory.mktemp("integers"))


@pytest.mark.parametrize("executor", ["python", "compiled"])
def test_integer_and_enumeration_values_pass_exactly(chain: Path, executor: str) -> None:
    result = orchestrator.run(chain, RunOptions(stop_time=1.5, step=0.5, executor=executor))
    rows = result.rows
    assert result.provenance["executor"] == executor
    counter = 1 + np.floor(rows["time"] + 1e-9)  # Stair: 1, then +1 at every full second
    for column in ("stair.counter", "a.Int32_input", "a.Enumeration_input",
                   "a.Enumeration_output", "b.Int32_input"):
        assert np.array_equal(rows[column], counter), column
    assert np.all(rows["d.Int32_output"] == BIG) and np.all(rows["c.Int32_input"] == BIG)


def test_both_executors_agree_to_the_bit(chain: Path) -> None:
    python, compiled = (orchestrator.run(chain, RunOptions(stop_time=1.5, step=0.5, executor=e)).rows
                        for e in ("python", "compiled"))
    assert python.tobytes() == compiled.tobytes()


def test_validate_names_each_integer_enumeration_connection(chain: Path) -> None:
    report = validate(chain)
    assert report.ok, report.errors
    mixed = [p.message for p in report.problems if "is Integer" in p.message and "Enumeration" in p.message]
    assert len(mixed) == 2, report.problems
    assert "stair.counter -> a.Enumeration_input" in mixed[0]
    assert "a.Enumeration_output -> b.Int32_input" in mixed[1]


def test_a_transformation_on_an_integer_connection_is_refused(tmp_path: Path) -> None:
    archive = integer_chain(tmp_path)
    with zipfile.ZipFile(archive) as zf:
        ssd = zf.read("SystemStructure.ssd").decode()
    bad = tmp_path / "bad"
    bad.mkdir()
    ssd = ssd.replace('endConnector="Int32_input"/>',
                      'endConnector="Int32_input"><ssc:LinearTransformation factor="2"/></ssd:Connection>', 1)
    with zipfile.ZipFile(bad / "integers.ssp", "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        for fmu in ("Stair", "Feedthrough"):
            zf.write(REFERENCE_FMUS / f"{fmu}.fmu", f"resources/{fmu}.fmu")
    report = validate(bad / "integers.ssp")
    assert any("stair.counter -> a.Int32_input: a LinearTransformation on an Integer connection" in p.message
               for p in report.errors), report.errors


@pytest.mark.parametrize("executor", ["python", "compiled"])
def test_an_item_the_fmu_refuses_is_one_line_naming_fmi2SetInteger(chain: Path, executor: str) -> None:
    """Past t = 2 s Stair's counter is 3, which Feedthrough's Enumeration (items 1, 2) refuses with
    fmi2Error: the run stops there with one line naming the component, the call and the time."""
    with pytest.raises(orchestrator.SimulationError) as caught:
        orchestrator.run(chain, RunOptions(stop_time=3.5, step=0.5, executor=executor))
    assert "a: fmi2SetInteger returned fmi2Error at t=2.000 s" in str(caught.value), str(caught.value)
