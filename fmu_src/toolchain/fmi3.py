# SPDX-License-Identifier: BSD-2-Clause
"""The FMI 3.0 Co-Simulation variant of a built FMI 2.0 FMU: same model code, runtime and pythonfmu
binary, with the FMI 3.0 layer of the shim (``shim/fmi3_functions.c`` and the files beside it) in front.

The FMI 2.0 archive is the source: its members move from ``binaries/linux64/`` to
``binaries/x86_64-linux/`` and from ``binaries/win64/`` to ``binaries/x86_64-windows/`` (FMI 3.0's
platform tuples), the shims there are recompiled with the FMI 3.0 layer (their FMI 2.0 functions
internal), and ``modelDescription.xml`` is translated:

* variables: Real -> Float64, Integer -> Int32, Boolean -> Boolean, String -> String, with their
  attributes (start, min, max, nominal, unit, displayUnit, declaredType, ...), value references,
  causality, variability and initial unchanged; Enumeration variables or types are refused;
* value references: the FMI 2.0 one plus ``VR_OFFSET`` (1); pythonfmu numbers the variables 0, 1,
  ... in the order listed, so every FMI 3.0 value reference is also the variable's 1-based index
  and the ModelStructure's dependencies read the same as value references (FMI 3.0) and as
  indices (FMI 2.0's meaning, which OMSimulator 3 still applies to FMI 3.0 FMUs);
* FMI 3.0 requires one independent variable: ``time`` is added last, with the next value
  reference; the shim serves it;
* ModelStructure: ``Output`` and ``InitialUnknown`` elements with dependencies as value
  references (FMI 2.0 gives indices into ModelVariables);
* CoSimulation: the FMI 2.0 capabilities (canGetAndSetFMUState, canSerializeFMUState, ...) and
  what the layer refuses said explicitly (hasEventMode, providesIntermediateUpdate, ... false);
* the instantiation token is a digest of the FMI 2.0 GUID and the FMI 3.0 shim.

The result is deterministic: the same FMI 2.0 archive and compiler give the same bytes.
"""

from __future__ import annotations

import hashlib
import tempfile
import uuid
import zipfile
from collections.abc import Sequence
from pathlib import Path
from xml.etree import ElementTree

from . import stamps
from .build import (
    GUID_NAMESPACE,
    IDENTITY_FILE,
    PLATFORM_NAMES,
    REPO_ROOT,
    SHIM_SOURCES,
    BuildError,
    _ensure_runtime,
    build_inputs,
    compile_shim,
    identity,
    shim_digest,
    shim_files,
    write_archive,
)
from .clocked import ClockedError, clocked_model_description
from .licences import generation_tool

__all__ = ["CLOCKED_SUFFIX", "FMI3_PLATFORM", "FMI3_SHIM_SOURCES", "build_fmu3", "compile_shared_fmi3",
           "fmi3_model_description",
           "fmu3_current", "target_name"]

FMI2_PLATFORM = "binaries/linux64/"
FMI3_PLATFORM = "binaries/x86_64-linux/"
# FMI 2.0 platform folder -> FMI 3.0 platform tuple, and the binaries' suffix
PLATFORM_TUPLES = {FMI2_PLATFORM: (FMI3_PLATFORM, ".so"),
                   "binaries/win64/": ("binaries/x86_64-windows/", ".dll")}
FMI3_SHIM_SOURCES = (*SHIM_SOURCES, "fmi3_functions.c", "fmi3_values.c", "fmi3_refused.c")
CLOCKED_SHIM_SOURCES = (*FMI3_SHIM_SOURCES, "fmi3_clocks.c")  # the clocked twin (toolchain/clocked.py)
CLOCKED_SUFFIX = "_clocked"  # FixedTimeController.fmu -> FixedTimeController_clocked.fmu
TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
# FMI 2.0 type attributes that FMI 3.0 keeps on the variable element (String's start is a child).
TYPE_ATTRIBUTES = ("declaredType", "quantity", "unit", "displayUnit", "relativeQuantity", "min", "max",
                   "nominal", "unbounded", "start")
VARIABLE_ATTRIBUTES = ("name", "valueReference", "description", "causality", "variability", "initial")
COSIMULATION = {  # FMI 2.0 attribute -> FMI 3.0 attribute
    "modelIdentifier": "modelIdentifier",
    "needsExecutionTool": "needsExecutionTool",
    "canBeInstantiatedOnlyOncePerProcess": "canBeInstantiatedOnlyOncePerProcess",
    "canGetAndSetFMUstate": "canGetAndSetFMUState",
    "canSerializeFMUstate": "canSerializeFMUState",
    "canHandleVariableCommunicationStepSize": "canHandleVariableCommunicationStepSize",
}
REFUSED_FEATURES = {  # what the FMI 3.0 layer does not provide, said explicitly
    "providesDirectionalDerivatives": "false",
    "providesAdjointDerivatives": "false",
    "providesPerElementDependencies": "false",
    "maxOutputDerivativeOrder": "0",
    "providesIntermediateUpdate": "false",
    "mightReturnEarlyFromDoStep": "false",
    "canReturnEarlyAfterIntermediateUpdate": "false",
    "hasEventMode": "false",
    "providesEvaluateDiscreteStates": "false",
}
TIME = "time"
VR_OFFSET = 1
# The FMI 3.0 shim's -D: no FMI 2.0 exports; the per-FMU value references are constants of the
# variable table's object (fmi3.h), so that every FMU shares the other objects; the clocked twin's too.
FMI3_DEFINES = ("EXPORT=", "FTC_TIME_VR=ftc_time_vr", f"FTC_VR_OFFSET={VR_OFFSET}")
CLOCKED_DEFINES = (*FMI3_DEFINES, "FTC_CLOCK_VR=ftc_clock_vr", "FTC_INTERVAL_VR=ftc_interval_vr")


def compile_shared_fmi3(root: Path = REPO_ROOT, platforms: Sequence[str] = PLATFORM_NAMES) -> None:
    """The FMI 3.0 shims' objects (plain and clocked) compiled once per platform, before builds run
    in parallel (as :func:`~fmu_src.toolchain.build.compile_shared` compiles the FMI 2.0 shim's):
    else two builds that start at once both compile them."""
    runtime = _ensure_runtime()
    with tempfile.TemporaryDirectory(prefix="ftc_shared3_") as tmp:
        for sources, defines in ((FMI3_SHIM_SOURCES, FMI3_DEFINES), (CLOCKED_SHIM_SOURCES, CLOCKED_DEFINES)):
            for windows in ("", "shared.dll") if "win64" in platforms else ("",):
                shim_digest(root, runtime, Path(tmp) / f"{len(defines)}{windows}", sources, defines, windows)


def _child(parent: ElementTree.Element, tag: str) -> ElementTree.Element | None:
    return parent.find(tag)


def fmi3_model_description(xml: bytes, token: str) -> tuple[bytes, int]:  # noqa: C901 (one pass, section by section)
    """The FMI 3.0 model description of the FMI 2.0 ``xml``, with instantiation token ``token``;
    also the value reference given to the independent variable ``time``. BuildError when the FMI
    2.0 description uses what the FMI 3.0 layer does not map (Enumeration, Model Exchange)."""
    old = ElementTree.fromstring(xml)
    model = old.get("modelName", "?")
    if old.get("fmiVersion") != "2.0":
        raise BuildError(f"{model}: not an FMI 2.0 model description (fmiVersion={old.get('fmiVersion')!r})")
    if _child(old, "ModelExchange") is not None:
        raise BuildError(f"{model}: the FMI 3.0 layer maps Co-Simulation only, not Model Exchange")
    cosimulation = _child(old, "CoSimulation")
    if cosimulation is None:
        raise BuildError(f"{model}: the FMI 2.0 model description has no CoSimulation element")
    root = ElementTree.Element("fmiModelDescription")
    root.set("fmiVersion", "3.0")
    for name in ("modelName", "description", "author", "version", "copyright", "license", "generationTool",
                 "variableNamingConvention"):
        if old.get(name) is not None:
            root.set(name, old.get(name, ""))
    root.set("generationTool", generation_tool("FMI 3.0 layer on PythonFMU 0.7.0, the shim, its own CPython"))
    root.set("instantiationToken", token)
    cs = ElementTree.SubElement(root, "CoSimulation")
    for name2, name3 in COSIMULATION.items():
        if cosimulation.get(name2) is not None:
            cs.set(name3, cosimulation.get(name2, ""))
    for name, value in REFUSED_FEATURES.items():
        cs.set(name, value)
    for section in ("UnitDefinitions",):
        found = _child(old, section)
        if found is not None:
            root.append(found)
    types = _child(old, "TypeDefinitions")
    if types is not None:
        root.append(_type_definitions(types, model))
    for section in ("LogCategories", "DefaultExperiment"):
        found = _child(old, section)
        if found is not None:
            root.append(found)

    variables = old.findall("ModelVariables/ScalarVariable")
    references = [int(v.get("valueReference", "-1")) + VR_OFFSET for v in variables]
    if any(v.get("name") == TIME for v in variables):
        raise BuildError(f"{model}: a variable is named '{TIME}', the name of FMI 3.0's independent variable")
    time_vr = max(references, default=0) + 1
    new_variables = ElementTree.SubElement(root, "ModelVariables")
    for v, vr in zip(variables, references, strict=True):
        new_variables.append(_variable(v, vr, model))
    ElementTree.SubElement(new_variables, "Float64", name=TIME, valueReference=str(time_vr),
                           description="Simulation time", causality="independent", variability="continuous")

    structure = ElementTree.SubElement(root, "ModelStructure")
    for section, tag in (("Outputs", "Output"), ("InitialUnknowns", "InitialUnknown")):
        for unknown in old.findall(f"ModelStructure/{section}/Unknown"):
            element = ElementTree.SubElement(structure, tag)
            element.set("valueReference", str(references[int(unknown.get("index", "0")) - 1]))
            dependencies = unknown.get("dependencies")
            if dependencies is not None:
                vrs = [str(references[int(i) - 1]) for i in dependencies.split()]
                element.set("dependencies", " ".join(vrs))
            kinds = unknown.get("dependenciesKind")
            if kinds is not None:
                element.set("dependenciesKind", kinds)
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n", time_vr


def _variable(v: ElementTree.Element, vr: int, model: str) -> ElementTree.Element:
    typed = next(iter(v), None)
    if typed is None or typed.tag not in TYPES:
        kind = typed.tag if typed is not None else "no type"
        raise BuildError(f"{model}: variable {v.get('name')} is {kind}; the FMI 3.0 layer maps "
                         f"{', '.join(TYPES)}")
    element = ElementTree.Element(TYPES[typed.tag])
    for name in VARIABLE_ATTRIBUTES:
        if v.get(name) is not None:
            element.set(name, str(vr) if name == "valueReference" else v.get(name, ""))
    for name in TYPE_ATTRIBUTES:
        value = typed.get(name)
        if value is None:
            continue
        if typed.tag == "String" and name == "start":
            ElementTree.SubElement(element, "Start", value=value)
        else:
            element.set(name, value)
    return element


def _type_definitions(types: ElementTree.Element, model: str) -> ElementTree.Element:
    new = ElementTree.Element("TypeDefinitions")
    for simple in types.findall("SimpleType"):
        typed = next(iter(simple), None)
        if typed is None or typed.tag not in TYPES:
            raise BuildError(f"{model}: type {simple.get('name')} is not one of {', '.join(TYPES)}")
        element = ElementTree.SubElement(new, f"{TYPES[typed.tag]}Type", name=simple.get("name", ""))
        if simple.get("description") is not None:
            element.set("description", simple.get("description", ""))
        for name in TYPE_ATTRIBUTES[1:-1]:
            if typed.get(name) is not None:
                element.set(name, typed.get(name, ""))
    return new


def _sources(root: Path, clocked: bool = False) -> list[Path]:
    files = shim_files(root, CLOCKED_SHIM_SOURCES if clocked else FMI3_SHIM_SOURCES)
    return sorted({*files, *([root / "fmu_src" / "toolchain" / "clocked.py"] if clocked else [])})


def _key(fmu2: Path, root: Path, clocked: bool = False) -> str:
    """The digest of what the FMI 3.0 variant (or the clocked twin) of ``fmu2`` is made from."""
    platforms = stamps.recorded_platforms(fmu2)
    return stamps.digest("fmi3-clocked" if clocked else "fmi3", Path(fmu2), *build_inputs(root, platforms),
                         *_sources(root, clocked))


def target_name(fmu2: Path, clocked: bool = False) -> str:
    """The file name of the FMI 3.0 variant of ``fmu2`` (the clocked twin: ``<name>_clocked.fmu``)."""
    return f"{fmu2.stem}{CLOCKED_SUFFIX}.fmu" if clocked else fmu2.name


def fmu3_current(fmu2: Path, dest: Path, root: Path = REPO_ROOT, clocked: bool = False) -> bool:
    """Whether ``dest/<name>`` is the FMI 3.0 variant (or the clocked twin) of ``fmu2`` as it is now."""
    return stamps.up_to_date(Path(dest) / target_name(fmu2, clocked), _key(fmu2, root, clocked),
                             stamps.recorded_platforms(fmu2))


def build_fmu3(fmu2: Path, dest: Path, root: Path = REPO_ROOT, *, force: bool = False,
               clocked: bool = False) -> Path:
    """Write ``dest/<model>.fmu``, the FMI 3.0 variant of the built FMI 2.0 FMU ``fmu2`` for the
    same platforms (reused when it was made from the same FMU by the same build, unless ``force``);
    ``clocked``: its clocked twin ``dest/<model>_clocked.fmu`` (:mod:`fmu_src.toolchain.clocked`,
    a controller's: its law activated by an input clock of interval ``sample_time``)."""
    dest = Path(dest)
    target = dest / target_name(fmu2, clocked)
    sources = _sources(root, clocked)
    platforms = stamps.recorded_platforms(fmu2)
    key = _key(fmu2, root, clocked)
    if not force and stamps.up_to_date(target, key, platforms):
        return target
    stamps.forget(target)
    with zipfile.ZipFile(fmu2) as archive:
        entries = {name: archive.read(name) for name in archive.namelist() if not name.endswith("/")}
    xml = entries.pop("modelDescription.xml", None)
    if xml is None:
        raise BuildError(f"{fmu2}: no modelDescription.xml")
    old = ElementTree.fromstring(xml)
    cosimulation = old.find("CoSimulation")
    model = cosimulation.get("modelIdentifier", "") if cosimulation is not None else ""
    if f"{FMI2_PLATFORM}{model}.so" not in entries:
        raise BuildError(f"{fmu2}: no {FMI2_PLATFORM}{model}.so")
    plain, time_vr = fmi3_model_description(xml, "")
    defines: tuple[str, ...] = FMI3_DEFINES
    constants = {"ftc_time_vr": time_vr}
    shim_sources: tuple[str, ...] = FMI3_SHIM_SOURCES
    if clocked:
        try:
            twin = clocked_model_description(plain)
        except ClockedError as exc:
            raise BuildError(f"{fmu2}: no clocked twin: {exc}") from None
        defines = CLOCKED_DEFINES
        constants |= {"ftc_clock_vr": twin.clock_vr, "ftc_interval_vr": twin.interval_vr}
        shim_sources = CLOCKED_SHIM_SOURCES
    moved = dict(entries)
    shims = {}  # FMI 3.0 platform folder -> the DLL's name (Windows) or ""
    for fmi2, (fmi3, suffix) in PLATFORM_TUPLES.items():
        if f"{fmi2}{model}{suffix}" not in entries:
            continue
        shims[fmi3] = (f"{model}.dll" if suffix == ".dll" else "", suffix)
        moved = {(fmi3 + name[len(fmi2):] if name.startswith(fmi2) else name): data
                 for name, data in moved.items()}
    with tempfile.TemporaryDirectory(prefix=f"ftc_build3_{model}_") as tmp:
        runtime = _ensure_runtime()
        code = shim_digest(root, runtime, Path(tmp), shim_sources, defines) + repr(sorted(constants.items()))
        digest = hashlib.sha256(old.get("guid", "").encode() + b"\0" + code.encode()).hexdigest()
        kind = "fmi3-clocked" if clocked else "fmi3"
        token = "{" + str(uuid.uuid5(GUID_NAMESPACE, f"{model}:{kind}:{digest}")) + "}"
        description = fmi3_model_description(xml, token)[0]
        moved["modelDescription.xml"] = clocked_model_description(description).xml if clocked else description
        moved[IDENTITY_FILE] = identity(moved["modelDescription.xml"])
        for fmi3, (dll, suffix) in shims.items():  # with the final description's variable table
            final = moved["modelDescription.xml"]
            moved[f"{fmi3}{model}{suffix}"] = compile_shim(root, runtime, Path(tmp), final, shim_sources,
                                                           defines, dll, constants)
    dest.mkdir(parents=True, exist_ok=True)
    write_archive(target, moved)
    stamps.record(target, key, stamps.recorded_sources(fmu2) | stamps.source_digests(sources, root), root,
                  platforms)
    return target
