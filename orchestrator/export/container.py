"""``orchestrate export``: a scenario as one FMI 2.0 Co-Simulation FMU.

The archive holds ``modelDescription.xml`` (the exposed variables ``<component>.<variable>``, the
scenario's DefaultExperiment and step), ``binaries/linux64/<id>.so`` (the container runtime of
``fmu_src/container``), ``resources/container.plan`` (:mod:`.plan`) and each distinct FMU of the
scenario unpacked under ``resources/fmus/<name>/``. Rebuilding from the same scenario and options
gives the same bytes; the GUID is a digest of them.
"""

from __future__ import annotations

import hashlib
import os
import re
import uuid
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path, PurePosixPath
from xml.etree import ElementTree

from fmu_src.build import BuildError
from fmu_src.container import compile_container

from .. import open_system
from ..errors import ScenarioError, UsageError
from ..files import replacing
from ..master import MASTERS
from ..ssp import DEFAULT_LIMITS, Limits
from ..system import ComponentModel, System
from ..validate import timing
from .plan import Exposed, Plan, make_plan, select

__all__ = ["FMI_VERSIONS", "export"]

FMI_VERSIONS = ("2", "3")
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
GUID_NAMESPACE = uuid.UUID("0d6c7e0e-8a55-4f0b-9d7e-3c1f0a6b2e41")
GENERATOR = "orchestrate export (fixed-time-cosim)"


def model_identifier(output: Path) -> str:
    """A C identifier from the FMU's file name (``example1.fmu`` -> ``example1``)."""
    name = re.sub(r"\W", "_", output.stem, flags=re.ASCII) or "scenario"
    return name if not name[0].isdigit() else f"_{name}"


def _folders(system: System) -> dict[str, str]:
    """component -> folder under resources/fmus/: one per distinct FMU file, named after it."""
    by_digest: dict[str, str] = {}
    folders: dict[str, str] = {}
    for comp in system.components.values():
        digest = hashlib.sha256(Path(comp.fmu).read_bytes()).hexdigest()
        if digest not in by_digest:
            stem = re.sub(r"[^\w.-]", "_", Path(comp.fmu).stem, flags=re.ASCII) or "fmu"
            name, n = stem, 1
            while name in by_digest.values():
                n += 1
                name = f"{stem}_{n}"
            by_digest[digest] = name
        folders[comp.name] = by_digest[digest]
    return folders


def _members(comp: ComponentModel, folder: str) -> dict[str, bytes]:
    """The FMU's files under ``resources/fmus/<folder>/`` (names checked to stay inside it)."""
    members: dict[str, bytes] = {}
    with zipfile.ZipFile(comp.fmu) as archive:
        for info in archive.infolist():
            name = info.filename
            parts = PurePosixPath(name).parts
            if info.is_dir():
                continue
            if name.startswith("/") or "\\" in name or ".." in parts or not parts:
                raise ScenarioError(f"{comp.fmu}: member '{name}' would leave the FMU's folder")
            members[f"resources/fmus/{folder}/{name}"] = archive.read(info)
    return members


def _variable(parent: ElementTree.Element, name: str, vr: int, causality: str, variability: str,
              description: str | None, initial: str | None) -> ElementTree.Element:
    attributes = {"name": name, "valueReference": str(vr)}
    if description:
        attributes["description"] = description
    attributes |= {"causality": causality, "variability": variability}
    if initial:
        attributes["initial"] = initial
    return ElementTree.SubElement(parent, "ScalarVariable", attributes)


def _start(type_: str, value: object) -> str:
    if type_ == "Real":
        return repr(float(value))  # type: ignore[arg-type]  # a Real start value is a number
    if type_ == "Boolean":
        return "true" if value else "false"
    return str(int(value))  # type: ignore[call-overload]  # an Integer start value is a number


def model_description(system: System, plan: Plan, identifier: str, guid: str, start: float, stop: float,
                      step: float, master: str) -> bytes:
    """The container's modelDescription.xml (FMI 2.0 Co-Simulation)."""
    description = (f"SSP scenario '{system.structure.name}' as one FMU ({len(system.components)} FMUs, "
                   f"master {master}, step {step:g} s), exported by orchestrate")
    root = ElementTree.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": system.structure.name, "guid": guid, "description": description,
        "generationTool": GENERATOR, "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    ElementTree.SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "needsExecutionTool": "false",
        "canHandleVariableCommunicationStepSize": "true", "canInterpolateInputs": "false",
        "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "false", "canSerializeFMUstate": "false",
        "providesDirectionalDerivative": "false"})
    units: dict[str, ElementTree.Element] = {}
    for e in plan.exposed:
        var = system.components[e.port.component].variables[e.port.connector]
        unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
        if unit and unit not in units:
            md = system.components[e.port.component].model
            definition = next((u for u in md.unitDefinitions if u.name == unit), None)
            element = ElementTree.Element("Unit", {"name": unit})
            if definition is not None and definition.baseUnit is not None:
                base = definition.baseUnit
                attributes = {k: str(getattr(base, k)) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
                              if getattr(base, k)}
                if float(base.factor) != 1.0:
                    attributes["factor"] = repr(float(base.factor))
                if float(base.offset) != 0.0:
                    attributes["offset"] = repr(float(base.offset))
                ElementTree.SubElement(element, "BaseUnit", attributes)
            units[unit] = element
    if units:
        ElementTree.SubElement(root, "UnitDefinitions").extend(units.values())
    ElementTree.SubElement(root, "DefaultExperiment", {
        "startTime": repr(start), "stopTime": repr(stop), "stepSize": repr(step)})
    variables = ElementTree.SubElement(root, "ModelVariables")
    for vr, e in enumerate(plan.exposed):
        var = system.components[e.port.component].variables[e.port.connector]
        unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
        if e.kind == "output":
            node = _variable(variables, str(e.port), vr, "output", "continuous", var.description,
                             "calculated")
            typed = ElementTree.SubElement(node, "Real")
        elif e.kind == "input":
            node = _variable(variables, str(e.port), vr, "input", "continuous", var.description, None)
            typed = ElementTree.SubElement(node, "Real", {"start": _start("Real", e.start)})
        else:
            node = _variable(variables, str(e.port), vr, "parameter", "fixed", var.description, "exact")
            typed = ElementTree.SubElement(node, e.type, {"start": _start(e.type, e.start)})
            for bound in ("min", "max"):
                if getattr(var, bound) is not None and e.type != "Boolean":
                    typed.set(bound, str(getattr(var, bound)))
        if unit and e.type == "Real":
            typed.set("unit", unit)
    structure = ElementTree.SubElement(root, "ModelStructure")
    index = {str(e.port): n for n, e in enumerate(plan.exposed, start=1)}
    outputs = [(n, e) for n, e in enumerate(plan.exposed, start=1) if e.kind == "output"]
    if outputs:
        section = ElementTree.SubElement(structure, "Outputs")
        for n, e in outputs:
            depends = " ".join(str(index[d]) for d in sorted(e.depends_on, key=index.__getitem__))
            ElementTree.SubElement(section, "Unknown", {"index": str(n), "dependencies": depends})
        section = ElementTree.SubElement(structure, "InitialUnknowns")
        for n, _ in outputs:
            ElementTree.SubElement(section, "Unknown", {"index": str(n)})
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _write(target: Path, entries: Mapping[str, bytes]) -> None:
    """The archive, written under a temporary name and renamed (the target is never half written)."""
    with replacing(target) as temporary, zipfile.ZipFile(temporary, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if name.endswith(".so") else 0o644) << 16
            archive.writestr(info, entries[name])


def export(scenario: str | os.PathLike, output: str | os.PathLike, *, fmi: str = "2",
           master: str = "gauss-seidel", expose: Sequence[str] = (),
           parameter_sets: Iterable[str | os.PathLike] = (), overrides: Mapping[str, object] | None = None,
           fmu_dirs: Iterable[str | os.PathLike] = (), limits: Limits = DEFAULT_LIMITS,
           start_time: float | None = None, stop_time: float | None = None,
           step: float | None = None) -> tuple[Path, list[Exposed]]:
    """Export ``scenario`` (as :func:`orchestrator.run` takes it, with the same parameter sets,
    overrides, start and stop time and step) as one FMU at ``output``; returns its path and the
    variables it exposes. The start and stop time become the FMU's DefaultExperiment, the step its
    internal communication step (and DefaultExperiment stepSize).

    ScenarioError for a scenario ``run`` would refuse, UsageError for a bad option (an FMI
    version or master that does not exist, ``--fmi 3``, an ``--expose`` pattern that matches
    nothing)."""
    if fmi not in FMI_VERSIONS:
        raise UsageError(f"--fmi must be one of {', '.join(FMI_VERSIONS)} (got {fmi!r})")
    if fmi == "3":
        raise UsageError("--fmi 3: FMI 3.0 export is not available yet (the container runtime and the "
                         "project's FMUs are FMI 2.0); export with --fmi 2")
    if master not in MASTERS:
        raise UsageError(f"unknown master '{master}' (choose from {', '.join(MASTERS)})")
    target = Path(output)
    if target.suffix.lower() != ".fmu":
        raise UsageError(f"the exported file must end in .fmu (got {target})")
    identifier = model_identifier(target)
    with open_system(scenario, parameter_sets=list(parameter_sets), overrides=overrides, fmu_dirs=fmu_dirs,
                     limits=limits) as system:
        start, stop, step = timing(system.structure, stop_time, step, start_time)
        exposed = select(system, expose)
        folders = _folders(system)
        plan = make_plan(system, start, step, master, exposed, folders)
        entries: dict[str, bytes] = {}
        for comp in system.components.values():
            entries |= _members(comp, folders[comp.name])
        try:
            entries[f"binaries/linux64/{identifier}.so"] = compile_container()
        except BuildError as exc:
            raise ScenarioError(f"cannot build the container runtime: {exc}") from exc
        digest = hashlib.sha256(plan.text("").encode())
        for name in sorted(entries):
            digest.update(name.encode() + b"\0" + hashlib.sha256(entries[name]).digest())
        digest.update(f"{identifier}\0{start!r}\0{stop!r}\0{step!r}".encode())
        guid = "{" + str(uuid.uuid5(GUID_NAMESPACE, digest.hexdigest())) + "}"
        entries["resources/container.plan"] = plan.text(guid).encode()
        entries["modelDescription.xml"] = model_description(system, plan, identifier, guid, start, stop, step,
                                                            master)
    _write(target, entries)
    return target, plan.exposed
