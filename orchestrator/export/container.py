# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate export``: a scenario as one FMI 2.0 (or 3.0) Co-Simulation FMU.

The archive holds ``modelDescription.xml`` (the exposed variables ``<component>.<variable>``, the
scenario's DefaultExperiment and step), ``binaries/linux64/<id>.so`` and ``binaries/win64/<id>.dll``
(FMI 3.0: ``x86_64-linux``, ``x86_64-windows``; the container runtime, ``orchestrator/native/container.c``
on the engine's C core, the DLL cross-compiled with mingw-w64), ``resources/container.plan`` (the
engine's plan, :mod:`.plan`) and each distinct FMU of the scenario (FMI 2.0 or 3.0 Co-Simulation)
unpacked under ``resources/fmus/<name>/``. Rebuilding from the same scenario and options
gives the same bytes; the GUID is a digest of them.
"""

from __future__ import annotations

import hashlib
import io
import os
import re
import uuid
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path, PurePosixPath
from xml.etree import ElementTree

from fmpy.model_description import ModelVariable

from fmu_src.toolchain.licences import CONTAINER_DEPENDENCIES, documentation, generation_tool

from .. import open_system
from ..errors import ScenarioError, UsageError
from ..files import replacing
from ..fmucache import materialize
from ..master import MASTERS
from ..native import NativeError, container_library
from ..plan import Plan
from ..ssp import DEFAULT_LIMITS, Limits
from ..system import ComponentModel, System
from ..validate import timing
from .plan import Exposed, container_plan, select

__all__ = ["FMI_VERSIONS", "export", "shared_runtimes"]

FMI_VERSIONS = ("2", "3")
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
GUID_NAMESPACE = uuid.UUID("0d6c7e0e-8a55-4f0b-9d7e-3c1f0a6b2e41")
SHARED_RUNTIME = "_runtime"  # resources/fmus/_runtime/<platform>/python: the FMUs' one runtime (loader.c)
RUNTIME_TAG = "311"  # python311.zip
GENERATOR = generation_tool("orchestrate export")


def model_identifier(output: Path) -> str:
    """A C identifier from the FMU's file name (``example1.fmu`` -> ``example1``)."""
    name = re.sub(r"\W", "_", output.stem, flags=re.ASCII) or "scenario"
    return name if not name[0].isdigit() else f"_{name}"


def _folders(system: System) -> dict[str, str]:
    """component -> folder under resources/fmus/: one per distinct FMU file, named after it."""
    by_digest: dict[str, str] = {}
    folders: dict[str, str] = {}
    for comp in system.components.values():
        digest = hashlib.sha256(materialize(comp.fmu).read_bytes()).hexdigest()
        if digest not in by_digest:
            stem = re.sub(r"[^\w.-]", "_", Path(comp.fmu).stem, flags=re.ASCII) or "fmu"
            name, n = stem, 1
            while name in by_digest.values() or name == SHARED_RUNTIME:
                n += 1
                name = f"{stem}_{n}"
            by_digest[digest] = name
        folders[comp.name] = by_digest[digest]
    return folders


def _members(comp: ComponentModel, folder: str) -> dict[str, bytes]:
    """The FMU's files under ``resources/fmus/<folder>/`` (names checked to stay inside it)."""
    members: dict[str, bytes] = {}
    with zipfile.ZipFile(materialize(comp.fmu)) as archive:
        for info in archive.infolist():
            name = info.filename
            parts = PurePosixPath(name).parts
            if info.is_dir():
                continue
            if name.startswith("/") or "\\" in name or ".." in parts or not parts:
                raise ScenarioError(f"{comp.fmu}: member '{name}' would leave the FMU's folder")
            members[f"resources/fmus/{folder}/{name}"] = archive.read(info)
    return members


def shared_runtimes(entries: Mapping[str, bytes]) -> dict[str, bytes]:
    """``entries`` with the Python runtimes the FMUs carry
    (``resources/fmus/<name>/binaries/<platform>/python/``, fmu_src/toolchain/runtime.py) moved
    into one per platform folder, ``resources/fmus/_runtime/<platform>/python/``, where the FMUs'
    shims look when they have none (fmu_src/toolchain/shim/loader.c): the interpreter and its
    libraries once, the standard-library zip the union of theirs, ``runtime.txt`` each FMU's
    manifest under its name. A file of the same name but other bytes in two FMUs (runtimes of two
    builds) is a ScenarioError."""
    moved: dict[str, dict[str, bytes]] = {}  # shared member -> folder -> bytes
    kept: dict[str, bytes] = {}
    for name, data in entries.items():
        parts = name.split("/")
        inner = parts[:2] == ["resources", "fmus"] and parts[3:4] == ["binaries"] and parts[5:6] == ["python"]
        if inner and len(parts) > 6:
            shared = "/".join(["resources", "fmus", SHARED_RUNTIME, parts[4], *parts[5:]])
            moved.setdefault(shared, {})[parts[2]] = data
        else:
            kept[name] = data
    for name, copies in sorted(moved.items()):
        if name.endswith(f"/python/python{RUNTIME_TAG}.zip"):
            kept[name] = _union(name, copies)
        elif name.endswith("/python/runtime.txt"):
            kept[name] = b"".join(f"## resources/fmus/{folder}\n".encode() + copies[folder]
                                  for folder in sorted(copies))
        elif len(set(copies.values())) > 1:
            file = name.split("/python/")[1]
            raise ScenarioError(f"the FMUs {', '.join(sorted(copies))} carry different {file}: runtimes of "
                                "different builds cannot share one folder; rebuild them")
        else:
            kept[name] = next(iter(copies.values()))
    return kept


def _union(name: str, copies: Mapping[str, bytes]) -> bytes:
    """One zip of every member of the zips ``copies`` (folder -> bytes), each member's bytes the same
    in all."""
    members: dict[str, bytes] = {}
    for folder, zipped in sorted(copies.items()):
        with zipfile.ZipFile(io.BytesIO(zipped)) as archive:
            for member in archive.namelist():
                data = archive.read(member)
                if members.setdefault(member, data) != data:
                    raise ScenarioError(f"{name}: {member} differs between the FMUs' runtimes ({folder}'s)")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for member in sorted(members):
            info = zipfile.ZipInfo(member, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, members[member])
    return buffer.getvalue()


def _start(type_: str, value: object) -> str:
    if type_ == "Real":
        return repr(float(value))  # type: ignore[arg-type]  # a Real start value is a number
    if type_ == "Boolean":
        return "true" if value else "false"
    return str(int(value))  # type: ignore[call-overload]  # an Integer start value is a number


def _unit(var: ModelVariable) -> str | None:
    return var.unit or (var.declaredType.unit if var.declaredType is not None else None)


def _unit_definitions(system: System, exposed: Sequence[Exposed]) -> ElementTree.Element | None:
    """UnitDefinitions of the exposed variables' units, copied from their FMUs (None: no unit)."""
    units: dict[str, ElementTree.Element] = {}
    for e in exposed:
        comp = system.components[e.port.component]
        unit = _unit(comp.variables[e.port.connector])
        if not unit or unit in units:
            continue
        definition = next((u for u in comp.model.unitDefinitions if u.name == unit), None)
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
    if not units:
        return None
    definitions = ElementTree.Element("UnitDefinitions")
    definitions.extend(units.values())
    return definitions


# FMI 2.0 type element -> FMI 3.0 variable element
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


def model_description(system: System, exposed: Sequence[Exposed], identifier: str, guid: str, start: float,
                      stop: float, step: float, master: str, fmi: str = "2") -> bytes:
    """The container's modelDescription.xml: FMI 2.0 Co-Simulation, or FMI 3.0 (``fmi`` "3", where
    value references, not indices, name dependencies and time is the independent variable)."""
    three = fmi == "3"
    description = (f"SSP scenario '{system.structure.name}' as one FMU ({len(system.components)} FMUs, "
                   f"master {master}, step {step:g} s), exported by orchestrate")
    root = ElementTree.Element("fmiModelDescription", {
        "fmiVersion": "3.0" if three else "2.0", "modelName": system.structure.name,
        "instantiationToken" if three else "guid": guid, "description": description,
        "generationTool": GENERATOR, "variableNamingConvention": "flat"})
    if three:
        ElementTree.SubElement(root, "CoSimulation", {
            "modelIdentifier": identifier, "needsExecutionTool": "false",
            "canHandleVariableCommunicationStepSize": "true", "canGetAndSetFMUState": "false",
            "canSerializeFMUState": "false", "hasEventMode": "false"})
    else:
        root.set("numberOfEventIndicators", "0")
        ElementTree.SubElement(root, "CoSimulation", {
            "modelIdentifier": identifier, "needsExecutionTool": "false",
            "canHandleVariableCommunicationStepSize": "true", "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "true",
            "canGetAndSetFMUstate": "false", "canSerializeFMUstate": "false",
            "providesDirectionalDerivative": "false"})
    units = _unit_definitions(system, exposed)
    if units is not None:
        root.append(units)
    ElementTree.SubElement(root, "DefaultExperiment", {
        "startTime": repr(start), "stopTime": repr(stop), "stepSize": repr(step)})
    _variables(ElementTree.SubElement(root, "ModelVariables"), system, exposed, three)
    _structure(ElementTree.SubElement(root, "ModelStructure"), exposed, three)
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _variables(variables: ElementTree.Element, system: System, exposed: Sequence[Exposed],
               three: bool) -> None:
    """The container's ModelVariables: each exposed port with its causality, start, range and unit
    (value reference: its position); FMI 3.0: then the independent variable time."""
    for vr, e in enumerate(exposed):
        var = system.components[e.port.component].variables[e.port.connector]
        attributes = {"name": str(e.port), "valueReference": str(vr)}
        if var.description:
            attributes["description"] = var.description
        if e.kind == "output":
            attributes |= {"causality": "output", "variability": "continuous", "initial": "calculated"}
        elif e.kind == "input":
            attributes |= {"causality": "input", "variability": "continuous"}
        else:
            attributes |= {"causality": "parameter", "variability": "fixed", "initial": "exact"}
        typed: dict[str, str] = {}
        if e.kind != "output":
            typed["start"] = _start(e.type, e.start)
        if e.kind == "parameter" and e.type != "Boolean":
            typed |= {b: str(getattr(var, b)) for b in ("min", "max") if getattr(var, b) is not None}
        if _unit(var) and e.type == "Real":
            typed["unit"] = _unit(var) or ""
        if three:
            ElementTree.SubElement(variables, FMI3_TYPES[e.type], attributes | typed)
        else:
            node = ElementTree.SubElement(variables, "ScalarVariable", attributes)
            ElementTree.SubElement(node, e.type, typed)
    if three:  # the plan's last value reference: the time of the last communication point
        ElementTree.SubElement(variables, "Float64", {
            "name": "time", "valueReference": str(len(exposed)), "causality": "independent",
            "variability": "continuous", "description": "Simulation time"})


def _structure(structure: ElementTree.Element, exposed: Sequence[Exposed], three: bool) -> None:
    """The container's ModelStructure: every output with its dependencies (FMI 2.0: indices, under
    Outputs and InitialUnknowns; FMI 3.0: value references, Output and InitialUnknown elements)."""
    key = {str(e.port): str(vr if three else vr + 1) for vr, e in enumerate(exposed)}
    attribute = "valueReference" if three else "index"
    outputs = [e for e in exposed if e.kind == "output"]
    if not outputs:
        return
    section = structure if three else ElementTree.SubElement(structure, "Outputs")
    for e in outputs:
        depends = " ".join(key[d] for d in sorted(e.depends_on, key=lambda d: int(key[d])))
        ElementTree.SubElement(section, "Output" if three else "Unknown",
                               {attribute: key[str(e.port)], "dependencies": depends})
    section = structure if three else ElementTree.SubElement(structure, "InitialUnknowns")
    for e in outputs:
        ElementTree.SubElement(section, "InitialUnknown" if three else "Unknown",
                               {attribute: key[str(e.port)]})


def _write(target: Path, entries: Mapping[str, bytes]) -> None:
    """The archive, written under a temporary name and renamed (the target is never half written)."""
    with replacing(target) as temporary, zipfile.ZipFile(temporary, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            # the runtime's .xz members are compressed already (fmu_src/toolchain/build.py): stored
            info.compress_type = zipfile.ZIP_STORED if name.endswith(".xz") else zipfile.ZIP_DEFLATED
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

    ``fmi`` "3": the FMU declares FMI 3.0 (its container speaks FMI 3.0 to the host; the FMUs
    inside stay FMI 2.0). ScenarioError for a scenario ``run`` would refuse, UsageError for a bad
    option (an FMI version or master that does not exist, an ``--expose`` pattern that matches
    nothing)."""
    if fmi not in FMI_VERSIONS:
        raise UsageError(f"--fmi must be one of {', '.join(FMI_VERSIONS)} (got {fmi!r})")
    if master not in MASTERS:
        raise UsageError(f"unknown master '{master}' (choose from {', '.join(MASTERS)})")
    target = Path(output)
    if target.suffix.lower() != ".fmu":
        raise UsageError(f"the exported file must end in .fmu (got {target})")
    identifier = model_identifier(target)
    with open_system(scenario, parameter_sets=list(parameter_sets), overrides=overrides, fmu_dirs=fmu_dirs,
                     limits=limits) as system:
        start, stop, step = timing(system.structure, stop_time, step, start_time)
        other = [f"{system.ssd}: component '{c.name}': FMU '{Path(c.fmu).name}' is FMI {c.model.fmiVersion}; "
                 "the container embeds FMI 2.0 and 3.0 Co-Simulation FMUs only"
                 for c in system.components.values() if c.model.fmiVersion.split(".")[0] not in ("2", "3")]
        if other:
            raise ScenarioError(other)
        folders = _folders(system)
        plan, exposed, records = container_plan(system, start, stop, step, master, select(system, expose),
                                                time_variable=fmi == "3")
        entries: dict[str, bytes] = {}
        for comp in system.components.values():
            entries |= _members(comp, folders[comp.name])
        entries = shared_runtimes(entries)
        try:
            platform = "x86_64-linux" if fmi == "3" else "linux64"  # FMI 3.0's platform tuple
            entries[f"binaries/{platform}/{identifier}.so"] = container_library()
            platform = "x86_64-windows" if fmi == "3" else "win64"
            entries[f"binaries/{platform}/{identifier}.dll"] = container_library(windows=True)
        except NativeError as exc:
            raise ScenarioError(f"cannot build the container runtime: {exc}") from exc
        entries |= documentation((), external=CONTAINER_DEPENDENCIES,
                                 note="The FMUs under resources/fmus/<name>/ keep their own licences in "
                                 "resources/fmus/<name>/documentation/licenses/.")
        digest = hashlib.sha256(_plan_text(plan, "", folders, records).encode())
        for name in sorted(entries):
            digest.update(name.encode() + b"\0" + hashlib.sha256(entries[name]).digest())
        digest.update(f"{identifier}\0{start!r}\0{stop!r}\0{step!r}\0{fmi}".encode())
        guid = "{" + str(uuid.uuid5(GUID_NAMESPACE, digest.hexdigest())) + "}"
        entries["resources/container.plan"] = _plan_text(plan, guid, folders, records).encode()
        entries["modelDescription.xml"] = model_description(system, exposed, identifier, guid, start, stop,
                                                            step, master, fmi)
    _write(target, entries)
    return target, exposed


def _plan_text(plan: Plan, guid: str, folders: Mapping[str, str], records: Sequence[str]) -> str:
    """The plan file: the engine's plan, each FMU in its folder, the container's variables."""
    return plan.text(guid, folders, records)
