# SPDX-License-Identifier: BSD-2-Clause
"""The clocked twin of an FMI 3.0 controller FMU's model description: the sampled controller as
FMI 3.0 says it (issue 48).

The controller is digital: its law is evaluated every ``sample_time`` and held in between. The
plain FMI 2.0 and 3.0 variants can only express that by the importer stepping on that grid. The
twin declares it:

* ``<CoSimulation hasEventMode="true">``: the importer instantiates with ``eventModeUsed`` and
  enters Event Mode at each activation of the clock;
* one input Clock, ``sample``, ``intervalVariability="fixed"`` without ``intervalDecimal``: a
  periodic clock whose interval is the ``sample_time`` parameter, which the importer reads with
  ``fmi3GetIntervalDecimal`` (and the shift, 0, with ``fmi3GetShiftDecimal``) in Initialization
  Mode, as FMI 3.0 section 2.2.8 prescribes for a fixed clock whose interval depends on a fixed
  parameter;
* every output is clocked by it (``clocks``, ``variability="discrete"``): computed at the
  activation from the inputs set then, and held until the next one; the outputs depend on the
  clock too, and leave the InitialUnknowns (FMI 3.0 lists no clocked variable there). The inputs
  stay continuous: an importer sets them as it does for any FMU, at every
  communication point and in Event Mode before it activates the clock; the law samples them at
  the activation (a clocked input could be set only in Event Mode while its clock is active,
  which a host without a notion of clocked inputs would break);
* FMU states are not offered (``canGetAndSetFMUState="false"``): what the shim holds between
  activations is not part of the FMI 2.0 slave's state.

The clock takes the value reference after ``time`` (the last variable), so value references stay
the variables' 1-based indices. The shim's FMI 3.0 layer, compiled with ``FTC_CLOCK_VR`` and
``FTC_INTERVAL_VR``, serves the clock (``fmu_src/toolchain/shim``); ``docs/fmus/clocked.md`` says
how a host drives it.
"""

from __future__ import annotations

from dataclasses import dataclass
from xml.etree import ElementTree

__all__ = ["CLOCK", "INTERVAL_PARAMETER", "ClockedDescription", "ClockedError", "clocked_model_description"]

CLOCK = "sample"  # the input clock's name
INTERVAL_PARAMETER = "sample_time"  # the fixed parameter that is the clock's interval


class ClockedError(ValueError):
    """The FMI 3.0 model description cannot be made a clocked controller (it names the reason)."""


@dataclass(frozen=True)
class ClockedDescription:
    """The clocked model description and the value references the shim is compiled with."""

    xml: bytes
    clock_vr: int  # the input clock's
    interval_vr: int  # the interval parameter's (FMI 3.0 numbering)


def clocked_model_description(xml: bytes) -> ClockedDescription:
    """The clocked twin of the FMI 3.0 model description ``xml`` (module docstring). ClockedError
    when it has no ``sample_time`` parameter, no output, or already a clock."""
    root = ElementTree.fromstring(xml)
    model = root.get("modelName", "?")
    if root.get("fmiVersion") != "3.0":
        raise ClockedError(f"{model}: not an FMI 3.0 model description")
    variables = root.find("ModelVariables")
    cosimulation = root.find("CoSimulation")
    if variables is None or cosimulation is None:
        raise ClockedError(f"{model}: no ModelVariables or no CoSimulation element")
    if variables.find("Clock") is not None:
        raise ClockedError(f"{model}: already declares a clock")
    by_name = {v.get("name"): v for v in variables}
    interval = by_name.get(INTERVAL_PARAMETER)
    if (interval is None or interval.tag != "Float64" or interval.get("causality") != "parameter"
            or interval.get("variability", "fixed") != "fixed"):
        raise ClockedError(f"{model}: no fixed Float64 parameter '{INTERVAL_PARAMETER}' to be the clock's "
                           "interval")
    clocked = [v for v in variables if v.get("causality") == "output"]
    if not clocked:
        raise ClockedError(f"{model}: no output to clock")
    clock_vr = max(int(v.get("valueReference", "0")) for v in variables) + 1

    root.set("modelName", f"{model} (clocked)")
    cosimulation.set("hasEventMode", "true")
    cosimulation.set("canGetAndSetFMUState", "false")
    cosimulation.set("canSerializeFMUState", "false")
    for v in clocked:
        v.set("variability", "discrete")
        v.set("clocks", str(clock_vr))
    ElementTree.SubElement(variables, "Clock", name=CLOCK, valueReference=str(clock_vr),
                           description=f"Activates the law every {INTERVAL_PARAMETER} s (its interval; "
                                       "shift 0)",
                           causality="input", variability="discrete", intervalVariability="fixed")
    structure = root.find("ModelStructure")
    assert structure is not None  # fmi3_model_description writes one
    for output in structure.iterfind("Output"):
        dependencies = output.get("dependencies")
        output.set("dependencies", " ".join([str(clock_vr), *(dependencies or "").split()]))
    clocked_vrs = {v.get("valueReference") for v in clocked}
    for unknown in structure.findall("InitialUnknown"):  # FMI 3.0: clocked variables are not listed
        if unknown.get("valueReference") in clocked_vrs:
            structure.remove(unknown)
    ElementTree.indent(root, space="  ")
    text = ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"
    return ClockedDescription(text, clock_vr, int(interval.get("valueReference", "0")))
