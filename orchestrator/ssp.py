"""SSP 1.0 scenarios as one object model: frozen dataclasses read from and written to SSD/SSV
files (a ``.ssp`` archive or a folder holding ``SystemStructure.ssd``).

Reading: the archive is unpacked safely (no member may escape the folder), every XML file is
parsed and validated against the SSP 1.0 schemas that fmpy ships, and the SSD is read into the
dataclasses. fmpy's reader is used for parameter sets; the parts that ``fmpy.ssp.ssd.read_ssd``
drops (connector types, ``ssc:LinearTransformation``, ``DefaultExperiment``, the tool annotations
that hold the communication step) are read here. Every problem names the file it is in.

Writing (lxml) the way every tool reads it (SPEC section 7): literal ``ssd:``/``ssc:``/``ssv:``
prefixes, ``version="1.0"``, every connector declared with its causality and type, parameter
bindings on components (one ``.ssv`` each: libcosim applies only the first binding of a
component), the communication step both where libcosim reads it (``osp:FixedStepAlgorithm
baseStepSize``) and where OMSimulator does (``oms:FixedStepMaster stepSize``).
"""

from __future__ import annotations

import functools
import os
import shutil
import stat
import tempfile
import zipfile
from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from fmpy.ssp import ssd as fmpy_ssd
from lxml import etree

from .errors import ScenarioError

__all__ = [
    "NS",
    "SSD_NAME",
    "Component",
    "Connection",
    "Connector",
    "Experiment",
    "Parameter",
    "ParameterSet",
    "PortRef",
    "SystemStructure",
    "component",
    "open_scenario",
    "pack_ssp",
    "read_parameter_set",
    "read_scenario",
    "write_ssd",
    "write_ssv",
]

SSD_NAME = "SystemStructure.ssd"

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
OSP_ANNOTATION = "com.opensimulationplatform"
OMS_ANNOTATION = "org.openmodelica"
TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")


@dataclass(frozen=True, order=True)
class PortRef:
    """A variable of a component; ``str()`` is ``controller.v``, the name used everywhere."""

    component: str
    connector: str

    def __str__(self) -> str:
        return f"{self.component}.{self.connector}"

    @classmethod
    def parse(cls, text: str) -> PortRef:
        """``"controller.k1"`` -> PortRef("controller", "k1"); the variable may contain dots."""
        component, sep, connector = text.partition(".")
        if not sep or not component or not connector:
            raise ValueError(f"'{text}' is not of the form COMPONENT.VARIABLE")
        return cls(component, connector)


@dataclass(frozen=True)
class Connector:
    """A connector declared on a component: ``kind`` is the causality, ``type`` the ssc type."""

    name: str
    kind: str
    type: str | None


@dataclass(frozen=True)
class Parameter:
    """One parameter value, already converted to the Python type of its SSV type."""

    name: str
    type: str
    value: float | int | bool | str


@dataclass(frozen=True)
class ParameterSet:
    """Parameters in the order written; ``origin`` names the file (relative to the SSD when bound by
    a component) and is how messages name it."""

    origin: str
    parameters: tuple[Parameter, ...]

    @classmethod
    def of(cls, origin: str, values: Mapping[str, float | int | bool | str]) -> ParameterSet:
        """A parameter set from Python values, typed Boolean, Integer, Real or String by value."""
        return cls(origin, tuple(Parameter(name, _type_of(v), v) for name, v in values.items()))


@dataclass(frozen=True)
class Component:
    """An FMU instance of the system, with its parameter sets in the order they apply. ``source``
    is the FMU file: as written in the SSD (``resources/X.fmu``) for writing, resolved when read."""

    name: str
    source: Path
    connectors: tuple[Connector, ...]
    parameter_sets: tuple[ParameterSet, ...] = ()


@dataclass(frozen=True)
class Connection:
    """``start`` output -> ``end`` input, with the value passed as ``factor * value + offset``
    (``ssc:LinearTransformation``; the identity when there is none)."""

    start: PortRef
    end: PortRef
    factor: float = 1.0
    offset: float = 0.0

    @classmethod
    def between(cls, start: str, end: str, factor: float = 1.0, offset: float = 0.0) -> Connection:
        """``Connection.between("plant.x1", "controller.x1")``."""
        return cls(PortRef.parse(start), PortRef.parse(end), factor, offset)

    @property
    def transformed(self) -> bool:
        """True when the value is not passed unchanged."""
        return not (self.factor == 1.0 and self.offset == 0.0)

    def __str__(self) -> str:
        return f"{self.start} -> {self.end}"


@dataclass(frozen=True)
class Experiment:
    """DefaultExperiment of the SSD plus the communication step from a tool annotation."""

    start_time: float = 0.0
    stop_time: float | None = None
    step: float | None = None


@dataclass(frozen=True)
class SystemStructure:
    """Everything the SSD says. When read, every file reference is resolved to a path that exists
    and ``ssd_file`` is how messages name the SSD."""

    name: str
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    experiment: Experiment
    description: str = ""
    ssd_file: str = ""


def open_scenario(scenario: str | os.PathLike, stack: ExitStack) -> Path:
    """Return the folder holding ``SystemStructure.ssd``; an archive is unpacked into a temporary
    folder that ``stack`` removes. Hostile or broken archives raise ScenarioError."""
    path = Path(scenario)
    if path.is_dir():
        folder = path
    elif path.is_file():
        folder = Path(tempfile.mkdtemp(prefix="ssp-"))
        stack.callback(shutil.rmtree, folder, ignore_errors=True)
        _safe_extract(path, folder)
    else:
        raise ScenarioError(f"{path}: no such scenario (expected a .ssp archive or a folder)")
    if not (folder / SSD_NAME).is_file():
        raise ScenarioError(f"{path}: no {SSD_NAME} at the root of the scenario")
    return folder


def _safe_extract(archive: Path, dest: Path) -> None:
    """Extract every member, refusing absolute paths, '..', symbolic links and duplicates."""
    try:
        with zipfile.ZipFile(archive) as zf:
            members = zf.infolist()
            problems = []
            for info in members:
                name = info.filename
                parts = PurePosixPath(name.replace("\\", "/")).parts
                mode = info.external_attr >> 16
                if name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":") or ".." in parts:
                    problems.append(f"{archive.name}: member '{name}' points outside the archive folder")
                elif stat.S_ISLNK(mode):
                    problems.append(f"{archive.name}: member '{name}' is a symbolic link")
            if problems:
                raise ScenarioError(problems)
            for info in members:
                target = dest.joinpath(*PurePosixPath(info.filename).parts)
                if not target.resolve().is_relative_to(dest.resolve()):
                    raise ScenarioError(f"{archive.name}: member '{info.filename}' points outside the folder")
                zf.extract(info, dest)
    except zipfile.BadZipFile as exc:
        raise ScenarioError(f"{archive}: not a valid SSP (zip) archive: {exc}") from exc


@functools.cache
def _schema(name: str) -> etree.XMLSchema:
    return etree.XMLSchema(file=str(Path(fmpy_ssd.__file__).parent / "schema" / name))


def _parse(path: Path, schema: str, label: str) -> etree._Element:
    """Parse and schema-validate one XML file; errors name ``label`` (the file) and the line."""
    if not path.is_file():
        raise ScenarioError(f"{label}: file is missing")
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as exc:
        raise ScenarioError(f"{label}: broken XML: {exc}") from exc
    validator = _schema(schema)
    if not validator.validate(root):
        raise ScenarioError([f"{label} line {e.line}: {e.message}" for e in validator.error_log])
    return root


def _convert(type_: str, text: str | None, where: str) -> float | int | bool | str:
    try:
        if type_ == "Real":
            return float(text)
        if type_ in ("Integer", "Enumeration"):
            return int(text)
        if type_ == "Boolean":
            if text not in ("true", "false", "1", "0"):
                raise ValueError(text)
            return text in ("true", "1")
        return "" if text is None else text
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{where}: value {text!r} is not a valid {type_}") from exc


def _parameter_set(fmpy_set: fmpy_ssd.ParameterSet, origin: str, prefix: str) -> ParameterSet:
    """Convert fmpy's parameter set, stripping the binding's prefix from every name."""
    problems, parameters = [], []
    for p in fmpy_set.parameters:
        name = p.name
        if prefix:
            if not name.startswith(prefix):
                problems.append(f"{origin}: parameter '{name}' does not start with the prefix '{prefix}'")
                continue
            name = name[len(prefix):]
        if p.type is None:
            problems.append(f"{origin}: parameter '{name}' has no value element")
            continue
        parameters.append(Parameter(name, p.type, _convert(p.type, p.value, f"{origin}: parameter '{name}'")))
    if problems:
        raise ScenarioError(problems)
    return ParameterSet(origin, tuple(parameters))


def read_parameter_set(path: str | os.PathLike, prefix: str = "") -> ParameterSet:
    """Read and validate one ``.ssv`` file (fmpy's reader, after our own schema check)."""
    path = Path(path)
    _parse(path, "SystemStructureParameterValues.xsd", str(path))
    return _parameter_set(fmpy_ssd.read_ssv(str(path), validate=False), path.name, prefix)


def read_scenario(folder: Path, label: str | None = None) -> SystemStructure:
    """Read the SSD in ``folder``; ``label`` is how messages name the SSD (default: its path)."""
    label = label or str(folder / SSD_NAME)
    root = _parse(folder / SSD_NAME, "SystemStructureDescription.xsd", label)
    problems: list[str] = []
    if root.get("version") != "1.0":
        problems.append(f"{label}: version must be \"1.0\" (got {root.get('version')!r})")
    system = root.find("ssd:System", NS)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        problems.append(f"{label}: nested systems are not supported")
    if system.find("ssd:ParameterBindings", NS) is not None:
        problems.append(f"{label}: parameter bindings on the system are not supported (other tools ignore "
                        "them); bind parameters on the components")

    components = []
    for element in system.findall("ssd:Elements/ssd:Component", NS):
        try:
            components.append(_read_component(element, folder, label))
        except ScenarioError as exc:
            problems.extend(exc.problems)
    connections = []
    for element in system.findall("ssd:Connections/ssd:Connection", NS):
        transformation = element.find("ssc:LinearTransformation", NS)
        if element.find("ssc:*", NS) is not None and transformation is None:
            start = f"{element.get('startElement')}.{element.get('startConnector')}"
            problems.append(f"{label}: connection from {start}"
                            " has a transformation other than LinearTransformation (not supported)")
        factor = offset = None
        if transformation is not None:
            factor = float(transformation.get("factor", "1"))
            offset = float(transformation.get("offset", "0"))
        connections.append(Connection(PortRef(element.get("startElement"), element.get("startConnector")),
                                      PortRef(element.get("endElement"), element.get("endConnector")),
                                      1.0 if factor is None else factor, 0.0 if offset is None else offset))
    if problems:
        raise ScenarioError(problems)
    return SystemStructure(system.get("name"), tuple(components), tuple(connections),
                           _read_experiment(root, system), system.get("description", ""), label)


def _read_component(element: etree._Element, folder: Path, label: str) -> Component:
    name = element.get("name")
    problems = []
    where = f"{label}: component '{name}'"
    source = folder / element.get("source")
    if element.get("type", "application/x-fmu-sharedlibrary") != "application/x-fmu-sharedlibrary":
        problems.append(f"{where}: only FMU components are supported (type {element.get('type')!r})")
    elif not source.is_file():
        problems.append(f"{where}: FMU '{element.get('source')}' is missing")
    connectors = []
    for c in element.findall("ssd:Connectors/ssd:Connector", NS):
        type_ = next((t for t in TYPES if c.find(f"ssc:{t}", NS) is not None), None)
        connectors.append(Connector(c.get("name"), c.get("kind"), type_))
    parameter_sets = []
    for binding in element.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        prefix = binding.get("prefix", "")
        try:
            if binding.get("source") is not None:
                ssv = folder / binding.get("source")
                _parse(ssv, "SystemStructureParameterValues.xsd", f"{label}: {binding.get('source')}")
                parameter_sets.append(_parameter_set(fmpy_ssd.read_ssv(str(ssv), validate=False),
                                                     binding.get("source"), prefix))
            for inline in binding.findall("ssd:ParameterValues/ssv:ParameterSet", NS):
                parameter_sets.append(_parameter_set(fmpy_ssd._get_parameter_set(inline),
                                                     f"{label} (inline values of '{name}')", prefix))
        except ScenarioError as exc:
            problems.extend(exc.problems)
    if problems:
        raise ScenarioError(problems)
    return Component(name, source, tuple(connectors), tuple(parameter_sets))


def _read_experiment(root: etree._Element, system: etree._Element) -> Experiment:
    """Start/stop from DefaultExperiment; the step from libcosim's or OMSimulator's annotation."""
    experiment = root.find("ssd:DefaultExperiment", NS)
    start, stop, step = 0.0, None, None
    if experiment is not None:
        start = float(experiment.get("startTime", "0"))
        stop = float(experiment.get("stopTime")) if experiment.get("stopTime") is not None else None
        osp = experiment.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']"
                              "/osp:Algorithm/osp:FixedStepAlgorithm", NS)
        if osp is not None:
            step = float(osp.get("baseStepSize"))
    if step is None:
        oms = system.find(f"ssd:Annotations/ssc:Annotation[@type='{OMS_ANNOTATION}']"
                          "/oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", NS)
        if oms is not None:
            step = float(oms.get("stepSize"))
    return Experiment(start, stop, step)


# -- writing ------------------------------------------------------------------------------------------
def _type_of(value: float | int | bool | str) -> str:
    if isinstance(value, bool):
        return "Boolean"
    if isinstance(value, int):
        return "Integer"
    return "String" if isinstance(value, str) else "Real"


def _literal(value: float | int | bool | str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return value if isinstance(value, str) else repr(value)


def _element(parent: etree._Element | None, tag: str, nsmap: Mapping[str, str] | None = None,
             **attributes: str) -> etree._Element:
    """``prefix:Name`` element with attributes in the order given, appended to ``parent``."""
    prefix, name = tag.split(":")
    qualified = f"{{{NS[prefix]}}}{name}"
    element = etree.Element(qualified, nsmap=nsmap) if parent is None else etree.SubElement(parent, qualified)
    for key, value in attributes.items():
        element.set(key, value)
    return element


def _write(root: etree._Element, path: Path) -> None:
    etree.ElementTree(root).write(str(path), pretty_print=True, xml_declaration=True, encoding="UTF-8")


def component(name: str, fmu: str, connectors: Iterable[tuple[str, str, str]],
              parameters: Mapping[str, float | int | bool | str] | None = None) -> Component:
    """A component to write: FMU file name under ``resources/``, connectors ``(name, kind, type)``
    and the parameter values bound from ``<name>.ssv`` (none: no binding)."""
    sets = (ParameterSet.of(f"{name}.ssv", parameters),) if parameters else ()
    return Component(name, Path("resources") / fmu, tuple(Connector(*c) for c in connectors), sets)


def write_ssv(path: str | os.PathLike, parameter_set: ParameterSet, name: str | None = None) -> Path:
    """Write a parameter set (names as given, no prefix); ``name`` defaults to the file's stem."""
    path = Path(path)
    root = _element(None, "ssv:ParameterSet", {"ssv": NS["ssv"]}, version="1.0", name=name or path.stem)
    parameters = _element(root, "ssv:Parameters")
    for p in parameter_set.parameters:
        _element(_element(parameters, "ssv:Parameter", name=p.name), f"ssv:{p.type}", value=_literal(p.value))
    _write(root, path)
    return path


def write_ssd(folder: str | os.PathLike, structure: SystemStructure) -> Path:
    """Write ``folder/SystemStructure.ssd`` and the ``.ssv`` file of every parameter set bound by a
    component (named by its ``origin``); returns the SSD's path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    nsmap = {prefix: NS[prefix] for prefix in ("ssd", "ssc", "ssv", "osp", "oms")}
    root = _element(None, "ssd:SystemStructureDescription", nsmap, version="1.0", name=structure.name)
    system = _element(root, "ssd:System", name=structure.name, description=structure.description)
    elements = _element(system, "ssd:Elements")
    for c in structure.components:
        source = c.source.relative_to(folder) if c.source.is_absolute() else c.source
        element = _element(elements, "ssd:Component", name=c.name, type="application/x-fmu-sharedlibrary",
                           source=source.as_posix())
        connectors = _element(element, "ssd:Connectors")
        for k in c.connectors:
            connector = _element(connectors, "ssd:Connector", name=k.name, kind=k.kind)
            if k.type is not None:
                _element(connector, f"ssc:{k.type}")
        if c.parameter_sets:
            bindings = _element(element, "ssd:ParameterBindings")
            for ps in c.parameter_sets:
                write_ssv(folder / ps.origin, ps, c.name)
                _element(bindings, "ssd:ParameterBinding", source=ps.origin)
    connections = _element(system, "ssd:Connections")
    for k in structure.connections:
        connection = _element(connections, "ssd:Connection", startElement=k.start.component,
                              startConnector=k.start.connector, endElement=k.end.component,
                              endConnector=k.end.connector)
        if k.transformed:
            _element(connection, "ssc:LinearTransformation", factor=repr(k.factor), offset=repr(k.offset))
    ex = structure.experiment
    if ex.step is not None:
        annotation = _element(_element(system, "ssd:Annotations"), "ssc:Annotation", type=OMS_ANNOTATION)
        information = _element(_element(annotation, "oms:Annotations"), "oms:SimulationInformation")
        _element(information, "oms:FixedStepMaster", description="oms-ma", stepSize=repr(ex.step))
    times = {"startTime": repr(ex.start_time)}
    if ex.stop_time is not None:
        times["stopTime"] = repr(ex.stop_time)
    experiment = _element(root, "ssd:DefaultExperiment", **times)
    if ex.step is not None:
        annotation = _element(_element(experiment, "ssd:Annotations"), "ssc:Annotation", type=OSP_ANNOTATION)
        _element(_element(annotation, "osp:Algorithm"), "osp:FixedStepAlgorithm", baseStepSize=repr(ex.step),
                 numWorkerThreads="0")
    path = folder / SSD_NAME
    _write(root, path)
    return path


def pack_ssp(folder: str | os.PathLike, fmus: Mapping[str, str | os.PathLike],
             dest: str | os.PathLike) -> Path:
    """Zip ``folder`` (SSD at the root, .ssv files beside it) with ``fmus`` (archive name -> file)
    placed under ``resources/``; written to a temporary name first so a failed build leaves no
    half-written archive."""
    folder, dest = Path(folder), Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    partial = dest.with_name(dest.name + ".part")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file() and not path.name.startswith("."):
                zf.write(path, path.relative_to(folder).as_posix())
        for name, path in sorted(fmus.items()):
            zf.write(path, f"resources/{name}")
    partial.replace(dest)
    return dest
