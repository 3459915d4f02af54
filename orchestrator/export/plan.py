# SPDX-License-Identifier: BSD-2-Clause
"""The container's plan: the engine's own :class:`~orchestrator.plan.Plan` of the validated System
(:func:`orchestrator.plan.make_plan`: layout, start values, grid, schedule), with the container's
variables added as ``exposed`` records for ``orchestrator/native/container.c`` to serve.

Everything is computed by the engine's own reading and validation (SSD, SSV, ``--parameter-set``,
``--set``, units converted); exposed parameters the scenario sets no value for get the FMU's own
start value as a start value, so that the host may change it.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Sequence
from dataclasses import dataclass

from ..errors import ScenarioError, UsageError
from ..plan import Plan, make_plan
from ..system import ComponentModel, PortRef, System, ssp_type

__all__ = ["Exposed", "container_plan", "exposable", "select"]

TYPE_LETTER = {"Real": "r", "Integer": "i", "Boolean": "b"}
EXPOSABLE_PARAMETER_TYPES = ("Real", "Integer", "Boolean")


@dataclass(frozen=True)
class Exposed:
    """A variable of the container: ``<component>.<variable>`` of one of its FMUs."""

    port: PortRef
    kind: str  # "output", "input" or "parameter"
    type: str  # "Real", "Integer", "Boolean"
    start: float | int | bool | None  # inputs and parameters
    depends_on: tuple[str, ...] = ()  # outputs: names of the container inputs they depend on directly


def _default_start(comp: ComponentModel, name: str) -> float | int | bool:
    """The FMU's own start value of a variable, as the engine would pass it."""
    var = comp.variables[name]
    text = var.start if var.start is not None else "0"
    type_ = ssp_type(comp.model, var)
    if type_ == "Real":
        return float(text)
    if type_ == "Boolean":
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
            type_ = ssp_type(comp.model, v)
            if v.causality == "parameter" and type_ in EXPOSABLE_PARAMETER_TYPES:
                port = PortRef(comp.name, v.name)
                start = comp.start_values.get(v.name, _default_start(comp, v.name))
                found[str(port)] = Exposed(port, "parameter", type_, start)  # type: ignore[arg-type]
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


def container_plan(system: System, start: float, stop: float, step: float, master: str,
                   exposed: Sequence[Exposed],
                   time_variable: bool = False) -> tuple[Plan, list[Exposed], list[str]]:
    """The engine's plan of ``system`` run by ``master`` on the grid ``start + k * step``, with the
    exposed parameters' start values added, the container's variables ``exposed`` (value references
    0, 1, ...; outputs with the container inputs they depend on directly) and their ``exposed``
    records; with ``time_variable``, the time as the next value reference (FMI 3.0's independent
    variable). ScenarioError for a loop gauss-seidel would iterate (the container does not)."""
    if not system.components:
        raise ScenarioError(f"{system.ssd}: the scenario has no component to export")
    if master == "gauss-seidel" and system.iterated:
        raise ScenarioError([f"{loop}: the container does not iterate algebraic loops (export with --master "
                             "jacobi, whose delayed connections have none)" for loop in system.loops])
    plan = make_plan(system, start, stop, step, master)
    index = {c.name: i for i, c in enumerate(plan.components)}
    added: dict[int, dict[str, tuple[str, int, object]]] = {}
    for e in exposed:
        if e.kind == "parameter":
            var = system.components[e.port.component].variables[e.port.connector]
            value = (var.type, int(var.valueReference), e.start)
            added.setdefault(index[e.port.component], {})[e.port.connector] = value
    plan = plan.with_starts(added)
    position = {(c.component, name): (number, j) for number, c in enumerate(plan.start_calls())
                for j, name in enumerate(c.names)}
    slot = {name: j for j, name in enumerate(plan.columns)}
    reach = _feeds(system)
    container_inputs = {e.port for e in exposed if e.kind == "input"}
    records: list[str] = []
    out: list[Exposed] = []
    for vr, e in enumerate(exposed):
        comp = system.components[e.port.component]
        if e.kind == "output":
            feeders = () if master == "jacobi" else tuple(
                str(p) for p in container_inputs if e.port in reach.get(p, set()))
            out.append(Exposed(e.port, e.kind, e.type, e.start, feeders))
            records.append(f"exposed {vr} o r {slot[str(e.port)]}")
        elif e.kind == "input":
            out.append(e)
            feeds = int(bool(reach.get(e.port)))
            records.append(f"exposed {vr} i r {slot[str(e.port)]} {index[comp.name]} "
                           f"{comp.variables[e.port.connector].valueReference} {feeds}")
        else:
            out.append(e)
            call, pos = position[(index[comp.name], e.port.connector)]
            records.append(f"exposed {vr} p {TYPE_LETTER[e.type]} {call} {pos}")
    if time_variable:
        records.append(f"exposed {len(exposed)} o r 0")  # slot 0: the time of the last communication point
    return plan, out, records
