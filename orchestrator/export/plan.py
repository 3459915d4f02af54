"""The container's plan: what the engine's master would do with a validated System, written down
for ``fmu_src/container/container.c`` to replay.

Everything is computed here, at export time, by the engine's own reading and validation (SSD, SSV,
``--parameter-set``, ``--set``, units converted): the value buffer laid out as
:meth:`orchestrator.master.Master._layout` lays it out, the start-value calls as
:meth:`orchestrator.fmi.Instance.set_start_values` groups them, the gauss-seidel schedule
(``System.schedule``) and the jacobi transfers. One record per line; reals as hexadecimal floats
(exact), names percent-encoded.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from urllib.parse import quote

from ..errors import ScenarioError, UsageError
from ..master import NS_PER_S, grid
from ..system import ComponentModel, PortRef, System

__all__ = ["PLAN_VERSION", "Exposed", "Plan", "make_plan"]

PLAN_VERSION = "1"
TYPE_LETTER = {"Real": "r", "Integer": "i", "Enumeration": "i", "Boolean": "b", "String": "s"}
EXPOSABLE_PARAMETER_TYPES = ("Real", "Integer", "Boolean")


@dataclass(frozen=True)
class Exposed:
    """A variable of the container: ``<component>.<variable>`` of one of its FMUs."""

    port: PortRef
    kind: str  # "output", "input" or "parameter"
    type: str  # "Real", "Integer", "Boolean"
    start: float | int | bool | None  # inputs and parameters
    depends_on: tuple[str, ...] = ()  # outputs: names of the container inputs they depend on directly


@dataclass
class Plan:
    """The plan's records (``text``) and the container's variables in value-reference order."""

    folders: dict[str, str]  # component -> folder of its FMU under resources/fmus/
    exposed: list[Exposed]
    lines: list[str] = field(default_factory=list)

    def text(self, guid: str) -> str:
        """The plan file, with the container's GUID in its first record."""
        return "\n".join([f"container {PLAN_VERSION} {_word(guid)}", *self.lines]) + "\n"


def _word(text: str) -> str:
    """A token of the plan: ``=`` and the text percent-encoded (never empty, even for '')."""
    return "=" + quote(text, safe="-_.:{}")


def _real(value: float) -> str:
    return float(value).hex()


def _value(type_: str, value: object) -> str:
    if type_ == "Real":
        return _real(float(value))  # type: ignore[arg-type]  # a Real start value is a number
    if type_ in ("Integer", "Enumeration"):
        return str(int(value))  # type: ignore[call-overload]  # an Integer start value is a number
    if type_ == "Boolean":
        return "1" if value else "0"
    return _word(str(value))


def _default_start(comp: ComponentModel, name: str) -> float | int | bool:
    """The FMU's own start value of a variable, as the engine would pass it."""
    var = comp.variables[name]
    text = var.start if var.start is not None else "0"
    if var.type == "Real":
        return float(text)
    if var.type == "Boolean":
        return str(text).lower() in ("true", "1")
    return int(text)


def exposable(system: System) -> dict[str, Exposed]:
    """Every variable a container can expose, by name: each component's outputs (its SSD
    connectors), its inputs no connection feeds, and its Real, Integer and Boolean parameters."""
    found: dict[str, Exposed] = {}
    for comp in system.components.values():
        for o in comp.outputs:
            found[str(PortRef(comp.name, o))] = Exposed(PortRef(comp.name, o), "output", "Real", None)
        for i in comp.inputs:
            port = PortRef(comp.name, i)
            if port not in system.links:
                start = comp.start_values.get(i, comp.variables[i].start)
                found[str(port)] = Exposed(port, "input", "Real", float(start) if start is not None else 0.0)
        for v in comp.model.modelVariables:
            if v.causality == "parameter" and v.type in EXPOSABLE_PARAMETER_TYPES:
                port = PortRef(comp.name, v.name)
                start = comp.start_values.get(v.name, _default_start(comp, v.name))
                found[str(port)] = Exposed(port, "parameter", v.type, start)  # type: ignore[arg-type]
    return found


def select(system: System, patterns: Sequence[str]) -> list[Exposed]:
    """The variables to expose: ``patterns`` (shell patterns on ``<component>.<variable>``) among
    :func:`exposable`, else the default (unconnected inputs and every output). UsageError naming a
    pattern that matches nothing."""
    candidates = exposable(system)
    if not patterns:
        return [e for e in candidates.values() if e.kind in ("input", "output")]
    chosen: dict[str, Exposed] = {}
    for pattern in patterns:
        matched = [name for name in candidates if fnmatch.fnmatchcase(name, pattern)]
        if not matched:
            connected = [str(p) for p in system.links if fnmatch.fnmatchcase(str(p), pattern)]
            what = "is an input" if len(connected) == 1 else "are inputs"
            reason = (f": {', '.join(connected)} {what} fed by a connection (expose its source instead)"
                      if connected else "")
            raise UsageError(f"--expose '{pattern}' matches no output, unconnected input or parameter of the "
                             f"scenario{reason}")
        chosen.update((name, candidates[name]) for name in matched)
    order = list(candidates)
    return sorted(chosen.values(), key=lambda e: order.index(str(e.port)))


def _feeds(system: System) -> dict[PortRef, set[PortRef]]:
    """Each input port -> every output it reaches at one communication point (direct feedthrough
    through the component, then on along connections)."""
    reach: dict[PortRef, set[PortRef]] = {}

    def outputs_of(port: PortRef, seen: set[PortRef]) -> set[PortRef]:
        if port in seen:
            return set()
        seen.add(port)
        comp = system.components[port.component]
        found = {PortRef(comp.name, o) for o in comp.feedthrough.get(port.connector, ())}
        for out in list(found):
            for end, link in system.links.items():
                if link.start == out:
                    found |= outputs_of(end, seen)
        return found

    for comp in system.components.values():
        for v in comp.model.modelVariables:
            if v.causality == "input":
                port = PortRef(comp.name, v.name)
                reach[port] = outputs_of(port, set())
    return reach


def make_plan(system: System, start: float, step: float, master: str, exposed: Sequence[Exposed],
              folders: dict[str, str], time_variable: bool = False) -> Plan:
    """The plan of ``system`` run by ``master`` on the grid ``start + k * step``, exposing ``exposed``
    (value references 0, 1, ...) and, with ``time_variable``, the time (the next value reference:
    FMI 3.0's independent variable)."""
    if master == "gauss-seidel" and system.iterated:
        raise ScenarioError([f"{loop}: the container does not iterate algebraic loops (export with --master "
                             "jacobi, whose delayed connections have none)" for loop in system.loops])
    t0, h, _ = grid(start, start + step, step)
    components = list(system.components.values())
    index = {c.name: i for i, c in enumerate(components)}

    # -- the value buffer, as Master._layout lays it out --------------------------------------
    input_order: list[PortRef] = []
    for comp in components:
        for op in system.schedule:
            if op.kind == "set" and op.component == comp.name:
                input_order += [PortRef(op.component, i) for i in op.inputs]
    n_connected = len(input_order)
    for comp in components:
        input_order += [p for p in (PortRef(comp.name, i) for i in comp.inputs) if p not in system.links]
    slot = {p: 1 + j for j, p in enumerate(input_order)}
    for comp in components:
        for o in comp.outputs:
            slot[PortRef(comp.name, o)] = len(slot) + 1
    initial = {0: t0 / NS_PER_S}
    for comp in components:
        for i in comp.inputs:
            value = comp.start_values.get(i, comp.variables[i].start)
            initial[slot[PortRef(comp.name, i)]] = float(value) if value is not None else 0.0

    # -- start values, grouped by type as Instance.set_start_values calls them ---------------
    calls: list[tuple[int, str, list[tuple[int, object]]]] = []
    position: dict[PortRef, tuple[int, int]] = {}
    parameters = {e.port: e for e in exposed if e.kind == "parameter"}
    for comp in components:
        values = dict(comp.start_values)
        for port in parameters:
            if port.component == comp.name and port.connector not in values:
                values[port.connector] = _default_start(comp, port.connector)  # exposed: the host may set it
        by_type: dict[str, list[tuple[int, object]]] = {}
        for name, value in values.items():
            var = comp.variables[name]
            entries = by_type.setdefault(var.type, [])
            position[PortRef(comp.name, name)] = (len(calls) + list(by_type).index(var.type), len(entries))
            entries.append((var.valueReference, value))
        calls += [(index[comp.name], type_, entries) for type_, entries in by_type.items()]

    def vrs(comp: ComponentModel, names: Iterable[str]) -> list[int]:
        variables = comp.variables
        return [variables[n].valueReference for n in names]

    def batch(comp: ComponentModel, ports: Sequence[PortRef]) -> str:
        pairs = " ".join(f"{vr} {slot[p]}" for vr, p in zip(vrs(comp, [p.connector for p in ports]), ports,
                                                               strict=True))
        return f"{index[comp.name]} {len(ports)} {pairs}".rstrip()

    def transfers(ports: Sequence[PortRef]) -> str:
        links = [system.links[p] for p in ports]
        plain = [lk for lk in links if lk.factor == 1.0 and lk.offset == 0.0]
        scaled = [lk for lk in links if not (lk.factor == 1.0 and lk.offset == 0.0)]
        records = [f"0 {slot[lk.end]} {slot[lk.start]} {_real(1.0)} {_real(0.0)}" for lk in plain]
        records += [f"1 {slot[lk.end]} {slot[lk.start]} {_real(lk.factor)} {_real(lk.offset)}"
                    for lk in scaled]
        return " ".join([str(len(links)), *records])

    reach = _feeds(system)
    container_inputs = {e.port for e in exposed if e.kind == "input"}
    lines = [f"master {master}", f"grid {t0} {h}",
             f"sizes {len(slot)} {len(components)} {len(calls)} {len(system.schedule)} "
             f"{len(exposed) + time_variable}"]
    lines += [f"value {s} {_real(v)}" for s, v in initial.items()]
    for comp in components:
        c = comp.model.coSimulation
        lines.append(f"component {_word(comp.name)} {_word(folders[comp.name])} {_word(c.modelIdentifier)} "
                     f"{_word(comp.model.guid)}")
    for number, type_, entries in calls:
        pairs = " ".join(f"{vr} {_value(type_, v)}" for vr, v in entries)
        lines.append(f"starts {number} {TYPE_LETTER[type_]} {len(entries)} {pairs}")
    for op in system.schedule:
        comp = system.components[op.component]
        if op.kind == "get":
            lines.append(f"get {batch(comp, [PortRef(comp.name, o) for o in comp.outputs])}")
        else:
            ports = [PortRef(op.component, i) for i in op.inputs]
            lines.append(f"set {batch(comp, ports)} {transfers(ports)}")
    connected = input_order[:n_connected]
    for comp in components:
        lines.append(f"jacobi-in {batch(comp, [p for p in connected if p.component == comp.name])}")
        lines.append(f"jacobi-out {batch(comp, [PortRef(comp.name, o) for o in comp.outputs])}")
    lines.append(f"jacobi-transfers {transfers(connected)}")
    out: list[Exposed] = []
    for vr, e in enumerate(exposed):
        comp = system.components[e.port.component]
        if e.kind == "output":
            feeders = () if master == "jacobi" else tuple(
                str(p) for p in container_inputs if e.port in reach.get(p, set()))
            out.append(Exposed(e.port, e.kind, e.type, e.start, feeders))
            lines.append(f"exposed {vr} o r {slot[e.port]}")
        elif e.kind == "input":
            out.append(e)
            feeds = int(bool(reach.get(e.port)))
            lines.append(f"exposed {vr} i r {slot[e.port]} {index[comp.name]} "
                         f"{comp.variables[e.port.connector].valueReference} {feeds}")
        else:
            out.append(e)
            call, pos = position[e.port]
            lines.append(f"exposed {vr} p {TYPE_LETTER[e.type]} {call} {pos}")
    if time_variable:
        lines.append(f"exposed {len(exposed)} o r 0")  # slot 0 holds the time of the last communication point
    if not components:
        raise ScenarioError(f"{system.ssd}: the scenario has no component to export")
    return Plan(folders, out, lines)
