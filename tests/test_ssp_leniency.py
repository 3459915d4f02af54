# SPDX-License-Identifier: BSD-2-Clause
"""Lenient where the peers are and nothing is lost; each leniency still a finding of validate.

* A connector naming no variable of its FMU that no connection uses (Dymola writes its wrapper
  parameters so; OMSimulator runs such files): a warning, and the run gives the rows the same
  file gives with the connector stripped (the oracle: that second file). Used by a connection,
  it stays an error.
* A value bound to an output of an FMI 1.0 FMU (files written for libcosim bind them): skipped
  with a warning. Oracle: libcosim running the same file (the OSP demo dp-ship with such a binding
  and one on an input, which libcosim applies): every output equal at every step, bit for bit.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from ssd_text import component, connector, ssd
from ssp_conformance.conformance import HERE, libcosim_series

import orchestrator
from orchestrator import RunOptions
from orchestrator.validate import validate

REFERENCE_FMUS = Path(__file__).resolve().parents[2] / "shared" / "tools" / "reference-fmus" / "2.0"
pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning"),
              pytest.mark.filterwarnings("ignore::orchestrator.EngineNote")]

SSD = ssd("wrapper", component("vdp", "resources/VanDerPol.fmu", connector("x0", "output") + "{extra}")
          + component("f", "resources/Feedthrough.fmu",
                      connector("Float64_continuous_input", "input") + "\n"
                      + connector("Float64_continuous_output", "output")),
          1, '      <ssd:Connection startElement="vdp" startConnector="x0" endElement="f"\n'
             '          endConnector="Float64_continuous_input"/>{connection}')
WRAPPER = '\n          <ssd:Connector name="wrapper.k" kind="parameter"><ssc:Real/></ssd:Connector>'


def wrapper_scenario(folder: Path, extra: str = "", connection: str = "") -> Path:
    (folder / "resources").mkdir(parents=True)
    for name in ("VanDerPol", "Feedthrough"):
        shutil.copy(REFERENCE_FMUS / f"{name}.fmu", folder / "resources")
    (folder / "SystemStructure.ssd").write_text(SSD.format(extra=extra, connection=connection))
    return folder


@pytest.mark.skipif(not (REFERENCE_FMUS / "VanDerPol.fmu").is_file(), reason="no Modelica Reference FMUs")
def test_unused_connector_without_variable_is_a_warning_and_changes_nothing(tmp_path: Path) -> None:
    lenient = wrapper_scenario(tmp_path / "with", WRAPPER)
    report = validate(lenient)
    assert report.ok, report.errors
    assert [p for p in report.problems if p.severity == "warning" and "connector 'wrapper.k': the FMU has no "
            "variable of that name; no connection uses it" in p.message]
    rows = orchestrator.run(lenient, RunOptions(step=0.01)).rows
    stripped = orchestrator.run(wrapper_scenario(tmp_path / "without"), RunOptions(step=0.01)).rows
    assert rows.dtype.names == stripped.dtype.names
    for name in rows.dtype.names:
        np.testing.assert_array_equal(rows[name], stripped[name], err_msg=name)
    assert abs(rows["f.Float64_continuous_output"]).max() > 1.0  # the oscillator's trajectory, passed on


@pytest.mark.skipif(not (REFERENCE_FMUS / "VanDerPol.fmu").is_file(), reason="no Modelica Reference FMUs")
def test_connected_connector_without_variable_stays_an_error(tmp_path: Path) -> None:
    connection = ('\n      <ssd:Connection startElement="f" startConnector="Float64_continuous_output" '
                  'endElement="vdp" endConnector="ghost"/>')
    ghost = '\n          <ssd:Connector name="ghost" kind="input"><ssc:Real/></ssd:Connector>'
    errors = [p.message for p in validate(wrapper_scenario(tmp_path / "s", ghost, connection)).errors]
    ssd = tmp_path / "s" / "SystemStructure.ssd"
    assert errors == [f"{ssd}: component 'vdp', connector 'ghost': the FMU has no variable of that name"]


BINDING = """        <ssd:ParameterBindings><ssd:ParameterBinding source="dp.ssv"/></ssd:ParameterBindings>
"""
SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0"
    name="dp">
  <ssv:Parameters>
    <ssv:Parameter name="Controlx"><ssv:Real value="7"/></ssv:Parameter>
    <ssv:Parameter name="reset1"><ssv:Real value="1"/></ssv:Parameter>
  </ssv:Parameters>
</ssv:ParameterSet>
"""


def test_value_for_an_fmi1_output_is_skipped_as_libcosim_skips_it(tmp_path: Path) -> None:
    pytest.importorskip("libcosimpy")
    folder = tmp_path / "dp-ship"
    shutil.copytree(HERE / "osp-demo-cases" / "dp-ship", folder)
    ssd = (folder / "SystemStructure.ssd").read_text()
    first = ssd.index("      </ssd:Component>")  # the first component: DP Controller
    (folder / "SystemStructure.ssd").write_text(ssd[:first] + BINDING + ssd[first:])
    (folder / "dp.ssv").write_text(SSV)
    report = validate(folder)
    assert report.ok, report.errors
    skipped = "DP Controller.Controlx is an output of an FMI 1.0 FMU: the value 7.0 given for it is not set"
    assert [p for p in report.problems if p.severity == "warning" and skipped in p.message]
    rows = orchestrator.run(folder, RunOptions(stop_time=1.0)).rows
    with orchestrator.open_system(folder) as system:
        outputs = [f"{n}.{o}" for n, c in system.components.items() for o in c.outputs]
    theirs = libcosim_series(folder, 1.0, [*outputs, "DP Controller.reset1"])
    assert theirs["DP Controller.reset1"][0] == 1.0  # libcosim applied the file
    assert (rows["DP Controller.Controlx"] == 0.0).all()
    for name in outputs:
        assert (np.array(theirs[name]) == rows[name]).all(), name
