# SPDX-License-Identifier: BSD-2-Clause
"""What a scenario holds, as ``fmpy info`` and ``cosim inspect`` show it (``orchestrate inspect``).

Components (FMU file, FMI version, model, generation tool), every input, output and parameter with
type, unit, range, the FMU's start value, the value a run would apply and where it comes from (the
FMU, a parameter set of the SSD, a ``--parameter-set`` file, ``--set``), the connections with
their transformations (unit conversions composed, as a run applies them), and the start, stop
time, step and master with where each comes from. Reading goes
as far as it can: what cannot be read is listed as a problem under the rest.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field, replace

from .ssp import DEFAULT_LIMITS, Limits, SystemStructure
from .system import ComponentModel, structure_sets
from .validate import DEFAULT_STEP, check_scenario, choose_master

__all__ = ["Inspection", "Variable", "inspect_scenario"]


@dataclass(frozen=True)
class Variable:
    """One variable of a component as a run would see it."""

    name: str
    causality: str
    type: str
    unit: str | None
    min: str | None
    max: str | None
    start: str | None  # the FMU's own start value
    value: object  # what a run applies (None: the FMU's start)
    origin: str  # FMU, or the file / --set that gave ``value``
    description: str | None = None
    connection: str = ""  # ``<- plant.y`` for a connected input, ``-> ...`` for an output


@dataclass
class Inspection:
    """Everything ``orchestrate inspect`` prints; ``problems``: what could not be read or checked."""

    scenario: str
    name: str = ""
    timing: list[tuple[str, str, str]] = field(default_factory=list)  # (what, value, where from)
    components: list[tuple[str, list[str], list[Variable]]] = field(default_factory=list)
    connections: list[str] = field(default_factory=list)
    connector_values: list[str] = field(default_factory=list)  # ``sub.x = 3.0 (from file)``
    problems: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        """The text ``orchestrate inspect`` prints."""
        out = [f"scenario: {self.scenario}" + (f" (system '{self.name}')" if self.name else "")]
        out += [f"  {what:<6} {value:<12} {origin}" for what, value, origin in self.timing]
        for name, about, variables in self.components:
            out.append(f"component {name}: " + ", ".join(about))
            rows = [("variable", "causality", "type", "unit", "range", "FMU start", "value", "from")]
            for v in variables:
                rng = "" if v.min is None and v.max is None else f"[{v.min or ''}, {v.max or ''}]"
                rows.append((v.name, v.causality, v.type, v.unit or "-", rng, v.start or "", *_value(v)))
            widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
            out += ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
                    for r in rows]
        if self.connector_values:
            out.append(f"system connectors given a value ({len(self.connector_values)}):")
            out += [f"  {v}" for v in self.connector_values]
        out.append(f"connections ({len(self.connections)}):")
        out += [f"  {c}" for c in self.connections]
        if self.problems:
            out.append(f"problems ({len(self.problems)}):")
            out += [f"  {p}" for p in self.problems]
        return out


def inspect_scenario(scenario: str | os.PathLike, *, parameter_sets: Iterable[str | os.PathLike] = (),
                     overrides: Mapping[str, object] | None = None,
                     fmu_dirs: Iterable[str | os.PathLike] = (),
                     limits: Limits = DEFAULT_LIMITS, root: str | os.PathLike | None = None,
                     strict_fmus: bool = False) -> Inspection:
    """Read ``scenario`` (``.ssp`` archive or folder) with the parameter sets and overrides a run
    would get, and describe it (:class:`Inspection`). Nothing is instantiated or written.

    Parameters
    ----------
    scenario : path
        ``.ssp`` archive or folder holding ``SystemStructure.ssd``.
    parameter_sets, overrides, fmu_dirs, limits, root, strict_fmus
        As for :class:`orchestrator.RunOptions`.
    """
    report = Inspection(str(scenario))
    with ExitStack() as stack:
        system, errors, _ = check_scenario(scenario, stack, parameter_sets=parameter_sets,
                                           overrides=overrides, fmu_dirs=fmu_dirs, limits=limits, root=root,
                                           strict_fmus=strict_fmus)
    report.problems = list(errors)
    if system is None:
        return report
    structure = system.structure
    report.name = structure.name
    report.timing = _timing(structure)
    sources = {str(end): str(link.start) + _transformation(link.factor, link.offset)
               for end, link in system.links.items()}
    targets: dict[str, list[str]] = {}
    for end, link in system.links.items():
        targets.setdefault(str(link.start), []).append(str(end))
    in_ssd = {p.origin or ps.origin for _, ps in structure_sets(structure) for p in ps.parameters}
    for c in structure.components:
        comp = system.components.get(c.name)
        if comp is None:
            report.components.append((c.name, [f"FMU {c.source.name} (not readable)"], []))
            continue
        variables = [replace(v, origin=_origin(v.origin, in_ssd)) for v in _variables(comp, sources, targets)]
        report.components.append((c.name, _about(comp), variables))
    report.connector_values = [f"{name} = {p.value!r} (from {p.origin})"
                               for name, p in structure.connector_values]
    applied = [system.links.get(link.end, link) if system.links.get(link.end, link).start == link.start
               else link for link in structure.connections]  # with the unit conversion a run composes
    report.connections = [f"{link.start} -> {link.end}{_transformation(link.factor, link.offset)}"
                          for link in applied]
    return report


def _origin(origin: str, in_ssd: set[str]) -> str:
    """Where a value comes from, named for a reader: ``SSD (x.ssv)``, ``--parameter-set x.ssv``,
    ``--set`` or ``FMU``."""
    if origin in ("FMU", "--set"):
        return origin
    return f"SSD ({origin})" if origin in in_ssd else f"--parameter-set {origin}"


def _value(v: Variable) -> tuple[str, str]:
    """The value a run gives ``v`` and where it comes from."""
    if v.value is not None:
        return repr(v.value), v.origin
    if v.connection.startswith("<-"):
        return v.connection, "connection"
    if v.causality == "output":
        return v.connection, ""
    return (v.start, "FMU") if v.start is not None else ("", "")


def _timing(structure: SystemStructure) -> list[tuple[str, str, str]]:
    ex = structure.experiment
    where = f"{structure.ssd_file} DefaultExperiment"
    stop = ("none", "none in the SSD: 'run' needs --stop-time") if ex.stop_time is None else (
        f"{ex.stop_time:g} s", where)
    step = ((f"{ex.step:g} s", f"{structure.ssd_file} step annotation (libcosim OSP FixedStepAlgorithm "
                               "or OMSimulator FixedStepMaster)") if ex.step is not None else
            (f"{DEFAULT_STEP:g} s", "default: no step annotation in the SSD (give --step; 'run' warns)"))
    return [("start", f"{ex.start_time:g} s", f"{where} (0 when it gives none)"), ("stop", *stop),
            ("step", *step), ("master", *choose_master(structure))]


def _about(comp: ComponentModel) -> list[str]:
    md = comp.model
    return [f"FMU {comp.fmu.name}", f"FMI {md.fmiVersion}", f"model {md.modelName}",
            f"generated by {md.generationTool or 'an unnamed tool'}",
            f"SSD connectors: {len(comp.inputs)} Real inputs, {len(comp.outputs)} Real outputs"]


def _variables(comp: ComponentModel, sources: Mapping[str, str],
               targets: Mapping[str, list[str]]) -> list[Variable]:
    """Inputs, outputs and parameters of ``comp`` in the FMU's order."""
    found = []
    for v in comp.model.modelVariables:
        if v.causality not in ("input", "output", "parameter"):
            continue
        port = f"{comp.name}.{v.name}"
        declared = getattr(v, "declaredType", None)
        unit = v.unit or (declared.unit if declared is not None else None)
        value = comp.start_values.get(v.name)
        connection = (f"<- {sources[port]}" if port in sources else
                      f"-> {', '.join(targets[port])}" if port in targets else "")
        found.append(Variable(v.name, v.causality, v.type, unit, _text(v.min), _text(v.max), _text(v.start),
                              value, comp.origins.get(v.name, "FMU"), v.description, connection))
    return found


def _text(value: object) -> str | None:
    return None if value is None else str(value)


def _transformation(factor: float, offset: float) -> str:
    if factor == 1.0 and offset == 0.0:
        return ""
    return f" (x {factor:g} + {offset:g})"

