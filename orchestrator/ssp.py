"""Read an SSP scenario (a ``.ssp`` archive or a folder holding ``SystemStructure.ssd``).

The archive is unpacked safely (no member may escape the folder), every XML file is parsed and
validated against the SSP 1.0 schemas that fmpy ships, and the SSD is read into plain frozen
dataclasses. fmpy's reader is used for parameter sets; the parts that ``fmpy.ssp.ssd.read_ssd``
drops (connector types, ``ssc:LinearTransformation``, ``DefaultExperiment``, the tool annotations
that hold the communication step) are read here. Every problem names the file it is in.
"""

from __future__ import annotations

import functools
import os
import shutil
import stat
import tempfile
import zipfile
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from fmpy.ssp import ssd as fmpy_ssd
from lxml import etree

from .errors import ScenarioError

__all__ = [
    "NS",
    "Component",
    "Connection",
    "Connector",
    "Experiment",
    "Parameter",
    "ParameterSet",
    "SystemStructure",
    "open_scenario",
    "read_parameter_set",
    "read_scenario",
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
    """Parameters in the order written; ``origin`` names the file (and element) for messages."""

    origin: str
    parameters: tuple[Parameter, ...]


@dataclass(frozen=True)
class Component:
    """An FMU instance of the system, with its parameter sets in the order they apply."""

    name: str
    source: Path
    connectors: tuple[Connector, ...]
    parameter_sets: tuple[ParameterSet, ...]


@dataclass(frozen=True)
class Connection:
    """``start`` output -> ``end`` input, with the value passed as ``factor * value + offset``."""

    start_element: str
    start_connector: str
    end_element: str
    end_connector: str
    factor: float = 1.0
    offset: float = 0.0

    def __str__(self) -> str:
        return f"{self.start_element}.{self.start_connector} -> {self.end_element}.{self.end_connector}"


@dataclass(frozen=True)
class Experiment:
    """DefaultExperiment of the SSD plus the communication step from a tool annotation."""

    start_time: float = 0.0
    stop_time: float | None = None
    step: float | None = None


@dataclass(frozen=True)
class SystemStructure:
    """Everything the SSD says, with file references resolved to paths that exist."""

    ssd_file: str
    name: str
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    experiment: Experiment


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
        connections.append(Connection(element.get("startElement"), element.get("startConnector"),
                                      element.get("endElement"), element.get("endConnector"),
                                      1.0 if factor is None else factor, 0.0 if offset is None else offset))
    if problems:
        raise ScenarioError(problems)
    return SystemStructure(label, system.get("name"), tuple(components), tuple(connections),
                           _read_experiment(root, system))


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
