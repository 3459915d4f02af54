# SPDX-License-Identifier: BSD-2-Clause
"""The clocked variant of a shipped scenario (issue 48): the paper's sampled controller as what it
is, the clocked twin of its controller FMU (:mod:`fmu_src.toolchain.clocked`), in an SSP 2.0 file.

From a scenario source folder (``ssp/<name>/``) it writes a folder beside which
:func:`orchestrator.ssp.pack_ssp` packs ``build/ssp/<name>_clocked.ssp``:

* the SSD as ``version="2.0"``, the controller component's source its twin
  (``FixedTimeController_clocked.fmu``) and one more connector, the twin's input clock
  ``sample`` (``ssc:Clock intervalVariability="fixed"``: its interval is the FMU's, asked in
  Initialization Mode);
* the controller's parameter file with ``sample_time`` equal to the scenario's communication step
  (the osp:FixedStepAlgorithm ``baseStepSize``): the unclocked scenario evaluates the law at every
  communication step, so this is its sampling period, and the clocked run equals it bit for bit
  (``tests/test_clocked_controller.py``) where the master's step divides it; at any other step
  the clock keeps the sampling right.

A scenario without a controller FMU of the project has no clocked variant (None).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from lxml import etree

from fmu_src.toolchain.clocked import CLOCK, INTERVAL_PARAMETER
from fmu_src.toolchain.fmi3 import CLOCKED_SUFFIX

from ..errors import ScenarioError
from ..ssp import NS, SSD_NAME

__all__ = ["CLOCKED_SCENARIO_SUFFIX", "clocked_folder"]

CLOCKED_SCENARIO_SUFFIX = "_clocked"  # build/ssp/<name>_clocked.ssp
CONTROLLER = re.compile(r"^resources/(FixedTimeController\d?)\.fmu$")
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"


def clocked_folder(folder: Path, dest: Path) -> dict[str, str] | None:
    """Write the clocked variant of the scenario source ``folder`` into ``dest`` (made anew);
    returns the FMU names it uses instead (``FixedTimeController.fmu`` ->
    ``FixedTimeController_clocked.fmu``), None when the scenario has no controller to clock."""
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_blank_text=False)
    ssd = etree.parse(str(folder / SSD_NAME), parser)
    root = ssd.getroot()
    controllers = [c for c in root.iterfind(".//ssd:Component", NS) if CONTROLLER.match(c.get("source", ""))]
    if not controllers:
        return None
    step = root.find("ssd:DefaultExperiment//{*}FixedStepAlgorithm", NS)
    if step is None or step.get("baseStepSize") is None:
        raise ScenarioError(f"{folder / SSD_NAME}: no osp:FixedStepAlgorithm baseStepSize: its clocked "
                            "variant needs the step the law is sampled at")
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(folder, dest, ignore=shutil.ignore_patterns(".*"))
    renamed = {}
    root.set("version", "2.0")
    for component in controllers:
        model = CONTROLLER.match(component.get("source", ""))
        assert model is not None
        twin = f"{model[1]}{CLOCKED_SUFFIX}.fmu"
        renamed[f"{model[1]}.fmu"] = twin
        component.set("source", f"resources/{twin}")
        connectors = component.find("ssd:Connectors", NS)
        assert connectors is not None  # every shipped component declares its connectors
        clock = etree.SubElement(connectors, f"{{{NS['ssd']}}}Connector", name=CLOCK, kind="input")
        etree.SubElement(clock, f"{{{NS['ssc']}}}Clock", intervalVariability="fixed")
        for binding in component.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            if binding.get("source"):
                _set_interval(dest / binding.get("source", ""), step.get("baseStepSize", ""))
    ssd.write(str(dest / SSD_NAME), xml_declaration=True, encoding="UTF-8")
    return renamed


def _set_interval(ssv: Path, step: str) -> None:
    """``sample_time`` in the parameter file ``ssv`` set to ``step`` (added when missing)."""
    tree = etree.parse(str(ssv), etree.XMLParser(resolve_entities=False, no_network=True))
    parameters = tree.getroot().find(f"{{{SSV}}}Parameters")
    if parameters is None:
        raise ScenarioError(f"{ssv}: no ssv:Parameters to set {INTERVAL_PARAMETER} in")
    found = [p for p in parameters if p.get("name") == INTERVAL_PARAMETER]
    parameter = found[0] if found else etree.SubElement(parameters, f"{{{SSV}}}Parameter",
                                                        name=INTERVAL_PARAMETER)
    for child in list(parameter):
        parameter.remove(child)
    etree.SubElement(parameter, f"{{{SSV}}}Real", value=step)
    tree.write(str(ssv), xml_declaration=True, encoding="UTF-8")
