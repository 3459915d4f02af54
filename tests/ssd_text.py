# SPDX-License-Identifier: BSD-2-Clause
"""SSP 1.0 system structure files written by hand for tests and benchmarks.

Hand-written on purpose: a test input made by the engine's own ``write_ssd`` would share the
engine's mistakes. This module only holds the frame every such file repeats.
"""

from __future__ import annotations

HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="{name}"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="{name}">
    <ssd:Elements>
"""
TAIL = """  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop}"/>
</ssd:SystemStructureDescription>
"""


def component(name: str, source: str, connectors: str) -> str:
    """An ``ssd:Component`` element with the given connector elements."""
    return (f'      <ssd:Component name="{name}" source="{source}">\n'
            f"        <ssd:Connectors>\n{connectors}\n        </ssd:Connectors>\n"
            "      </ssd:Component>\n")


def connector(name: str, kind: str) -> str:
    """A Real ``ssd:Connector`` element."""
    return f'          <ssd:Connector name="{name}" kind="{kind}"><ssc:Real/></ssd:Connector>'


def ssd(name: str, components: str, stop: float | str, connections: str = "") -> str:
    """A whole SSD text: ``components`` in the elements, ``connections`` (elements) if any."""
    links = f"    <ssd:Connections>\n{connections}\n    </ssd:Connections>\n" if connections else ""
    return HEAD.format(name=name) + components + "    </ssd:Elements>\n" + links + TAIL.format(stop=stop)


def feedthrough(name: str, stop: float | str, source: str = "resources/Feedthrough.fmu") -> str:
    """One component ``f``, a Reference-FMU Feedthrough (or an FMU made from one), with its Float64 output."""
    return ssd(name, component("f", source, connector("Float64_continuous_output", "output")), stop)
