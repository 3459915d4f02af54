# SPDX-License-Identifier: BSD-2-Clause
"""FMI 3.0 clocks the masters drive: periodic input clocks of Co-Simulation FMUs in event mode.

An FMI 3.0 Co-Simulation FMU with ``hasEventMode="true"`` may declare input clocks; the importer
instantiates it with ``eventModeUsed``, and at every tick of a clock enters event mode, activates
the clock (``fmi3SetClock``), lets the clocked partition run (``fmi3UpdateDiscreteStates`` until no
more updates are needed) and returns to step mode (FMI 3.0, 4.2.3 and 5.2.2 "Co-Simulation with
Clocks"). What is supported here, and refused in one line naming the SSD, the component and the
clock otherwise:

* input clocks of ``intervalVariability`` ``constant`` or ``fixed`` with an interval: the FMU's
  ``intervalDecimal``, or the SSD's (an SSP 2.0 ``ssc:Clock`` connector's ``intervalDecimal``; both
  given must agree), and ``shiftDecimal`` (default 0): ticks at ``t0 + shift + j * interval``; a
  ``fixed`` clock that neither gives is asked in Initialization Mode (``fmi3GetIntervalDecimal``,
  ``fmi3GetShiftDecimal``), as FMI 3.0 (2.2.8) prescribes for an interval that depends on fixed
  parameters (:meth:`InputClock.asked`);
* its inputs unclocked (set in step mode, held through the tick: the clocked partition samples
  them) and its clocked outputs read after the tick.

Triggered, countdown, changing and tunable clocks, output clocks, clocked inputs, and an FMU with
clocks but no event mode (Scheduled Execution) are refused.

Tick times are integer nanoseconds, as the masters' grid (:mod:`orchestrator.plan`), so a tick
lands on a communication point exactly where both coincide.
"""

from __future__ import annotations

import math
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from fmpy.model_description import ModelDescription, ModelVariable
from lxml import etree

from . import fmucache
from .ssp import Connector

__all__ = ["InputClock", "due", "input_clocks", "next_tick", "pieces"]

NS_PER_S = 1_000_000_000
PERIODIC = ("constant", "fixed")


@dataclass(frozen=True)
class InputClock:
    """A periodic input clock of one FMU: ``vr`` its value reference, ticks every ``interval_ns``
    from ``shift_ns`` after the start time (integer nanoseconds). ``interval_ns`` 0: a fixed clock
    whose interval and shift the FMU gives in Initialization Mode (:meth:`asked`)."""

    name: str
    vr: int
    interval_ns: int
    shift_ns: int = 0

    def asked(self, interval: float, shift: float) -> InputClock:
        """This clock with the interval and shift (seconds) the FMU gave; ValueError naming the
        clock when the interval is not positive and finite or the shift negative."""
        if not (math.isfinite(interval) and _ns(interval) > 0 and math.isfinite(shift) and shift >= 0):
            raise ValueError(f"input clock '{self.name}': the FMU gives interval {interval!r} s and shift "
                             f"{shift!r} s (fmi3GetIntervalDecimal, fmi3GetShiftDecimal): the interval must "
                             "be positive, the shift at least 0")
        return InputClock(self.name, self.vr, _ns(interval), _ns(shift))

    def tick_at_or_after(self, t_ns: int, t0_ns: int) -> int:
        """The first tick at or after ``t_ns`` (a run started at ``t0_ns``)."""
        first = t0_ns + self.shift_ns
        if t_ns <= first:
            return first
        j = -(-(t_ns - first) // self.interval_ns)  # ceiling
        return first + j * self.interval_ns


def _ns(seconds: float) -> int:
    return round(seconds * NS_PER_S)


def _decimals(fmu: Path | None) -> dict[str, tuple[float | None, float | None]]:
    """Each Clock's ``intervalDecimal`` and ``shiftDecimal`` as the FMU's model description (or a
    ``modelDescription.xml`` itself) gives them (fmpy 0.3 does not read them); empty when the file
    cannot be read."""
    if fmu is None:
        return {}
    parser = etree.XMLParser(resolve_entities=False, no_network=True)
    try:
        if fmu.suffix == ".xml":
            root = etree.parse(str(fmu), parser).getroot()
        else:
            with zipfile.ZipFile(fmucache.materialize(fmu)) as zf, zf.open("modelDescription.xml") as xml:
                root = etree.parse(xml, parser).getroot()
    except (OSError, KeyError, zipfile.BadZipFile, etree.XMLSyntaxError):
        return {}

    def number(text: str | None) -> float | None:
        try:
            return None if text is None else float(text)
        except ValueError:
            return None
    return {c.get("name", ""): (number(c.get("intervalDecimal")), number(c.get("shiftDecimal")))
            for c in root.iter("Clock")}


def input_clocks(where: str, md: ModelDescription, declared: Iterable[Connector] = (),
                 fmu: Path | None = None) -> tuple[list[InputClock], list[str]]:
    """The periodic input clocks of an FMU and the problems that refuse it (one line each, naming
    ``where`` — the SSD and component — and the clock); both empty for an FMU without clocks.
    ``declared``: the component's SSD connectors, whose Clock ``intervalDecimal`` gives the interval
    of a ``fixed`` clock the FMU leaves open; ``fmu``: the FMU file, whose model description gives
    the clocks' ``intervalDecimal`` and ``shiftDecimal``."""
    variables = [v for v in md.modelVariables if v.type == "Clock"]
    if not variables:
        return [], []
    decimals = _decimals(fmu)
    cs = md.coSimulation
    if cs is None or not cs.hasEventMode:
        return [], [f"{where}: the FMU has clocks ({', '.join(v.name for v in variables)}) but its "
                    "Co-Simulation interface has no event mode (hasEventMode): Scheduled Execution is not "
                    "supported"]
    from_ssd = {k.name: k.interval for k in declared if k.type == "Clock" and k.interval is not None}
    clocks, problems = [], []
    for v in md.modelVariables:
        on = [c for c in (v.clocks or []) if c is not None]
        if v.causality == "input" and v.type != "Clock" and on:
            problems.append(f"{where}: input '{v.name}' is clocked by {', '.join(c.name for c in on)}: "
                            "clocked inputs are not supported (declare the input unclocked: the clocked "
                            "partition samples it at the tick)")
    for v in variables:
        clock = _input_clock(where, v, decimals, from_ssd)
        if isinstance(clock, str):
            problems.append(clock)
        else:
            clocks.append(clock)
    return clocks, problems


def _input_clock(where: str, v: ModelVariable, decimals: dict[str, tuple[float | None, float | None]],
                 from_ssd: dict[str, float]) -> InputClock | str:
    """The clock variable ``v`` as the master ticks it, or the one line that refuses it."""
    if v.causality != "input":
        return f"{where}: clock '{v.name}' is an {v.causality} clock: only input clocks are supported"
    variability = v.intervalVariability or ""
    if variability not in PERIODIC:
        return (f"{where}: input clock '{v.name}' has intervalVariability '{variability}': only periodic "
                f"clocks ({', '.join(PERIODIC)}) are supported")
    interval, shift = decimals.get(v.name, (v.intervalDecimal, v.shiftDecimal))
    ssd = from_ssd.get(v.name)
    if interval is None:
        interval = ssd
    elif ssd is not None and not math.isclose(ssd, interval, rel_tol=1e-12):
        return (f"{where}: input clock '{v.name}': the SSD's intervalDecimal {ssd!r} differs from the FMU's "
                f"{interval!r}")
    if interval is None and variability == "fixed":
        return InputClock(v.name, v.valueReference, 0)  # asked in Initialization Mode
    if interval is None or not math.isfinite(interval) or _ns(interval) <= 0:
        return (f"{where}: input clock '{v.name}' has no positive interval (intervalDecimal, in the FMU or "
                "the SSD's Clock connector)")
    return InputClock(v.name, v.valueReference, _ns(interval), _ns(shift or 0.0))


def next_tick(clocks: Sequence[InputClock], after_ns: int, t0_ns: int) -> int | None:
    """The first tick of any of ``clocks`` strictly after ``after_ns``; None without clocks."""
    if not clocks:
        return None
    return min(c.tick_at_or_after(after_ns + 1, t0_ns) for c in clocks)


def due(clocks: Sequence[InputClock], t_ns: int, t0_ns: int) -> list[InputClock]:
    """The clocks that tick at ``t_ns``."""
    return [c for c in clocks if c.tick_at_or_after(t_ns, t0_ns) == t_ns]


def pieces(clocks: Sequence[InputClock], start_ns: int, end_ns: int, t0_ns: int) -> list[int]:
    """Where a step from ``start_ns`` to ``end_ns`` is cut: the end of each piece, every tick of
    ``clocks`` inside it and then ``end_ns`` (just ``[end_ns]`` without a tick)."""
    ends = []
    while start_ns < end_ns:
        tick = next_tick(clocks, start_ns, t0_ns)
        start_ns = end_ns if tick is None or tick > end_ns else tick
        ends.append(start_ns)
    return ends
