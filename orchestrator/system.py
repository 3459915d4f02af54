# SPDX-License-Identifier: BSD-2-Clause
"""The co-simulation system: components, connections and parameters, validated on construction.

``System`` joins what the SSD says with what each FMU's modelDescription.xml says, collects every
inconsistency into one ScenarioError, and derives the order in which outputs must be read and
inputs set at a communication point (from the ModelStructure dependencies), so that an input is
set only after the outputs it depends on are up to date. Real algebraic loops are named by the
ports on the loop (a warning) and become spans of the schedule that gauss-seidel iterates.
"""

from __future__ import annotations

import copy
import os
import re
import zipfile
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import SupportsFloat, SupportsIndex, SupportsInt, TypeVar

import fmpy
from fmpy import read_model_description, validation
from fmpy.model_description import ModelDescription, ModelVariable, Unit, ValidationError
from fmpy.validation import validate_model_description
from lxml import etree

from . import fmucache
from .clocks import InputClock, input_clocks
from .errors import ScenarioError, option
from .ssp import Component, Connection, Connector, Parameter, ParameterSet, PortRef, SystemStructure
from .units import BASE, UnitDef, UnitError, conversion, convert, resolve, split_value

__all__ = ["FMI3_TYPES", "INTEGERS", "ComponentModel", "Operation", "PortRef", "System", "ssp_type"]

FMU_TYPES = {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean", "String": "String",
             "Enumeration": "Enumeration"}
# FMI 3.0 scalar types and the SSP 1.0 type they are exchanged and set as (SSP 1.0 predates FMI
# 3.0; SSP tools connect ssc:Real to Float64); the other FMI 3.0 types are refused where used.
FMI3_TYPES = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean"}
INTEGERS = ("Integer", "Enumeration")  # SSP types exchanged as integers (exact in float64)
SETTABLE = ("parameter", "input")


@dataclass(frozen=True)
class Operation:
    """One step of the propagation at a communication point: read a component's outputs
    (``inputs`` empty) or set the listed inputs of a component."""

    kind: str
    component: str
    inputs: tuple[str, ...] = ()


@dataclass
class ComponentModel:
    """One FMU instance: its model description and the values to apply before initialization;
    ``outputs`` and ``inputs`` are those exchanged and recorded: every Real connector, then the
    Integer and Enumeration ones a connection uses."""

    name: str
    fmu: Path
    model: ModelDescription
    outputs: list[str]
    inputs: list[str]
    start_values: dict[str, float | int | bool | str] = field(default_factory=dict)
    feedthrough: dict[str, set[str]] = field(default_factory=dict)
    origins: dict[str, str] = field(default_factory=dict)  # variable -> where its start value came from
    clocks: list[InputClock] = field(default_factory=list)  # periodic input clocks the master ticks

    @property
    def variables(self) -> dict:
        """Variables of the FMU by name."""
        return {v.name: v for v in self.model.modelVariables}


class System:
    """Validated system: ``components`` (SSD order), ``links`` (by end port) and the propagation
    ``schedule``.

    ``parameter_sets`` name parameters ``<component>.<variable>`` and apply after the SSD's own
    bindings; ``overrides`` (``"component.variable" -> value``) apply last.

    Every check runs, each as far as what is known allows, and every problem is collected in
    ``problems``; with ``strict`` (the default) they raise one ScenarioError. Components named in
    ``no_fmu`` (FMU missing, already reported) are checked only as far as the SSD goes; those in
    ``partial`` (some parameter values unreadable, already reported) are not checked for inputs
    without a value. Inputs left at the FMU's start value, with no connection and no value given,
    are listed in ``unconnected`` (and ``warnings``). What fmpy's checks of a model description find
    (a unit used but not defined, an Enumeration marked continuous, ...) goes to ``warnings`` when
    the FMU can still run as the other tools run it (``strict_fmus``: to ``problems``, for CI);
    ``fmu_warnings`` adds fmpy's full FMU validation (``validate_fmu``) to ``warnings``.

    Algebraic loops (a cycle of direct feedthrough through connections) are no error: ``loops``
    lists them (and ``warnings``); under gauss-seidel ``iterated`` holds the spans ``(first, end)``
    of the ``schedule`` that the master repeats until the inputs on them converge, under jacobi every
    connection is delayed and there is no loop. ``schedule`` is empty when there are problems.
    """

    def __init__(self, structure: SystemStructure,
                 parameter_sets: Iterable[ParameterSet] = (),
                 overrides: Mapping[str, object] | None = None,
                 model_descriptions: Mapping[Path, ModelDescription] | None = None, *,
                 strict: bool = True, no_fmu: Collection[str] = (), partial: Collection[str] = (),
                 fmu_warnings: bool = False, strict_fmus: bool = False) -> None:
        self.structure = structure
        self.strict_fmus = strict_fmus
        self.ssd = structure.ssd_file
        self.problems: list[str] = []
        self.warnings: list[str] = []
        problems = self.problems
        self.components: dict[str, ComponentModel] = {}
        names: set[str] = set()
        self._connected = {port for con in structure.connections for port in (con.start, con.end)}
        # one model description per FMU, however many components use it (16 copies of example1 read
        # 64, 1.6 MB; issue 46): nothing changes it, the start values given live in each component
        read = dict(model_descriptions or {})
        for c in structure.components:
            if c.name in names:
                problems.append(f"{self.ssd}: component name '{c.name}' is used twice")
                continue
            names.add(c.name)
            if c.name not in no_fmu:
                md = self._model_description(c, read.get(c.source), fmu_warnings)
                if md is not None:
                    read[c.source] = md
                    self.components[c.name] = self._component(c, md, problems)
        self.links: dict[PortRef, Connection] = {}
        self._check_connections(problems)
        self._check_units(problems)
        parameter_sets = list(parameter_sets)
        for name, ps in structure_sets(structure):
            self._apply(name, ps, problems)
        for ps in parameter_sets:
            self._apply_prefixed(ps, problems)
        for key, value in (overrides or {}).items():
            self._override(key, value, problems)
        self.values_checked = (sum(len(ps.parameters) for _, ps in structure_sets(structure))
                               + sum(len(ps.parameters) for ps in parameter_sets) + len(overrides or {}))
        self._check_inputs(problems, partial)
        self.loops = self._algebraic_loops()
        self.warnings.extend(f"{loop} (gauss-seidel iterates it to a fixed point at every communication "
                             "point; jacobi delays every connection by one step)" for loop in self.loops)
        self.schedule: list[Operation] = []
        self.iterated: list[tuple[int, int]] = []
        if problems:
            if strict:
                raise ScenarioError(problems)
            return
        self.schedule, self.iterated = self._schedule()

    # -- construction -----------------------------------------------------------------------
    def _model_description(self, c: Component, md: ModelDescription | None,
                           fmu_warnings: bool) -> ModelDescription | None:
        """The FMU's model description when it passes the checks a run needs (else None, with the
        problems recorded); with ``fmu_warnings`` also fmpy's full validation, as warnings."""
        where = f"{self.ssd}: component '{c.name}': FMU '{os.path.basename(c.source)}'"
        try:
            md = md or read_model_description(str(fmucache.entry_of(c.source) or c.source), validate=False)
        except Exception as exc:  # fmpy raises plain Exception for unreadable FMUs
            self.problems.append(f"{where}: cannot read modelDescription.xml: {exc}")
            return None
        # fmpy's checks, except a missing input start, which _check_inputs reports in context: the
        # FMU still loads (OMSimulator and libcosim run it), so a warning unless strict_fmus
        found = validate_model_description(md)
        inputs = {v.name for v in md.modelVariables if v.causality == "input"}
        invalid = [p for p in found if not _is_input_start(p, inputs)]
        if fmu_warnings:
            known = set(found)
            self.warnings.extend(f"{where}: {p}" for p in fmu_findings(fmucache.materialize(c.source), md)
                                 if p not in known and not _is_input_start(p, inputs))
        (self.problems if self.strict_fmus else self.warnings).extend(f"{where}: {p}" for p in invalid)
        bad_starts = [f"variable '{v.name}': start=\"{v.start}\" is no {v.type} value"
                      for v in md.modelVariables if not _start_ok(v)]  # FMI 3.0: fmpy keeps it a string
        self.problems.extend(f"{where}: {p}" for p in bad_starts)  # a run would fail on it at once
        if (invalid and self.strict_fmus) or bad_starts:
            return None
        if md.coSimulation is None:
            kind = "Model Exchange" if md.modelExchange is not None else "no"
            self.problems.append(f"{self.ssd}: component '{c.name}': FMU is an FMI {md.fmiVersion} {kind} "
                                 "FMU: orchestrate runs Co-Simulation FMUs only")
            return None
        missing = _no_binary(c.source, md)
        if missing:
            self.problems.append(f"{where}: {missing}")
            return None
        return md

    def _component(self, c: Component, md: ModelDescription, problems: list[str]) -> ComponentModel:
        variables = {v.name: v for v in md.modelVariables}
        outputs: list[str] = []
        inputs: list[str] = []
        for k in c.connectors:
            where = f"{self.ssd}: component '{c.name}', connector '{k.name}'"
            v = variables.get(k.name)
            if v is None and PortRef(c.name, k.name) not in self._connected:
                self.warnings.append(f"{where}: the FMU has no variable of that name; no connection uses it, "
                                     "so it is left out (as OMSimulator leaves it; Dymola writes its wrapper "
                                     "parameters so)")
                continue
            if v is None:
                problems.append(f"{where}: the FMU has no variable of that name")
                continue
            if v.type == "Clock" or k.type == "Clock":
                if v.type != k.type:
                    problems.append(f"{where}: declared type {k.type} but the FMU's variable is {v.type}")
                continue  # ticked by the master (orchestrator.clocks), never exchanged as a value
            if v.causality != k.kind:
                problems.append(f"{where}: declared kind '{k.kind}' but the FMU's causality is "
                                f"'{v.causality}'")
                continue
            type_ = ssp_type(md, v)
            if type_ is None:
                problems.append(f"{where}: {_unsupported(md, v)}")
                continue
            if k.type is not None and FMU_TYPES.get(str(_exchanged(k.type))) != type_ and k.type != v.type:
                problems.append(f"{where}: declared type {k.type} but the FMU's variable is {v.type}")
                continue
            if k.unit is not None and _unit_name(v) is not None:
                try:
                    declared, own = self._resolve(k.unit), _unit_def(md, v)
                except UnitError as exc:
                    problems.append(f"{where}: {exc}")
                    continue
                if replace(declared, name="") != replace(own, name=""):
                    problems.append(f"{where}: declared unit {k.unit} but the FMU's variable is in "
                                    f"{own.name}")
            if type_ == "Real":  # recorded and exchanged (integers a connection uses: _integer_link)
                (outputs if k.kind == "output" else inputs if k.kind == "input" else []).append(k.name)
        feedthrough: dict[str, set[str]] = {}
        all_inputs = {v.name for v in md.modelVariables if v.causality == "input"}
        for output, deps in _dependencies(c.source, md, all_inputs).items():
            for d in deps:
                feedthrough.setdefault(d, set()).add(output)
        clocks, clock_problems = input_clocks(f"{self.ssd}: component '{c.name}'", md, c.connectors, c.source)
        problems.extend(clock_problems)
        return ComponentModel(c.name, c.source, md, outputs, inputs, feedthrough=feedthrough, clocks=clocks)

    def _check_connections(self, problems: list[str]) -> None:
        declared = {c.name: {k.name: k for k in c.connectors} for c in self.structure.components}
        for con in self.structure.connections:
            start, end = con.start, con.end
            where = f"{self.ssd}: connection {con}"
            ends = [declared.get(p.component, {}).get(p.connector) for p in (start, end)]
            if any(k is not None and k.type == "Clock" for k in ends):
                self._clock_connection(where, ends, problems)
                continue
            bad = False
            for port, kind in ((start, "output"), (end, "input")):
                if port.component not in declared:
                    problems.append(f"{where}: no component named '{port.component}'")
                    bad = True
                elif port.connector not in declared[port.component]:
                    problems.append(f"{where}: component '{port.component}' declares no connector "
                                    f"'{port.connector}'")
                    bad = True
                elif declared[port.component][port.connector].kind != kind:
                    problems.append(f"{where}: {port} is an {declared[port.component][port.connector].kind}, "
                                    f"not an {kind}")
                    bad = True
            if bad:
                continue
            t_start = _exchanged(declared[start.component][start.connector].type)
            t_end = _exchanged(declared[end.component][end.connector].type)
            integers = {t_start, t_end} <= set(INTEGERS)
            if t_start != t_end and not integers:
                problems.append(f"{where}: type mismatch ({start} is {t_start}, {end} is {t_end})")
            elif t_start != "Real" and not integers:
                problems.append(f"{where}: only Real, Integer and Enumeration connections are supported "
                                f"({start} is {t_start})")
            elif end in self.links:
                problems.append(f"{where}: input {end} is already connected to {self.links[end].start}")
            elif integers and self._integer_link(con, where, t_start, t_end, problems):
                self.links[end] = con
            elif not integers:
                self.links[end] = con

    def _integer_link(self, con: Connection, where: str, t_start: str | None, t_end: str | None,
                      problems: list[str]) -> bool:
        """Whether an Integer or Enumeration connection can run: its value is exchanged exactly (an
        FMI 1.0/2.0 Integer is a 32-bit int, exact in the float64 value buffer) and copied
        unchanged; its ports join the component's exchanged inputs and outputs (after the Real
        ones). Integer <-> Enumeration passes the number, as OMSimulator does (a warning: the
        FMU must accept it as an item)."""
        comps = [self.components.get(p.component) for p in (con.start, con.end)]
        if con.transformed:
            problems.append(f"{where}: a LinearTransformation on an {t_start} connection (SSP 1.0 defines it "
                            "for Real connections only)")
            return False
        if any(c is not None and c.model.fmiVersion.startswith("3.") for c in comps):
            problems.append(f"{where}: {t_start} connections of FMI 3.0 FMUs are not supported yet "
                            "(FMI 1.0 and 2.0 are)")
            return False
        if t_start != t_end:
            self.warnings.append(f"{where}: {con.start} is {t_start}, {con.end} is {t_end}: the integer "
                                 "value is passed unchanged (as OMSimulator passes it; the FMU must accept "
                                 "it as an item)")
        for comp, port, kind in ((comps[0], con.start, "outputs"), (comps[1], con.end, "inputs")):
            names = getattr(comp, kind) if comp is not None else None
            if names is not None and port.connector not in names:
                names.append(port.connector)
        return True

    def _clock_connection(self, where: str, ends: list[Connector | None], problems: list[str]) -> None:
        """An SSP 2.0 connection of Clock connectors. Between two periodic input clocks of equal
        interval it states what the master does anyway (both tick together) and is accepted; any
        other (an output or triggered clock driving another) is refused: the master ticks each
        periodic input clock on its own schedule and propagates no clock."""
        if any(k is None or k.type != "Clock" for k in ends):
            problems.append(f"{where}: a Clock connector can only be connected to a Clock connector")
            return
        intervals = {k.interval for k in ends if k is not None}
        if any(k is not None and k.kind != "input" for k in ends) or len(intervals) != 1 or None in intervals:
            problems.append(f"{where}: only connections of two periodic input clocks of the same interval "
                            "(intervalDecimal on both connectors) are supported: orchestrate ticks each "
                            "input clock on its own schedule and does not propagate clocks")

    def _check_units(self, problems: list[str]) -> None:
        """A connection joins units of the same dimension where both ends declare one (the SSD
        connector's unit, else the FMU variable's): equal units pass the value unchanged, scalings
        of each other (deg -> rad, ms -> s, degC -> K) get the implied conversion, other dimensions
        are an error. As SSP 1.0.1 orders it (4.5.2.1), the conversion comes first and the
        connection's LinearTransformation applies to the converted value: the link's factor and
        offset become the composition, and a warning shows it (tools differ here). With
        ``suppressUnitConversion`` the transformation alone applies and the units are not judged."""
        for end, con in list(self.links.items()):
            if con.suppress_units:
                continue
            try:
                start, target = self._port_unit(con.start), self._port_unit(con.end)
            except UnitError as exc:
                problems.append(f"{self.ssd}: connection {con}: {exc}")
                continue
            except _UndefinedUnitError as exc:  # the FMU's own fault, which fmpy's checks reported
                self.warnings.append(f"{self.ssd}: connection {con}: {exc.args[0]}: the value is passed "
                                     "unchanged" + (" by the LinearTransformation alone" if con.transformed
                                                    else ""))
                continue
            if start is None or target is None or start.name == target.name:
                continue
            try:
                factor, offset = conversion(start, target)
            except UnitError:
                hint = (" (if the LinearTransformation is meant as the conversion, set "
                        "suppressUnitConversion=\"true\" on the connection)" if con.transformed else "")
                problems.append(f"{self.ssd}: connection {con}: unit mismatch ({con.start} is in "
                                f"{start.name}, {con.end} in {target.name}){hint}")
                continue
            if (factor, offset) == (1.0, 0.0):
                continue
            composed = replace(con, factor=con.factor * factor, offset=con.factor * offset + con.offset)
            if con.transformed:
                self.warnings.append(
                    f"{self.ssd}: connection {con}: {start.name} -> {target.name} is converted before the "
                    f"LinearTransformation (factor {con.factor:g}, offset {con.offset:g}), as SSP 1.0.1 "
                    f"4.5.2.1 orders it: {con.end} = {composed.factor:.12g} * {con.start} + "
                    f"{composed.offset:.12g} (suppressUnitConversion=\"true\" applies the transformation "
                    "alone)")
            self.links[end] = composed

    def _resolve(self, name: str, *definitions: Iterable[UnitDef],
                 fmu: ModelDescription | None = None) -> UnitDef:
        """A unit named in the SSD or a parameter set: the files' own definitions, then (``fmu``) the
        UnitDefinitions of the FMU the value goes to (a value in ``bar`` for a variable whose FMU
        defines bar: OMSimulator's acvs files give them so), else the known names."""
        tables = [{u.name: u for u in d} for d in (*definitions, self.structure.units)]
        if fmu is not None:
            tables.append({u.name: _definition(u) for u in fmu.unitDefinitions if u.baseUnit is not None})
        return resolve(name, *tables)

    def _given_unit(self, name: str, units: Iterable[UnitDef], fmu: ModelDescription, label: str) -> UnitDef:
        """The unit a parameter value is given in (:meth:`_resolve`); a name in brackets that no file
        defines (``[m]``: Embrace's SSVs write units so, defining ``m``) is read as the name inside,
        with a warning (once per file and name); UnitError when neither resolves."""
        try:
            return self._resolve(name, units, fmu=fmu)
        except UnitError:
            inner = name[1:-1] if name.startswith("[") and name.endswith("]") else None
            if inner is None:
                raise
            try:
                found = self._resolve(inner, units, fmu=fmu)
            except UnitError:
                raise UnitError(f"unknown unit '{name}' (nor '{inner}' without the brackets)") from None
        note = (f"{label}: the unit '{name}', which no file defines, is read as '{inner}' (the name in "
                "brackets)")
        if note not in self.warnings:
            self.warnings.append(note)
        return found

    def _port_unit(self, ref: PortRef) -> UnitDef | None:
        """The unit of a connected port: its SSD connector's, else its FMU variable's (None: neither)."""
        comp = self.components.get(ref.component)
        var = comp.variables.get(ref.connector) if comp is not None else None
        if comp is None or var is None or ssp_type(comp.model, var) != "Real":
            return None
        declared = next((k.unit for c in self.structure.components if c.name == ref.component
                         for k in c.connectors if k.name == ref.connector), None)
        if declared is not None:
            return self._resolve(declared)
        if _unit_name(var) is None:
            return None
        try:
            return _unit_def(comp.model, var)
        except UnitError as exc:
            if self.strict_fmus or any(u.name == _unit_name(var) for u in comp.model.unitDefinitions):
                raise
            raise _UndefinedUnitError(f"{ref} has the unit {_unit_name(var)}, which its FMU does not "
                                      f"define ({exc})") from exc

    @staticmethod
    def _twice(ps: ParameterSet, problems: list[str]) -> None:
        """A parameter named twice in one set: which value applies would be the file's order."""
        seen: dict[str, object] = {}
        for p in ps.parameters:
            if p.name in seen:
                problems.append(f"{ps.origin}: parameter '{p.name}' is given twice ({seen[p.name]!r} and "
                                f"{p.value!r}); give it once")
            seen.setdefault(p.name, p.value)

    def _apply(self, component: str, ps: ParameterSet, problems: list[str]) -> None:
        self._twice(ps, problems)
        for p in ps.parameters:
            self._set_start(PortRef(component, p.name), p, p.origin or ps.origin, problems, ps.units)

    def _apply_prefixed(self, ps: ParameterSet, problems: list[str]) -> None:
        self._twice(ps, problems)
        for p in ps.parameters:
            try:
                ref = self.port(p.name)
            except ValueError as exc:
                problems.append(f"{ps.origin}: {exc}")
                continue
            self._set_start(ref, Parameter(ref.connector, p.type, p.value, p.unit), ps.origin, problems,
                            ps.units)

    def _override(self, key: str, value: object, problems: list[str]) -> None:
        try:
            ref = self.port(key)
        except ValueError as exc:
            problems.append(f"{option('overrides')}: {exc}")
            return
        comp = self.components.get(ref.component)
        var = comp.variables.get(ref.connector) if comp else None
        type_ = (ssp_type(comp.model, var) if comp is not None and var is not None else None) or "Real"
        unit = None
        if type_ == "Real" and isinstance(value, str):
            value, unit = split_value(value)
        try:
            converted = _convert(type_, value)
        except ValueError:
            problems.append(f"{option('overrides')} {key}: {value!r} is not a valid {type_}")
            return
        self._set_start(ref, Parameter(ref.connector, type_, converted, unit), "--set", problems)

    def _set_start(self, ref: PortRef, p: Parameter, origin: str, problems: list[str],
                   units: Iterable[UnitDef] = ()) -> None:
        label = option("overrides") if origin == "--set" else origin  # the API names the field
        comp = self.components.get(ref.component)
        if comp is None:
            if ref.component not in {c.name for c in self.structure.components}:
                problems.append(f"{label}: no component named '{ref.component}' (for {ref})")
            return
        var = comp.variables.get(ref.connector)
        type_ = ssp_type(comp.model, var) if var is not None else None
        if var is None:
            problems.append(f"{label}: component '{ref.component}' has no variable '{ref.connector}'")
        elif _fmi1_output(comp, var):
            self.warnings.append(f"{label}: {ref} is an output of an FMI 1.0 FMU: the value {p.value!r} "
                                 "given for it is not set, as libcosim, which runs such files, does not set "
                                 "it (FMI 2.0 allows no value for an output)")
        elif var.causality not in SETTABLE or var.variability == "constant":
            problems.append(f"{label}: {ref} is a {var.variability} {var.causality}, it cannot be set")
        elif ref in self.links:
            problems.append(f"{label}: {ref} is an input fed by {self.links[ref].start}: a value given for "
                            "it would be overwritten at once (set a parameter of a component instead)")
        elif type_ is None:
            problems.append(f"{label}: {ref}: {_unsupported(comp.model, var)}")
        elif type_ != p.type and not (type_ == "Real" and p.type == "Integer"):
            problems.append(f"{label}: {ref} is {var.type} but the value given is {p.type}")
        else:
            value = float(p.value) if type_ == "Real" else p.value
            if p.unit is not None and type_ == "Real" and p.unit != _unit_name(var):
                try:
                    given = self._given_unit(p.unit, units, comp.model, label)
                    own = _unit_def(comp.model, var)
                except UnitError as exc:
                    problems.append(f"{label}: {ref} = {p.value!r} {p.unit}: {exc}")
                    return
                if given.exponents != own.exponents:
                    fmu = (f"the FMU's unit {own.name} ({own.dimension()})" if _unit_name(var) else
                           "the FMU's variable, which is dimensionless (give the value without a unit)")
                    problems.append(f"{label}: {ref} = {p.value!r} {p.unit}: a value in {p.unit} "
                                    f"({given.dimension()}) cannot be converted to {fmu}")
                    return
                value = convert(float(value), given, own)  # already a float: a Real
                if p.transform is not None and given.name != own.name:
                    self.warnings.append(
                        f"{label}: {ref} = {p.value!r} {p.unit}: converted to {own.name} before the "
                        f"LinearTransformation (factor {p.transform[0]:g}, offset {p.transform[1]:g}), as "
                        f"SSP 1.0.1 5.3.2 orders it: {value!r} {own.name} -> "
                        f"{p.transform[0] * float(value) + p.transform[1]!r}")
            if p.transform is not None and type_ == "Real":
                value = p.transform[0] * float(value) + p.transform[1]
            outside = _outside(var, value)
            if outside:
                problems.append(f"{label}: {ref} = {value!r} {outside}")
            else:
                comp.start_values[ref.connector] = value
                comp.origins[ref.connector] = origin

    def _check_inputs(self, problems: list[str], partial: Collection[str]) -> None:
        """An input that no connection feeds: an error without a start value; otherwise a warning
        in ``unconnected`` (also in ``warnings``) unless a parameter set or override gave it a value,
        since every pythonfmu input has a start value and a deleted connection would go unnoticed."""
        self.unconnected: list[str] = []
        self.unconnected_ports: list[PortRef] = []  # the input each message of ``unconnected`` names
        for comp in self.components.values():
            if comp.name in partial:
                continue
            for v in comp.model.modelVariables:
                ref = PortRef(comp.name, v.name)
                if v.causality != "input" or ref in self.links or v.name in comp.start_values or \
                        v.type == "Clock":  # an input clock is ticked by the master
                    continue
                where = f"{self.ssd}: component '{comp.name}', input '{v.name}'"
                if v.start is None:
                    problems.append(f"{where} is neither connected nor has a start value")
                else:
                    self.unconnected.append(f"{where} is not connected: it keeps the FMU's start "
                                            f"value {v.start} for the whole run")
                    self.unconnected_ports.append(ref)
        self.warnings.extend(self.unconnected)

    # -- propagation order --------------------------------------------------------------------
    def _feeds(self, comp: ComponentModel, inputs: Iterable[str]) -> bool:
        return any(comp.feedthrough.get(i) for i in inputs)

    def _schedule(self) -> tuple[list[Operation], list[tuple[int, int]]]:
        """Order of 'get outputs' / 'set inputs' at a communication point (one set per component
        when possible, else the inputs that feed no output are set last), and the spans
        ``(first, end)`` of it that form an algebraic loop, to be repeated until they converge."""
        for split in (False, True):
            nodes, before = self._graph(split)
            order = _toposort(nodes, before)
            if order is not None:
                return order, []
        # a loop: its strongly connected parts in dependency order, each part one span
        succ: dict[Operation, list[Operation]] = {n: [] for n in nodes}
        for n, deps in before.items():
            for d in deps & succ.keys():  # a component whose FMU is missing (reported) has no node
                succ[d].append(n)
        labels = _strong_components(nodes, succ)
        order, spans = [], []
        for label in sorted(set(labels.values()), reverse=True):  # Tarjan finishes sinks first
            part = [n for n in nodes if labels[n] == label]
            if len(part) > 1 or part[0] in succ[part[0]]:
                spans.append((len(order), len(order) + len(part)))
            order += part
        return order, spans

    def _graph(self, split: bool) -> tuple[list[Operation], dict[Operation, set[Operation]]]:
        """The operations at a communication point and, for each, those that must come before it."""
        nodes: list[Operation] = []
        for comp in self.components.values():
            connected = [i for i in comp.inputs if PortRef(comp.name, i) in self.links]
            direct = tuple(i for i in connected if comp.feedthrough.get(i))
            late = tuple(i for i in connected if not comp.feedthrough.get(i))
            if split:
                nodes += [Operation("set", comp.name, g) for g in (direct, late) if g]
            elif connected:
                nodes.append(Operation("set", comp.name, direct + late))
            nodes.append(Operation("get", comp.name))
        before: dict[Operation, set[Operation]] = {n: set() for n in nodes}
        for n in nodes:
            if n.kind == "set":
                comp = self.components[n.component]
                for i in n.inputs:
                    before[n].add(Operation("get", self.links[PortRef(n.component, i)].start.component))
                if self._feeds(comp, n.inputs):
                    before[Operation("get", n.component)].add(n)
        return nodes, before

    def port(self, text: str) -> PortRef:
        """``"sub.plant.y"`` -> PortRef("sub.plant", "y"): the longest component name that starts the
        text (component names of nested systems contain dots, so do variable names); ValueError
        when no component does (then ``component.variable`` as :meth:`PortRef.parse` splits it)."""
        for name in sorted(self.components, key=len, reverse=True):
            if text.startswith(name + ".") and len(text) > len(name) + 1:
                return PortRef(name, text[len(name) + 1:])
        names = {c.name for c in self.structure.components}
        for name in sorted(names, key=len, reverse=True):
            if text.startswith(name + ".") and len(text) > len(name) + 1:
                return PortRef(name, text[len(name) + 1:])
        return PortRef.parse(text)

    def _algebraic_loops(self) -> list[str]:
        """Port graph: output -> connected input -> outputs depending on it. Every strongly
        connected part with an edge inside is an algebraic loop, reported as one cycle through it
        from its first port. Components whose FMU is unknown add no edges."""
        succ: dict[PortRef, list[PortRef]] = {}
        for link in self.links.values():
            succ.setdefault(link.start, []).append(link.end)
            comp = self.components.get(link.end.component)
            if comp is not None:
                succ.setdefault(link.end, []).extend(
                    PortRef(comp.name, o) for o in sorted(comp.feedthrough.get(link.end.connector, ())))
        ports = sorted(set(succ) | {q for qs in succ.values() for q in qs})
        labels = _strong_components(ports, succ)
        parts: dict[int, set[PortRef]] = {}
        for p in ports:  # in port order: each part listed from its first port
            parts.setdefault(labels[p], set()).add(p)
        loops = []
        for members in parts.values():
            first = min(members)
            if len(members) > 1 or first in succ.get(first, ()):
                cycle = _cycle(first, {p: [q for q in succ.get(p, ()) if q in members] for p in members})
                loops.append(f"{self.ssd}: algebraic loop: " + " -> ".join(map(str, cycle)))
        return loops


def _toposort(nodes: list[Operation], before: Mapping[Operation, set[Operation]]) -> list[Operation] | None:
    """``nodes`` in an order where each comes after those ``before`` it (the first ready first);
    None when they form a cycle."""
    order: list[Operation] = []
    done: set[Operation] = set()
    while len(order) < len(nodes):
        ready = [n for n in nodes if n not in done and before[n] <= done]
        if not ready:
            return None
        order.append(ready[0])
        done.add(ready[0])
    return order


Node = TypeVar("Node", PortRef, Operation)


def _strong_components(nodes: list[Node], succ: Mapping[Node, list[Node]]) -> dict[Node, int]:
    """Tarjan's strongly connected components, iterative: node -> label (equal labels, one part).
    A few lines here instead of scipy.sparse.csgraph, whose import alone (0.18 s) cost more than a
    whole short run; the graphs are a scenario's ports (tens to thousands)."""
    index: dict[Node, int] = {}
    low: dict[Node, int] = {}
    labels: dict[Node, int] = {}
    stack: list[Node] = []
    parts = 0
    for root in nodes:
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        work = [(root, iter(succ.get(root, ())))]
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:  # node is the root of a part: pop it
                    while True:
                        member = stack.pop()
                        labels[member] = parts
                        if member == node:
                            break
                    parts += 1
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                work.append((child, iter(succ.get(child, ()))))
            elif child not in labels:  # on the stack: same part
                low[node] = min(low[node], index[child])
    return labels


def _cycle(first: PortRef, succ: Mapping[PortRef, list[PortRef]]) -> list[PortRef]:
    """A cycle from ``first`` back to it, inside one strongly connected part (depth first, the
    first successors first)."""
    path, seen = [first], {first}
    stack = [iter(succ[first])]
    while stack:
        q = next(stack[-1], None)
        if q is None:
            stack.pop()
            path.pop()
        elif q == first:
            return [*path, first]
        elif q not in seen:
            seen.add(q)
            path.append(q)
            stack.append(iter(succ[q]))
    raise AssertionError("a strongly connected part has a cycle through each of its ports")


def _exchanged(ssc_type: str | None) -> str | None:
    """An SSD connector type as the engine exchanges it: SSP 2.0's Float64 and Int32 are SSP 1.0's
    Real and Integer (what FMI3_TYPES maps the FMU's variables to)."""
    return FMI3_TYPES.get(ssc_type, ssc_type) if ssc_type in ("Float64", "Int32") else ssc_type


def ssp_type(md: ModelDescription, var: ModelVariable) -> str | None:
    """The SSP 1.0 type a variable is connected and set as (Real, Integer, Boolean, ...; FMI 3.0:
    Float64, Int32 and Boolean as Real, Integer and Boolean); None for a type the engine does not
    support (the other FMI 3.0 types)."""
    if md.fmiVersion.startswith("3."):
        return FMI3_TYPES.get(var.type)
    return var.type


def _unsupported(md: ModelDescription, var: ModelVariable) -> str:
    return (f"the FMU's variable is {var.type}, an FMI {md.fmiVersion} type orchestrate does not support "
            f"yet (supported: {', '.join(f'{t} as {s}' for t, s in FMI3_TYPES.items())})")


def _unit_name(var: ModelVariable) -> str | None:
    """The unit a Real variable declares, directly or through its type (None: dimensionless)."""
    return var.unit or (var.declaredType.unit if var.declaredType is not None else None)


def _unit_def(md: ModelDescription, var: ModelVariable) -> UnitDef:
    """The unit of an FMU variable: its UnitDefinitions entry (base units, factor, offset), else the
    known unit of that name; dimensionless when it declares none. UnitError when unknown."""
    name = _unit_name(var)
    unit = next((u for u in md.unitDefinitions if u.name == name), None) if name else None
    if unit is None or unit.baseUnit is None:
        return resolve(name)
    return _definition(unit)


def _definition(unit: Unit) -> UnitDef:
    """An FMU's ``<Unit>`` with a ``<BaseUnit>`` as a UnitDef."""
    base = unit.baseUnit
    return UnitDef(unit.name, tuple(int(getattr(base, b)) for b in BASE), float(base.factor),
                   float(base.offset))


class _UndefinedUnitError(Exception):
    """A unit an FMU's variable uses without defining it (and orchestrate does not know)."""


INT32 = (-(2**31), 2**31 - 1)  # what fmi2SetInteger passes (the value would wrap around)


def _outside(var: ModelVariable, value: float | int | bool | str) -> str:
    """Why ``value`` does not fit the variable's declared range or enumeration items ('' if it does)."""
    declared = var.declaredType
    if var.type == "Enumeration" and declared is not None and declared.items:
        items = {int(i.value): i.name for i in declared.items}
        if value not in items:
            return f"is not an item of {declared.name} ({', '.join(f'{k}={n}' for k, n in items.items())})"
        return ""
    if var.type not in ("Real", "Integer", "Enumeration", *FMI3_TYPES) or var.type == "Boolean":
        return ""
    if var.type in ("Integer", "Enumeration", "Int32") and not INT32[0] <= int(value) <= INT32[1]:
        return f"is outside the range of an FMI Integer ({INT32[0]} .. {INT32[1]})"
    number = float(value)  # a Real, Integer or Enumeration value (FMI 3.0: Float64, Int32)
    low = var.min if var.min is not None else getattr(declared, "min", None)
    high = var.max if var.max is not None else getattr(declared, "max", None)
    if low is not None and not number >= float(low):  # written so that NaN is outside
        return f"is below the FMU's min {low}"
    if high is not None and not number <= float(high):
        return f"is above the FMU's max {high}"
    return ""


NUMBERS = ("Real", "Integer", "Enumeration", "Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16",
           "Int32", "UInt32", "Int64", "UInt64")


def _start_ok(var: ModelVariable) -> bool:
    """False for a scalar variable whose start attribute is no value of its type (``start=""``,
    which validate passed and the run died on)."""
    start = var.start
    if start is None or getattr(var, "dimensions", None) or not isinstance(start, str):
        return True
    if var.type in NUMBERS:
        try:
            float(start)
        except ValueError:
            return False
    elif var.type == "Boolean":
        return start.strip() in ("true", "false", "1", "0")
    return True


# A name FMI's "structured" grammar accepts without quotes: identifiers, array indices, dots, der(...).
_PLAIN = r"[A-Za-z_][A-Za-z0-9_]*(?:\[[0-9]+(?:,[0-9]+)*\])?"
_PLAIN_NAME = re.compile(rf"(?:{_PLAIN}(?:\.{_PLAIN})*|der\({_PLAIN}(?:\.{_PLAIN})*(?:,[0-9]+)?\))")


def fmu_findings(fmu: Path, md: ModelDescription) -> list[str]:
    """What fmpy's ``validate_fmu`` finds in an FMU (backslashes in member names, the schema,
    variable names, ModelStructure, start values, units), in time linear in its variables:
    fmpy parses every "structured" name with an Earley parser (27 ms a name, minutes for an FMU
    with 10^5 variables); here a name the grammar's unquoted form accepts (``a.b[2]``,
    ``der(x)``, matched by a regular expression written from that grammar) is accepted at once and
    only the others go to fmpy's parser, so its verdict stands for each name."""
    problems: list[str] = []
    with zipfile.ZipFile(fmu) as zf:
        problems += [f'The file path "{i.orig_filename}" contains a backslash.' for i in zf.filelist
                     if "\\" in i.orig_filename]
    try:  # the schema and fmpy's other checks, names left to the loop below
        read_model_description(str(fmu), validate=True, validate_model_structure=True)
    except ValidationError as exc:
        problems += exc.problems
    except Exception as exc:  # noqa: BLE001 - fmpy's validate_fmu reports any failure so
        problems.append(str(exc))
    if md.variableNamingConvention == "structured":
        other = [v for v in md.modelVariables if not _PLAIN_NAME.fullmatch(v.name)]
        if other:
            problems += validation._validate_variable_names(  # noqa: SLF001 - fmpy's own verdict
                _with_variables(md, other))
    else:
        problems += validation._validate_variable_names(md)  # noqa: SLF001 - flat: linear already
    return problems


def _with_variables(md: ModelDescription, variables: list[ModelVariable]) -> ModelDescription:
    """A shallow copy of ``md`` with only ``variables``."""
    shallow = copy.copy(md)
    shallow.modelVariables = variables
    return shallow


def _fmi1_output(comp: ComponentModel, var: ModelVariable) -> bool:
    """An output of an FMI 1.0 FMU, which files written for libcosim (Vico's, OSP's) give values:
    libcosim runs them and leaves the value unset (the OSP demo dp-ship with DP Controller.Controlx
    bound to 7 gives libcosim's outputs, 0, bit for bit only when it is skipped), so orchestrate
    skips it with a warning where an FMI 2.0 output is an error."""
    return comp.model.fmiVersion.startswith("1.") and var.causality == "output"


def _is_input_start(problem: str, inputs: Collection[str]) -> bool:
    """Whether fmpy's ``problem`` is an input without a start value (one of ``inputs``, a set: the
    check runs once per problem, and an FMU may declare 10^5 variables)."""
    return problem.endswith("has no start value.") and problem.split('"')[1] in inputs


def structure_sets(structure: SystemStructure) -> list[tuple[str, ParameterSet]]:
    """The SSD's own parameter sets as (component, set), in binding order."""
    return [(c.name, ps) for c in structure.components for ps in c.parameter_sets]


def _convert(type_: str, value: object) -> float | int | bool | str:
    if type_ == "Real":
        if not isinstance(value, str | SupportsFloat | SupportsIndex):
            raise TypeError(f"{value!r} is not a number")
        return float(value)
    if type_ in ("Integer", "Enumeration"):
        if not isinstance(value, str | SupportsInt | SupportsIndex):
            raise TypeError(f"{value!r} is not a number")
        if isinstance(value, str):
            return int(value)
        if isinstance(value, float) and not value.is_integer():
            raise ValueError(value)
        return int(value)
    if type_ == "Boolean":
        if isinstance(value, str):
            if value.lower() not in ("true", "false", "1", "0"):
                raise ValueError(value)
            return value.lower() in ("true", "1")
        return bool(value)
    return str(value)


def _no_binary(fmu: Path, md: ModelDescription) -> str:
    """Why the FMU cannot be loaded on this platform ('' when it can): no shared library of its
    model identifier for this platform, naming the platforms it has."""
    assert md.coSimulation is not None
    identifier = md.coSimulation.modelIdentifier
    folders = ((fmpy.platform_tuple,) if md.fmiVersion.startswith("3.") else
               (fmpy.platform, fmpy.platform_tuple))
    wanted = {f"binaries/{folder}/{identifier}{fmpy.sharedLibraryExtension}" for folder in folders}
    entry = fmucache.entry_of(fmu)
    try:
        if entry is not None:  # unpacked in the cache (an archive's FMU left unextracted)
            names = [p.relative_to(entry).as_posix() for p in entry.glob("binaries/*/*")]
        else:
            with zipfile.ZipFile(fmu) as zf:
                names = zf.namelist()
    except (OSError, zipfile.BadZipFile):
        return ""  # an extracted or broken FMU: the instantiation reports it
    if wanted & set(names):
        return ""
    platforms = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2
                        and not n.endswith("/")})
    has = f"it has binaries for {', '.join(platforms)}" if platforms else "it has no binaries at all"
    return (f"no binary for this platform ({fmpy.platform}: {sorted(wanted)[0]}); {has}"
            + ("; it has C sources, which orchestrate does not compile" if
               any(n.startswith("sources/") for n in names) else ""))


def _dependencies(fmu: Path, md: ModelDescription, inputs: set[str]) -> dict[str, set[str]]:
    """Each output -> the inputs it depends on directly: the ModelStructure (FMI 2.0, 3.0; every
    input when it lists none), or FMI 1.0's DirectDependency of each output (which fmpy does not
    read; every input when the output has none, as FMI 1.0 says)."""
    if not md.fmiVersion.startswith("1."):
        return {u.variable.name: inputs if u.dependencies is None else {d.name for d in u.dependencies}
                for u in md.outputs}
    try:
        with zipfile.ZipFile(fmucache.materialize(fmu)) as zf, zf.open("modelDescription.xml") as xml:
            root = etree.parse(xml, etree.XMLParser(resolve_entities=False, no_network=True)).getroot()
    except (OSError, KeyError, zipfile.BadZipFile, etree.XMLSyntaxError):
        return {v.name: inputs for v in md.modelVariables if v.causality == "output"}
    found: dict[str, set[str]] = {}
    for variable in root.iter("ScalarVariable"):
        if variable.get("causality") == "output":
            direct = variable.find("DirectDependency")
            found[variable.get("name", "")] = (inputs if direct is None else
                                               {n.text.strip() for n in direct.iter("Name") if n.text})
    return found
