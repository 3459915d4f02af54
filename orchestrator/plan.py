# SPDX-License-Identifier: BSD-2-Clause
"""The one plan of a run: what every executor does with a validated System, computed once.

:func:`make_plan` lays out the value buffer (``time``, the inputs, the outputs: the recorded row),
the grid ``t_k = t0 + k h`` in integer nanoseconds, each component's start values and its batched
calls, the gauss-seidel propagation (``System.schedule``: read a component's outputs, or transfer
connections into some of its inputs and write them), its algebraic loops, the jacobi transfers and
the inputs an input file drives. Three executors consume it and make the same FMI calls with the
same arguments in the same order, so their results are equal bit for bit:

* the Python master (:mod:`orchestrator.master`), which also serves ``--fmi-log``, FMI 1.0, loops
  iterated to a fixed point and the fast tier's fake instances;
* the compiled executor (:mod:`orchestrator.native`), which steps blocks of the run in C;
* the exported container (``orchestrate export``), which replays it inside one FMU.

The C executors read the plan as text (:meth:`Plan.text`): one record per line, space-separated
tokens, reals as C99 hexadecimal floats (exact), names percent-encoded (see
``orchestrator/native/plan.c``).

Every batch is a contiguous slice of the value buffer, so one ``fmi2GetReal``/``fmi2SetReal``
reads or writes it in place: a component's outputs, the connected inputs each set operation writes
(grouped per component in schedule order), and per component its unconnected inputs, those an input
file drives first.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import quote

import numpy as np

from .clocks import InputClock
from .system import INTEGERS, ComponentModel, PortRef, System

__all__ = ["MAX_TIME", "NS_PER_S", "PLAN_VERSION", "Batch", "Call", "GridError", "Plan", "PlanComponent",
           "Span", "StartCall", "Transfer", "grid", "make_plan", "start_calls", "time_grid"]

NS_PER_S = 1_000_000_000
MAX_TIME = (2**63 - 1) / NS_PER_S / 2  # s: t0 + n*h stays within int64 nanoseconds (292 years / 2)
PLAN_VERSION = "4"
TYPE_LETTER = {"Real": "r", "Float64": "r", "Integer": "i", "Enumeration": "i", "Int32": "i", "Boolean": "b",
               "String": "s"}


class GridError(ValueError):
    """A start time, stop time or step that gives no grid; ``quantities`` names those at fault
    (``"start time"``, ``"stop time"``, ``"communication step"``)."""

    def __init__(self, message: str, *quantities: str) -> None:
        super().__init__(message)
        self.quantities = quantities


def grid(start: float, stop: float, step: float) -> tuple[int, int, int]:
    """The grid t_k = t0 + k*h, k = 0..n, up to the last point not after ``stop``: t0 and h in
    integer nanoseconds (libcosim's time representation) and n. GridError when a time is not
    finite or beyond ``MAX_TIME``, the step is below 1 ns or the stop is before the start."""
    for name, x in (("start time", start), ("stop time", stop), ("communication step", step)):
        if not (math.isfinite(x) and abs(x) <= MAX_TIME):
            raise GridError(f"the {name} {x:g} s is not a finite time within +-{MAX_TIME:.3g} s", name)
    t0, t1, h = (round(x * NS_PER_S) for x in (start, stop, step))
    if h <= 0:
        raise GridError(f"the communication step must be positive and at least 1 ns (got {step!r} s)",
                        "communication step")
    if t1 < t0:
        raise GridError(f"the stop time {stop!r} s is before the start time {start!r} s", "start time",
                        "stop time")
    return t0, h, (t1 - t0) // h


def time_grid(start: float, stop: float, step: float) -> np.ndarray:
    """Communication points t_k = t0 + k*h, k = 0..n (:func:`grid`), in seconds, each computed in
    integer nanoseconds and rounded once."""
    t0, h, n = grid(start, stop, step)
    return (t0 + h * np.arange(n + 1, dtype=np.int64)) / NS_PER_S


@dataclass(frozen=True)
class Transfer:
    """A connection: ``values[dst] = values[src]`` (``plain``) or ``factor * values[src] + offset``."""

    dst: int
    src: int
    factor: float = 1.0
    offset: float = 0.0

    @property
    def plain(self) -> bool:
        """No transformation: the value is copied."""
        return self.factor == 1.0 and self.offset == 0.0


@dataclass(frozen=True)
class Batch:
    """One batched ``fmi2GetReal``/``fmi2SetReal`` of component ``component`` (its index in
    :attr:`Plan.components`): value references ``vrs`` <-> ``values[start:start + len(vrs)]``;
    the last ``ints`` of them are Integer or Enumeration variables, exchanged with
    ``fmi2GetInteger``/``fmi2SetInteger`` (a 32-bit int is exact in the float64 buffer)."""

    component: int
    vrs: tuple[int, ...]
    start: int
    ints: int = 0

    @property
    def slice(self) -> slice:
        """Where the batch's values are in the value buffer."""
        return slice(self.start, self.start + len(self.vrs))


@dataclass(frozen=True)
class Call:
    """One operation of the propagation at a communication point: read a component's outputs
    (``is_set`` False), or apply ``transfers`` (the copies first, then the transformed ones) and
    write the inputs of ``batch``."""

    is_set: bool
    batch: Batch
    transfers: tuple[Transfer, ...] = ()


@dataclass(frozen=True)
class Span:
    """Calls ``first`` to ``end`` of the propagation: run once, or (``loop``, an algebraic loop
    under gauss-seidel) swept until ``inputs`` (value slots) converge; ``components`` names them."""

    first: int
    end: int
    loop: bool = False
    inputs: tuple[int, ...] = ()
    components: tuple[str, ...] = ()


@dataclass(frozen=True)
class StartCall:
    """One call setting start values of one type on one component (as ``set_start_values`` groups
    them: one call per type, in the order the types first appear)."""

    component: int
    type: str
    vrs: tuple[int, ...]
    values: tuple[object, ...]
    names: tuple[str, ...]


def start_calls(component: int, starts: Mapping[str, tuple[str, int, object]]) -> list[StartCall]:
    """The start values ``name -> (type, value reference, value)`` of one component as calls, one
    per type in the order the types first appear (``fmi2SetReal``, ``fmi2SetInteger`` ...)."""
    by_type: dict[str, list[tuple[str, int, object]]] = {}
    for name, (type_, vr, value) in starts.items():
        by_type.setdefault(type_, []).append((name, vr, value))
    return [StartCall(component, type_, tuple(vr for _, vr, _ in entries), tuple(v for _, _, v in entries),
                      tuple(n for n, _, _ in entries))
            for type_, entries in by_type.items()]


@dataclass(frozen=True)
class PlanComponent:
    """One FMU instance of the plan: what to load, its start values (``name -> (type, value
    reference, value)``, in the order they are set) and its batches: every output (``outputs``),
    the connected inputs (``inputs``: jacobi writes them before each step) and those an input file
    drives (``driven``; ``columns``: their columns in the input series)."""

    name: str
    fmu: Path
    guid: str
    identifier: str
    fmi_version: str
    starts: Mapping[str, tuple[str, int, object]]
    outputs: Batch
    inputs: Batch
    driven: Batch
    columns: tuple[int, ...] = ()


@dataclass(frozen=True)
class Plan:
    """What a run does, in the order it does it (:func:`make_plan`): the grid ``t0``, ``h`` (integer
    nanoseconds) and ``n`` steps, the recorded ``columns`` and their ``initial`` values, the
    ``components``, the gauss-seidel ``propagation`` cut into ``spans``, the jacobi ``transfers``
    (every connection at once), where the outputs start (``first_output``) and the output columns in
    propagation order (``output_order``: the first non-finite value of a row is named from it) and the
    periodic input clocks of FMI 3.0 components (``clocks``: an interval of 0 is asked in
    Initialization Mode)."""

    master: str
    t0: int
    h: int
    n: int
    stop: float
    columns: tuple[str, ...]
    initial: tuple[float, ...]
    components: tuple[PlanComponent, ...]
    propagation: tuple[Call, ...]
    spans: tuple[Span, ...]
    transfers: tuple[Transfer, ...]
    first_output: int
    output_order: tuple[int, ...]
    clocks: tuple[tuple[int, InputClock], ...] = ()  # (component index, clock), in component order

    @property
    def start_time(self) -> float:
        """t0 in seconds."""
        return self.t0 / NS_PER_S

    def time(self, k: int) -> float:
        """t_k in seconds, rounded once from integer nanoseconds."""
        return (self.t0 + self.h * k) / NS_PER_S

    @property
    def iterates(self) -> bool:
        """Some span is an algebraic loop swept to a fixed point (gauss-seidel)."""
        return any(s.loop for s in self.spans)

    @property
    def driven(self) -> int:
        """How many inputs an input file drives."""
        return sum(len(c.driven.vrs) for c in self.components)

    def start_calls(self) -> list[StartCall]:
        """Every component's start-value calls, in component order."""
        return [call for i, c in enumerate(self.components) for call in start_calls(i, c.starts)]

    def with_starts(self, extra: Mapping[int, Mapping[str, tuple[str, int, object]]]) -> Plan:
        """The plan with start values added after a component's own (``component index -> name ->
        (type, value reference, value)``), where it has none of that name."""
        components = list(self.components)
        for i, values in extra.items():
            starts = dict(components[i].starts)
            for name, value in values.items():
                starts.setdefault(name, value)
            components[i] = replace(components[i], starts=starts)
        return replace(self, components=tuple(components))

    def text(self, guid: str = "", folders: Mapping[str, str] | None = None,
             exposed: Sequence[str] = ()) -> str:
        """The plan as the C executors read it: ``guid`` in its first record; each component's
        ``folder`` (``folders``; relative to the container's ``resources/fmus``) where the C code
        loads the FMU itself, none where the caller binds instances it made; ``exposed``: the
        container's ``exposed`` records."""
        folders = folders or {}
        calls = self.start_calls()
        lines = [f"plan {PLAN_VERSION} {word(guid)}", f"master {self.master}",
                 f"grid {self.t0} {self.h} {self.n}",
                 f"sizes {len(self.columns)} {len(self.components)} {len(calls)} {len(self.propagation)} "
                 f"{len(exposed)}"]
        lines += [f"value {slot} {real(v)}" for slot, v in enumerate(self.initial) if v or slot == 0]
        for c in self.components:
            lines.append(f"component {word(c.name)} {word(folders.get(c.name, ''))} {word(c.identifier)} "
                         f"{word(c.guid)} {c.fmi_version.split('.')[0]}")
        for call in calls:
            pairs = " ".join(f"{vr} {_value(call.type, v)}"
                             for vr, v in zip(call.vrs, call.values, strict=True))
            lines.append(f"starts {call.component} {TYPE_LETTER[call.type]} {len(call.vrs)} {pairs}".rstrip())
        for op in self.propagation:
            kind = "set" if op.is_set else "get"
            lines.append(f"{kind} {_batch(op.batch)} {_transfers(op.transfers)}".rstrip())
        for c in self.components:
            lines.append(f"io {_batch(c.inputs)} {_batch(c.outputs)} {_batch(c.driven)}")
        lines.append(f"transfers {_transfers(self.transfers)}")
        lines.append(" ".join(["clocks", str(len(self.clocks)), *(f"{i} {c.vr} {c.interval_ns} {c.shift_ns}"
                                                                 for i, c in self.clocks)]))
        return "\n".join([*lines, *exposed]) + "\n"


def word(text: str) -> str:
    """A token of the plan: ``=`` and the text percent-encoded (never empty, even for '')."""
    return "=" + quote(text, safe="-_.:{}")


def real(value: float) -> str:
    """A real of the plan: C99's hexadecimal float, exact."""
    return float(value).hex()


def _value(type_: str, value: object) -> str:
    letter = TYPE_LETTER[type_]
    if letter == "r":
        return real(float(value))  # type: ignore[arg-type]  # a Real start value is a number
    if letter == "i":
        return str(int(value))  # type: ignore[call-overload]  # an Integer start value is a number
    if letter == "b":
        return "1" if value else "0"
    return word(str(value))


def _batch(b: Batch) -> str:
    return " ".join(map(str, (b.component, b.start, len(b.vrs), b.ints, *b.vrs)))


def _transfers(transfers: Sequence[Transfer]) -> str:
    return " ".join([str(len(transfers)), *(f"{t.dst} {t.src} {real(t.factor)} {real(t.offset)}"
                                            for t in transfers)])


def _vrs(comp: ComponentModel, names: Iterable[str]) -> tuple[int, ...]:
    variables = comp.variables
    return tuple(int(variables[n].valueReference) for n in names)


def _input_order(system: System, driven: set[PortRef]) -> tuple[list[PortRef], int]:
    """The inputs' places in the value buffer and how many are connected: connected inputs in
    schedule order (each set operation a contiguous slice, grouped per component), then per component
    the unconnected ones, those an input file drives first."""
    order: list[PortRef] = []
    for comp in system.components.values():
        for op in system.schedule:
            if op.kind == "set" and op.component == comp.name:
                order += [PortRef(op.component, i) for i in _reals_first(comp, op.inputs)]
    n_connected = len(order)
    for comp in system.components.values():
        free = [p for p in (PortRef(comp.name, i) for i in comp.inputs) if p not in system.links]
        order += [p for p in free if p in driven] + [p for p in free if p not in driven]
    return order, n_connected


def _reals_first(comp: ComponentModel, names: Iterable[str]) -> list[str]:
    """``names`` with the Integer and Enumeration variables last (a batch's integer tail)."""
    variables = comp.variables
    return sorted(names, key=lambda n: variables[n].type in INTEGERS)


def _start_values(comp: ComponentModel) -> dict[str, tuple[str, int, object]]:
    """Parameters and start values from the SSD, .ssv files and overrides: name -> (type, vr, value)."""
    variables = comp.variables
    return {name: (variables[name].type, int(variables[name].valueReference), value)
            for name, value in comp.start_values.items()}


def make_plan(system: System, start: float, stop: float, step: float, master: str,
              driven: Sequence[PortRef] = ()) -> Plan:
    """The plan of ``system`` run by ``master`` (``gauss-seidel`` or ``jacobi``) on the grid
    ``start + k * step`` up to ``stop`` (which the FMUs' setup is told), the inputs ``driven`` (the
    ports of an input series, in its column order) set from an input file. GridError for a grid
    that does not exist."""
    t0, h, n = grid(start, stop, step)
    components = list(system.components.values())
    index = {c.name: i for i, c in enumerate(components)}
    input_order, n_connected = _input_order(system, set(driven))
    columns = ["time", *(str(p) for p in input_order)]
    slot = {p: 1 + j for j, p in enumerate(input_order)}
    first_output = len(columns)
    for comp in components:
        for o in comp.outputs:
            slot[PortRef(comp.name, o)] = len(columns)
            columns.append(str(PortRef(comp.name, o)))
    initial = [0.0] * len(columns)
    initial[0] = t0 / NS_PER_S
    for comp in components:
        for i in comp.inputs:
            value = comp.start_values.get(i, comp.variables[i].start)
            initial[slot[PortRef(comp.name, i)]] = float(value) if value is not None else 0.0

    def batch(comp: ComponentModel, ports: Sequence[PortRef]) -> Batch:
        first = slot[ports[0]] if ports else 0
        assert [slot[p] for p in ports] == list(range(first, first + len(ports)))  # laid out contiguous
        names = [p.connector for p in ports]
        assert names == _reals_first(comp, names)  # the integers last
        ints = sum(comp.variables[n].type in INTEGERS for n in names)
        return Batch(index[comp.name], _vrs(comp, names), first, ints)

    def transfers(ports: Sequence[PortRef]) -> tuple[Transfer, ...]:
        links = [system.links[p] for p in ports]
        made = [Transfer(slot[lk.end], slot[lk.start], float(lk.factor), float(lk.offset)) for lk in links]
        return tuple([t for t in made if t.plain] + [t for t in made if not t.plain])

    connected = input_order[:n_connected]
    parts = []
    for comp in components:
        outputs = [PortRef(comp.name, o) for o in comp.outputs]
        fed = [p for p in input_order[n_connected:] if p.component == comp.name and p in driven]
        parts.append(PlanComponent(
            comp.name, Path(comp.fmu), comp.model.guid, comp.model.coSimulation.modelIdentifier,
            comp.model.fmiVersion, _start_values(comp), batch(comp, outputs),
            batch(comp, [p for p in connected if p.component == comp.name]), batch(comp, fed),
            tuple(list(driven).index(p) for p in fed)))
    calls = []
    for op in system.schedule:
        comp = system.components[op.component]
        if op.kind == "get":
            calls.append(Call(False, parts[index[comp.name]].outputs))
        else:
            ports = [PortRef(op.component, i) for i in _reals_first(comp, op.inputs)]
            calls.append(Call(True, batch(comp, ports), transfers(ports)))
    read = [op.component for op in system.schedule if op.kind == "get"]
    read += [name for name in system.components if name not in read]
    output_order = tuple(slot[PortRef(name, o)] for name in read for o in system.components[name].outputs)
    return Plan(master, t0, h, n, float(stop), tuple(columns), tuple(initial), tuple(parts), tuple(calls),
                _spans(calls, system.iterated if master == "gauss-seidel" else [], components),
                transfers(connected), first_output, output_order,
                tuple((index[c.name], clock) for c in components for clock in c.clocks))


def _spans(calls: list[Call], iterated: Sequence[tuple[int, int]],
           components: Sequence[ComponentModel]) -> tuple[Span, ...]:
    """The propagation cut into spans: run once, or (an algebraic loop) repeated until it converges."""
    spans, cut = [], 0
    for first, end in iterated:
        if first > cut:
            spans.append(Span(cut, first))
        loop = calls[first:end]
        inputs = tuple(t.dst for call in loop for t in call.transfers)
        names = tuple(dict.fromkeys(components[call.batch.component].name for call in loop))
        spans.append(Span(first, end, True, inputs, names))
        cut = end
    if cut < len(calls) or not spans:
        spans.append(Span(cut, len(calls)))
    return tuple(spans)
