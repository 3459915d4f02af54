# SPDX-License-Identifier: BSD-2-Clause
"""SSP 1.0 and 2.0 scenarios as one object model: frozen dataclasses read from and written to SSD/SSV
files (a ``.ssp`` archive or a folder holding ``SystemStructure.ssd``).

Reading: the archive is unpacked safely and within bounds: only the SSD and what it references
(its parameter files, the FMUs of its components) are extracted, no member may escape the folder,
and :class:`Limits` bounds the number of members, the size of each member and of all together, and
the compression ratio, for the archive and for every FMU in it (see ``Limits``). Every XML file is
parsed (no entity expansion, no network) and validated against the schemas of its version: SSP
1.0's that fmpy ships, or SSP 2.0's (``orchestrator/schemas/ssp2``, the standard's own, tag v2.0),
and the SSD is read into the dataclasses. SSP 2.0 (same namespaces) adds what is read here: the
FMI 3.0 connector types (Float64, Float32, the integer widths, Binary, Clock), clock connectors
and their connections, and the kinds and arrays that are refused in one line each (structural
parameters, array connectors, connections of array elements: see :func:`_connectors`). Read
here too, beyond what ``fmpy.ssp.ssd.read_ssd`` keeps: connector types,
``ssc:LinearTransformation``, ``DefaultExperiment``, the tool annotations that hold the
communication step, and what other tools write beyond our own scenarios: nested systems
(flattened once, here, into components named ``sub.component``), parameter bindings on systems,
SSM parameter mappings, and OMSimulator's ``version="2.0"`` files. Every problem names the file it is in.

Writing (lxml) the way every tool reads it (SPEC section 7): literal ``ssd:``/``ssc:``/``ssv:``
prefixes, ``version="1.0"`` (``"2.0"`` only when a connector needs SSP 2.0: an FMI 3.0 type, a
clock), every connector declared with its causality and type, parameter
bindings on components (one ``.ssv`` each: libcosim applies only the first binding of a
component), the communication step both where libcosim reads it (``osp:FixedStepAlgorithm
baseStepSize``) and where OMSimulator does (``oms:FixedStepMaster stepSize``).
"""

from __future__ import annotations

import functools
import math
import os
import posixpath
import re
import shutil
import stat
import zipfile
from collections.abc import Iterable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath
from typing import overload
from urllib.parse import parse_qs, urlsplit

from fmpy.ssp import ssd as fmpy_ssd
from lxml import etree

from . import files, fmucache
from .errors import ScenarioError
from .units import UnitDef, read_units

__all__ = [
    "NS",
    "SSD_NAME",
    "Component",
    "Connection",
    "Connector",
    "DEFAULT_LIMITS",
    "Experiment",
    "Limits",
    "Parameter",
    "ParameterSet",
    "PortRef",
    "Reading",
    "SystemStructure",
    "component",
    "extract_scenario",
    "open_scenario",
    "pack_ssp",
    "read_parameter_set",
    "read_scenario",
    "reference_problem",
    "scan_parameter_set",
    "scan_scenario",
    "test_zip",
    "unpack_scenario",
    "write_ssd",
    "write_ssv",
]

SSD_NAME = "SystemStructure.ssd"

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
OSP_ANNOTATION = "com.opensimulationplatform"
OMS_ANNOTATION = "org.openmodelica"
VERSIONS = ("1.0", "2.0")
SSP2_SCHEMAS = Path(__file__).resolve().parent / "schemas" / "ssp2"
# The connector types of ssc:GTypeChoice (SSP 2.0 adds FMI 3.0's; an SSP 1.0 file has the first row).
TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary",
         "Float64", "Float32", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
         "Clock")
# SSV value elements of SSP 2.0 -> the type the engine sets them as (SSP 1.0's name).
SSV_TYPES = {"Real": "Real", "Float64": "Real", "Float32": "Real", "Integer": "Integer",
             **{t: "Integer" for t in TYPES[8:16]}, "Boolean": "Boolean", "String": "String",
             "Enumeration": "Enumeration", "Binary": "Binary"}
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the date of every member pack_ssp writes (the earliest a zip holds)


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
    """A connector declared on a component: ``kind`` is the causality, ``type`` the ssc type,
    ``unit`` the unit its type element declares (None: none). SSP 2.0: ``clocks`` the clocks it is
    associated to (``ssd:Clock name``), ``interval`` the ``intervalDecimal`` of a Clock connector
    (None: not given; the FMU's own applies)."""

    name: str
    kind: str
    type: str | None
    unit: str | None = None
    clocks: tuple[str, ...] = ()
    interval: float | None = None


@dataclass(frozen=True)
class Parameter:
    """One parameter value, already converted to the Python type of its SSV type; ``unit``: the
    unit the value is given in (SSV ``unit`` attribute of a Real; None: the variable's own);
    ``origin``: how messages name where it came from when not its set's file (an SSM entry);
    ``transform``: ``(factor, offset)`` of a LinearTransformation still to apply, after the value is
    converted from ``unit`` to the variable's unit (SSP 1.0.1, 5.3.2: units first)."""

    name: str
    type: str
    value: float | int | bool | str
    unit: str | None = None
    origin: str | None = None
    transform: tuple[float, float] | None = None


@dataclass(frozen=True)
class ParameterSet:
    """Parameters in the order written; ``origin`` names the file (relative to the SSD when bound by
    a component) and is how messages name it."""

    origin: str
    parameters: tuple[Parameter, ...]
    units: tuple[UnitDef, ...] = ()  # the file's own ssv:Units definitions

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
    (``ssc:LinearTransformation``; the identity when there is none). Read from an SSD, the factor
    and offset are the file's; the System composes them with the conversion between the ends'
    units (applied first, SSP 1.0.1 4.5.2.1), unless ``suppress_units`` (``suppressUnitConversion``)."""

    start: PortRef
    end: PortRef
    factor: float = 1.0
    offset: float = 0.0
    suppress_units: bool = False

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
    """DefaultExperiment of the SSD plus the communication step from a tool annotation, and the
    master that annotation implies (``algorithm``, a name of ``orchestrator.master.MASTERS``; None
    when the SSD names no algorithm) with the annotation it comes from (``algorithm_from``), and
    the relative tolerance OMSimulator's annotation gives the FMUs' own solvers (``tolerance``;
    None: the SSD gives none, and each FMU uses its own default). Those three are read, never
    written (:func:`write_ssd` writes both tools' annotations, which name no one algorithm), so
    they take no part in comparing experiments."""

    start_time: float = 0.0
    stop_time: float | None = None
    step: float | None = None
    algorithm: str | None = field(default=None, compare=False)
    algorithm_from: str = field(default="", compare=False)
    tolerance: float | None = field(default=None, compare=False)


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
    units: tuple[UnitDef, ...] = ()  # the SSD's own ssd:Units definitions
    connector_values: tuple[tuple[str, Parameter], ...] = ()  # values bound to system connectors


@dataclass(frozen=True)
class Limits:
    """Bounds on what a scenario may unpack to, so that any input costs bounded disk, memory and
    time (a CI service runs archives it did not write). They apply to the members extracted from an
    ``.ssp`` archive (all together: ``total``) and to every FMU of the scenario (all its members,
    as an FMU is extracted whole). Sizes are the uncompressed sizes the zip directory declares,
    which Python's zipfile enforces while reading (a member that lies fails its CRC check).

    ``ratio`` (uncompressed / compressed) applies to members of at least ``RATIO_FLOOR`` bytes:
    small files compress well without being bombs. ``xml`` bounds an SSD, SSV, SSM or
    modelDescription.xml, which are parsed in memory (lxml needs several times the file size)."""

    total: int = 1 << 30
    member: int = 512 << 20
    ratio: float = 100.0
    members: int = 10_000
    xml: int = 32 << 20

    OPTIONS = {"total": "--max-total-size", "member": "--max-member-size", "ratio": "--max-ratio",
               "members": "--max-members", "xml": "--max-xml-size"}


DEFAULT_LIMITS = Limits()
RATIO_FLOOR = 1 << 20
NAME_MAX = 255  # bytes of one file name (Linux, macOS, Windows): a longer member cannot be extracted
XML_SUFFIXES = (".ssd", ".ssv", ".ssm", ".xml")


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _shown(name: str) -> str:
    """A member name or reference as a message shows it: characters that are not printable (a
    carriage return, a line or paragraph separator, control characters) escaped, so that a hostile
    name cannot break the message's single line."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in name)


def _size(n: float) -> str:
    """``1536`` -> ``1.5 KiB``."""
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return ""  # unreachable


def open_scenario(scenario: str | os.PathLike, stack: ExitStack, limits: Limits = DEFAULT_LIMITS) -> Path:
    """Return the folder holding ``SystemStructure.ssd``; an archive is unpacked into a temporary
    folder that ``stack`` removes. Hostile or broken archives raise ScenarioError."""
    folder, problems = unpack_scenario(scenario, stack, limits)
    if folder is None or problems:
        raise ScenarioError(problems)
    return folder


def unpack_scenario(scenario: str | os.PathLike, stack: ExitStack,
                    limits: Limits = DEFAULT_LIMITS,
                    root: Path | None = None) -> tuple[Path | None, list[str]]:
    """:func:`open_scenario` that returns its problems instead of raising, for checks that go on:
    unsafe members of an archive are reported and left out, the SSD and what it references
    extracted within ``limits``; every FMU the SSD references is checked against ``limits`` (also in
    a folder, with those below ``root`` it reaches with '..'). The folder is None when there is no
    SSD to read, or the archive breaks a limit."""
    path = Path(scenario)
    if path.is_dir():
        problems = _check_fmus(path, str(path), limits, root)
        if problems:
            return None, problems
        if not (path / SSD_NAME).is_file():
            return None, [f"{path}: no {SSD_NAME} at the root of the scenario"]
        return path, []
    if not path.is_file():
        return None, [f"{path}: no such scenario (expected a .ssp archive or a folder)"]
    try:
        folder = files.temporary_folder("ssp-")
    except OSError as exc:
        return None, [f"{path}: cannot unpack: no temporary folder ({_one_line(exc)})"]
    stack.callback(shutil.rmtree, folder, ignore_errors=True)
    stack.callback(fmucache.forget, folder)
    problems, refused = _unpack(path, folder, limits, defer=True)
    return (None if refused else folder), problems


def extract_scenario(archive: Path, dest: Path, limits: Limits = DEFAULT_LIMITS) -> list[str]:
    """Unpack the ``.ssp`` ``archive`` into the folder ``dest`` as :func:`unpack_scenario` does
    (what a campaign worker runs); every problem found, none when it may be run."""
    dest.mkdir(parents=True, exist_ok=True)
    return _unpack(archive, dest, limits)[0]


def _unpack(path: Path, folder: Path, limits: Limits, defer: bool = False) -> tuple[list[str], bool]:
    """Unpack archive ``path`` into ``folder``: the problems, and whether they refuse it whole
    (``defer``: FMUs the cache holds unpacked are left in the archive, :func:`fmucache.defer`)."""
    try:
        problems, refused = _safe_extract(path, folder, limits, defer)
    except OSError as exc:  # a full or unwritable temporary folder, an unreadable archive
        return [f"{path}: cannot unpack into {folder}: {_one_line(exc)}"], True
    except Exception as exc:  # noqa: BLE001 - zipfile, zlib and friends: not an archive we can read
        return [f"{path}: not a valid SSP (zip) archive: {_one_line(exc)}"], True
    if refused:
        return problems, True
    if not (folder / SSD_NAME).is_file():
        return [*problems, f"{path}: no {SSD_NAME} at the root of the scenario"], True
    fmu_problems = _check_fmus(folder, path.name, limits)
    return problems + fmu_problems, bool(fmu_problems)


def _check_fmus(folder: Path, label: str, limits: Limits, root: Path | None = None) -> list[str]:
    """The limits the FMUs the SSD in ``folder`` references break (refused before anything reads
    them: fmpy reads an FMU whole)."""
    if not (folder / SSD_NAME).is_file():
        return []
    for reference in _references(folder / SSD_NAME, limits, root is not None)[1]:
        fmu = folder / reference
        if root is not None and not fmu.resolve().is_relative_to(root.resolve()):
            continue  # refused by the reading
        if fmu.is_file() and zipfile.is_zipfile(fmu):  # not a deferred one: its entry is unpacked already
            problems = check_zip(fmu, f"{label}: {reference}", limits)
            if problems:
                return problems
    return []


def check_zip(path: Path, label: str, limits: Limits = DEFAULT_LIMITS,
              infos: list[zipfile.ZipInfo] | None = None) -> list[str]:
    """The limits ``path`` (a zip file, e.g. an FMU, extracted whole) breaks, or ``infos`` of it, and
    its members that would leave the folder it is extracted to; one line each naming ``label``, the
    member and the option that raises the limit. Reads only the zip's directory."""
    problems = []
    if infos is None:
        try:
            with zipfile.ZipFile(path) as zf:
                infos = zf.infolist()
        except (zipfile.BadZipFile, OSError, ValueError) as exc:
            return [f"{label}: not a valid zip file: {exc}"]
    option = Limits.OPTIONS
    if len(infos) > limits.members:
        return [f"{label}: {len(infos)} members, above the limit of {limits.members} ({option['members']})"]
    total = 0
    for info in infos:
        size, name = info.file_size, info.filename
        total += size
        where = f"{label}: member '{_shown(name)}'"
        if _escapes(name):
            problems.append(f"{where} points outside the archive folder")
        elif "\\" in name or ":" in name:
            problems.append(f"{where} has a backslash or a colon in its name (zip paths use '/' and "
                            "no drive or device letter)")
        elif any(len(part.encode()) > NAME_MAX for part in name.split("/")):
            problems.append(f"{where} has a name part longer than {NAME_MAX} bytes (no file system "
                            "can hold it)")
        elif stat.S_ISLNK(info.external_attr >> 16):
            problems.append(f"{where} is a symbolic link")
        elif size > limits.member:
            problems.append(f"{where} is {_size(size)} uncompressed, above the limit of "
                            f"{_size(limits.member)} per member ({option['member']})")
        elif name.lower().endswith(XML_SUFFIXES) and size > limits.xml:
            problems.append(f"{where} is {_size(size)}, above the limit of {_size(limits.xml)} for an "
                            f"XML file ({option['xml']})")
        elif size >= RATIO_FLOOR and size > limits.ratio * max(info.compress_size, 1):
            problems.append(f"{where} expands {size / max(info.compress_size, 1):.0f} times (to "
                            f"{_size(size)}), above the limit of {limits.ratio:g} ({option['ratio']})")
    if total > limits.total and not problems:
        problems.append(f"{label}: {_size(total)} uncompressed in all, above the limit of "
                        f"{_size(limits.total)} ({option['total']})")
    return problems


def test_zip(path: Path, label: str) -> list[str]:
    """Read every member of the zip file ``path`` (within the limits :func:`check_zip` checked) as
    an extraction would: a member whose data is corrupt or whose declared size lies fails its CRC
    or size check here. One line naming ``label`` and the member, or none."""
    name = ""
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                name = info.filename
                with zf.open(info) as member:
                    while member.read(1 << 20):
                        pass
    except Exception as exc:  # noqa: BLE001 - zipfile, zlib, bz2, lzma each raise their own
        where = f"member '{_shown(name)}'" if name else "its directory"
        return [f"{label}: {where} cannot be unpacked: {_one_line(exc)}"]
    return []


def _escapes(name: str) -> bool:
    """Whether a member name is absolute or climbs out of the folder it is extracted to."""
    parts = PurePosixPath(name.replace("\\", "/")).parts
    return name.startswith(("/", "\\")) or (len(name) > 1 and name[1] == ":") or ".." in parts


def _unsafe(info: zipfile.ZipInfo, dest: Path, label: str) -> str:
    """Why a member must not be extracted into ``dest`` ('' when it may)."""
    name = info.filename
    target = dest.joinpath(*PurePosixPath(name).parts)
    if _escapes(name) or not target.resolve().is_relative_to(dest.resolve()):
        return f"{label}: member '{_shown(name)}' points outside the archive folder"
    if stat.S_ISLNK(info.external_attr >> 16):
        return f"{label}: member '{_shown(name)}' is a symbolic link"
    return ""


def _safe_extract(archive: Path, dest: Path, limits: Limits,
                  defer: bool = False) -> tuple[list[str], bool]:
    """Extract the SSD and the members it references (parameter files, FMUs), nothing else, within
    ``limits``; members with an absolute path, '..' or a symbolic link are reported and left out
    (nothing is ever written outside ``dest``). With ``defer``, an FMU whose digest an earlier
    extraction remembered and whose cache entry is complete stays in the archive
    (:func:`fmucache.defer`): a run reads it from the entry. Returns the problems and whether the
    archive is refused as a whole (a limit broken: nothing more is read). Raises BadZipFile when
    the file is not a zip archive."""
    problems = []
    label = archive.name
    with zipfile.ZipFile(archive) as zf:
        infos = zf.infolist()
        if len(infos) > limits.members:
            return [f"{label}: {len(infos)} members, above the limit of {limits.members} "
                    f"({Limits.OPTIONS['members']})"], True
        safe: dict[str, zipfile.ZipInfo] = {}
        for info in infos:
            problem = _unsafe(info, dest, label)
            if problem:
                problems.append(problem)
            elif not info.is_dir():
                safe[posixpath.normpath(info.filename)] = info
        if SSD_NAME not in safe:
            return problems, False
        wanted = [safe[SSD_NAME]]
        limit_problems = check_zip(archive, label, limits, wanted)
        if limit_problems:
            return problems + limit_problems, True
        zf.extract(wanted[0], dest)
        xml_files, fmus = _references(dest / SSD_NAME, limits)
        wanted += [safe[n] for n in dict.fromkeys(xml_files + fmus) if n in safe and n != SSD_NAME]
        limit_problems = check_zip(archive, label, limits, wanted)
        if limit_problems:
            return problems + limit_problems, True
        for info in wanted[1:]:
            name = info.filename
            if not (defer and name in fmus and fmucache.defer(dest / name, archive, name)):
                zf.extract(info, dest)
    for name in dict.fromkeys(fmus):
        if (dest / name).is_file():
            fmucache.member_sha256(dest / name, archive, name)  # remembered: not hashed again
    return problems, False


def _fmu_file(path: Path) -> bool:
    """Whether an FMU is there: a file, or an archive's member left unextracted (its cache entry
    holds it unpacked, :func:`fmucache.defer`)."""
    return fmucache.deferred(path) or path.is_file()


def _parser() -> etree.XMLParser:
    """lxml parser for untrusted files: no entity expansion, no DTD or network access."""
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)


def _references(ssd: Path, limits: Limits, climb: bool = False) -> tuple[list[str], list[str]]:
    """What the SSD at ``ssd`` references, as normalized paths relative to its folder: XML files
    (SSV, SSM) and FMUs; paths that would leave the folder are left out (the reading reports them
    missing). Empty when the SSD cannot be parsed."""
    try:
        if ssd.stat().st_size > limits.xml:
            return [], []
        root = etree.parse(str(ssd), _parser()).getroot()
    except (OSError, etree.XMLSyntaxError):
        return [], []
    xml_files: list[str] = []
    fmus: list[str] = []
    for element in root.iter(f"{{{NS['ssd']}}}*"):
        source = element.get("source")
        if not source or etree.QName(element).localname not in ("Component", "ParameterBinding",
                                                                 "ParameterMapping"):
            continue
        if reference_problem(source, climb):
            continue
        name = posixpath.normpath(source.replace("\\", "/"))
        (fmus if etree.QName(element).localname == "Component" else xml_files).append(name)
    return xml_files, fmus


_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*:")


def reference_problem(reference: str, climb: bool = False) -> str:
    """Why an SSD file reference (a component's FMU, a parameter file) may not be followed, '' when
    it may: a scenario references files inside itself only, never a URL, an absolute path (or a
    drive letter) or a path that climbs out with '..' (backslashes count as slashes); ``climb``:
    '..' allowed (a folder read with ``--root``, checked against the root)."""
    if _SCHEME.match(reference):
        return "is a URL or names a drive"
    if reference.startswith(("/", "\\")):
        return "is an absolute path"
    if not climb and ".." in reference.replace("\\", "/").split("/"):
        return "climbs out of the scenario with '..'"
    return ""


def _inside(folder: Path, reference: str, where: str, problems: list[str],
            root: Path | None = None) -> Path | None:
    """The file ``reference`` (from the SSD in ``folder``) names, when it lies inside ``folder``
    (also after following symbolic links), or inside ``root`` when one is given (``--root``: a
    folder scenario whose FMUs lie in a sibling folder); else None and one line in ``problems``
    naming ``where`` (the element) and the reference."""
    problem = reference_problem(reference, climb=root is not None)
    path = folder.joinpath(*PurePosixPath(reference.replace("\\", "/")).parts)
    within = (root or folder).resolve()
    if not problem and not path.resolve().is_relative_to(within):
        problem = f"leads outside the root {root}" if root is not None else (
            "leads outside the scenario through a symbolic link")
    if problem:
        allowed = f"files below the root {root}" if root is not None else (
            "files inside itself (a folder scenario may reference files below a folder named with --root)")
        problems.append(f"{where}: reference '{_shown(reference)}' {problem}; a scenario may only reference "
                        f"{allowed}")
        return None
    return path if root is None else Path(os.path.normpath(path))


@functools.cache
def _schema(name: str, version: str = "1.0") -> etree.XMLSchema:
    """The schema ``name`` of SSP ``version``: 2.0's from the standard, 1.0's as fmpy ships them
    (kept until :func:`scan_scenario` ends)."""
    folder = SSP2_SCHEMAS if version == "2.0" else Path(fmpy_ssd.__file__).parent / "schema"
    return etree.XMLSchema(file=str(folder / name))


def _load(path: Path, schema: str, label: str) -> tuple[etree._Element | None, list[str]]:
    """Parse one XML file and validate it against ``schema``; problems name ``label`` (the file)
    and the line. The root is None when the file is missing or not XML; a root that breaks the
    schema is still returned, so the checks after it can go on.

    A file of ``version="2.0"`` (SSP 2.0; OMSimulator writes its SSD, SSV and SSM files so) is
    validated against the SSP 2.0 schemas, any other against SSP 1.0's (whose pattern reports a
    version it does not know)."""
    if not path.is_file():
        return None, [f"{label}: file is missing"]
    try:
        root = etree.parse(str(path), _parser()).getroot()
    except etree.XMLSyntaxError as exc:
        return None, [f"{label}: broken XML: {_one_line(exc)}"]  # lxml's may span lines
    except (OSError, ValueError) as exc:  # lxml: undecodable bytes, unreadable file
        return None, [f"{label}: cannot be read: {_one_line(exc)}"]
    validator = _schema(schema, "2.0" if root.get("version") == "2.0" else "1.0")
    if validator.validate(root):
        return root, []
    return root, [f"{label} line {e.line}: {' '.join(e.message.split())}" for e in validator.error_log]


def _convert(type_: str, text: str | None) -> float | int | bool | str:
    """The Python value of an SSV value attribute; ValueError when it is not one of ``type_``."""
    if text is None:
        if type_ == "String":
            return ""
        raise ValueError(text)
    if type_ == "Real":
        return float(text)
    if type_ in ("Integer", "Enumeration"):
        return int(text)
    if type_ == "Boolean":
        if text not in ("true", "false", "1", "0"):
            raise ValueError(text)
        return text in ("true", "1")
    return text


def _parameter_set(element: etree._Element, origin: str, prefix: str,
                   problems: list[str], units: tuple[UnitDef, ...] = ()) -> ParameterSet:
    """The parameters of an ``ssv:ParameterSet`` element, stripping the binding's prefix from every
    name; parameters that cannot be used are left out and reported in ``problems``. The value
    element of SSP 2.0's FMI 3.0 types is set as its SSP 1.0 kind (``SSV_TYPES``: Float64 and
    Float32 as Real, the integer widths as Integer); the System checks the value against the FMU's
    variable."""
    parameters = []
    for p in element.findall("ssv:Parameters/ssv:Parameter", NS):
        name = p.get("name", "")
        value_element = next((v for v in p.findall("ssv:*", NS) if etree.QName(v).localname in SSV_TYPES),
                             None)
        type_ = SSV_TYPES[etree.QName(value_element).localname] if value_element is not None else None
        value = value_element.get("value") if value_element is not None else None
        if prefix:
            if not name.startswith(prefix):
                problems.append(f"{origin}: parameter '{name}' does not start with the prefix '{prefix}'")
                continue
            name = name[len(prefix):]
        if type_ is None or value_element is None:
            problems.append(f"{origin}: parameter '{name}' has no value element")
            continue
        unit = value_element.get("unit") if type_ == "Real" else None
        try:
            parameters.append(Parameter(name, type_, _convert(type_, value), unit))
        except ValueError:
            problems.append(f"{origin}: parameter '{name}': value {value!r} is not a valid {type_}")
    return ParameterSet(origin, tuple(parameters), units)


def _read_ssv(path: Path, label: str, origin: str, prefix: str) -> tuple[ParameterSet | None, list[str]]:
    """One ``.ssv`` file: the parameters that can be used (None when the file breaks its schema)
    and the problems."""
    root, problems = _load(path, "SystemStructureParameterValues.xsd", label)
    if root is None or problems:
        return None, problems
    units = tuple(read_units(root, "ssv:Units", NS).values())
    return _parameter_set(root, origin, prefix, problems, units), problems


def read_parameter_set(path: str | os.PathLike, prefix: str = "") -> ParameterSet:
    """Read and validate one ``.ssv`` file."""
    parameter_set, problems = scan_parameter_set(path, prefix)
    if parameter_set is None or problems:
        raise ScenarioError(problems)
    return parameter_set


def scan_parameter_set(path: str | os.PathLike, prefix: str = "") -> tuple[ParameterSet | None, list[str]]:
    """:func:`read_parameter_set` that returns its problems instead of raising: the parameters that
    can be used (None when the file cannot be read) and every problem."""
    path = Path(path)
    return _read_ssv(path, str(path), path.name, prefix)


@dataclass(frozen=True)
class Reading:
    """What could be read of a scenario, with every problem found on the way.

    ``structure`` is None when the SSD cannot be read at all. The checks that follow must treat
    two kinds of components as unknown: ``no_fmu``, whose FMU is missing or not an FMU, and
    ``partial``, some of whose parameter values could not be read (their start values are not all
    known). ``notes``: what was read in a way the file did not say exactly (connections written
    from an input to an output, system values that name nothing), reported as warnings."""

    structure: SystemStructure | None
    problems: tuple[str, ...] = ()
    no_fmu: frozenset[str] = frozenset()
    partial: frozenset[str] = frozenset()
    notes: tuple[str, ...] = ()


def read_scenario(folder: Path, label: str | None = None, root: Path | None = None) -> SystemStructure:
    """Read the SSD in ``folder``; ``label`` is how messages name the SSD (default: its path).
    Raises ScenarioError listing every problem."""
    reading = scan_scenario(folder, label, root=root)
    if reading.structure is None or reading.problems:
        raise ScenarioError(list(reading.problems))
    return reading.structure


def scan_scenario(folder: Path, label: str | None = None, fmu_dirs: Iterable[Path] = (),
                  root: Path | None = None) -> Reading:
    """:func:`read_scenario` that returns its problems instead of raising and reads as much as it
    can: an SSD that breaks the schema is still read (elements lacking what the schema requires
    are left out), a component keeps its connectors when its FMU or a parameter file is bad.
    An FMU missing from the folder is taken, by file name, from the first of ``fmu_dirs`` holding
    it (a scenario source folder run with the built FMUs). ``root``: a folder above ``folder``
    whose files the SSD may reference with '..' (``--root``; never for an archive).

    Nested systems are flattened here, once: a component of system ``sub`` is the component
    ``sub.<name>``, connections through system connectors become connections between the
    components at their ends (their transformations composed), and the parameter bindings of
    every system (SSV files, inline values, SSM mappings) become parameter sets of the
    components they reach, in the standard's precedence (see :class:`_SystemReader`).

    The schemas parsed for the reading (libxml2's memory, 0.9 MB for the SSD's) are let go at its
    end, for the FMUs loaded next to reuse: kept, 16 copies of example1 peaked 0.55 MB higher
    (48.1 against 47.5 MB, six runs each). Parsing them again for the next scenario takes 3 ms."""
    try:
        return _scan(folder, label or str(folder / SSD_NAME), tuple(fmu_dirs), root)
    finally:
        _schema.cache_clear()


def _scan(folder: Path, label: str, fmu_dirs: tuple[Path, ...], root: Path | None) -> Reading:
    """:func:`scan_scenario`, with the schemas it parses kept while it reads."""
    notes: list[str] = []
    root_element, problems = _load(folder / SSD_NAME, "SystemStructureDescription.xsd", label)
    if root_element is None or (system := root_element.find("ssd:System", NS)) is None:
        return Reading(None, tuple(problems), notes=tuple(notes))
    if root_element.get("version") not in VERSIONS:
        problems.append(f"{label}: version must be \"1.0\" or \"2.0\" (got {root_element.get('version')!r})")
    reader = _SystemReader(folder, label, problems, notes, fmu_dirs, root)
    reader.read(system, ())
    components, connections, values = reader.flatten()
    structure = SystemStructure(system.get("name", ""), components, connections,
                                _read_experiment(root_element, system, label, problems),
                                system.get("description", ""), label,
                                tuple(read_units(root_element, "ssd:Units", NS).values()), values)
    return Reading(structure, tuple(problems), frozenset(reader.no_fmu), frozenset(reader.partial),
                   tuple(notes))


@overload
def _number(text: str | None, default: float) -> float: ...
@overload
def _number(text: str | None, default: None) -> float | None: ...
def _number(text: str | None, default: float | None) -> float | None:
    """A double attribute; ``default`` when absent or not a number (the schema reports the latter)."""
    try:
        return default if text is None else float(text)
    except ValueError:
        return default


Node = tuple[tuple[str, ...], str]  # (path of a component or system below the root, connector name)


@dataclass(frozen=True)
class _Edge:
    """One ``ssd:Connection`` of some system, its ends as nodes."""

    start: Node
    end: Node
    factor: float
    offset: float
    system: tuple[str, ...]  # where it is declared
    suppress: bool = False  # suppressUnitConversion="true"


@dataclass
class _SystemInfo:
    """A system as read: its connectors and the kind of each element ("component" or "system")."""

    path: tuple[str, ...]
    name: str
    connectors: dict[str, Connector]
    elements: dict[str, str] = field(default_factory=dict)
    bindings: list[ParameterSet] = field(default_factory=list)


@dataclass(frozen=True)
class _Mapping:
    """One ``ssm:MappingEntry``: the target name, the transformation and how messages name it."""

    target: str
    origin: str
    factor: float = 1.0
    offset: float = 0.0
    table: tuple[tuple[str, str], ...] | None = None  # Boolean/Integer/EnumerationMappingTransformation
    linear: bool = False
    keep_unit: bool = True  # suppressUnitConversion="false"


def _flat(path: tuple[str, ...]) -> str:
    return ".".join(path)


def _name(node: Node) -> str:
    """A node as messages name it: ``sub.component.connector`` or ``sub.connector``."""
    return _flat((*node[0], node[1]))


def _proxied(reference: str) -> str | None:
    """The FMU file of a libcosim proxy FMU on this host (``proxyfmu://localhost?file=a.fmu``, the
    file relative to the SSD); None for another host or no file."""
    parts = urlsplit(reference)
    files_ = parse_qs(parts.query).get("file")
    if parts.hostname not in (None, "", "localhost", "127.0.0.1") or not files_:
        return None
    return files_[0]


class _SystemReader:
    """Reads a system and its nested systems into flat components, connections and parameter sets.

    Names: an element of a nested system ``sub`` is ``sub.<element>`` (the root system's own
    name left out, as for the components directly in it), so the columns read
    ``sub.<component>.<connector>``.

    Parameter bindings (SSP 1.0, ``TParameterBindings``): a component's bindings name its variables;
    a system's name the variables below it hierarchically (``<element>.<variable>``,
    ``<subsystem>.<element>.<variable>``, or one of its own connectors). A binding's ``prefix`` is
    stripped from the names of a component's binding (as before; the names must start with it)
    and prepended to those of a system's binding. A ParameterMapping renames a source parameter
    to its entries' targets, through their transformation; parameters it does not name keep their
    names. Precedence: later bindings of one element over earlier ones, and a system's over those
    of the systems and components inside it; ``--parameter-set`` and ``--set`` come after all.
    A value bound to a system connector applies to every component input or parameter the
    connector feeds (through the connections' transformations)."""

    def __init__(self, folder: Path, label: str, problems: list[str], notes: list[str],
                 fmu_dirs: tuple[Path, ...], root: Path | None) -> None:
        self.folder, self.label, self.problems, self.notes = folder, label, problems, notes
        self.fmu_dirs, self.root = fmu_dirs, root
        self.systems: dict[tuple[str, ...], _SystemInfo] = {}
        self.components: dict[tuple[str, ...], Component] = {}
        self.edges: list[_Edge] = []
        self.no_fmu: set[str] = set()
        self.partial: set[str] = set()

    # -- reading ----------------------------------------------------------------------------------
    def read(self, system: etree._Element, path: tuple[str, ...]) -> None:
        """Read ``system`` (at ``path`` below the root) and everything inside it."""
        where = f"{self.label}: system '{_flat(path) or system.get('name', '')}'"
        info = _SystemInfo(path, system.get("name", ""), _connectors(system, where, self.problems))
        self.systems[path] = info
        for element in system.findall("ssd:Elements/*", NS):
            kind, name = etree.QName(element).localname, element.get("name")
            if name is None or kind not in ("Component", "System", "SignalDictionaryReference"):
                continue  # the schema requires a name and has reported it
            if name in info.elements:
                self.problems.append(f"{where}: element name '{name}' is used twice")
                continue
            if kind == "SignalDictionaryReference":
                self.problems.append(f"{where}: signal dictionaries are not supported ('{name}')")
            elif kind == "System":
                info.elements[name] = "system"
                self.read(element, (*path, name))
            elif element.get("source") is not None:  # the schema requires it and has reported it
                info.elements[name] = "component"
                self._component(element, (*path, name))
        for element in system.findall("ssd:Connections/ssd:Connection", NS):
            self._connection(element, path, where)
        info.bindings = self._bindings(system, where, strip_prefix=False, path=path)

    def _component(self, element: etree._Element, path: tuple[str, ...]) -> None:
        """One component: its FMU, connectors and own parameter bindings."""
        name = _flat(path)
        where = f"{self.label}: component '{name}'"
        reference = element.get("source", "")
        inside = None
        if reference.startswith("proxyfmu:"):
            target = _proxied(reference)
            proxy = f"{where}: source '{_shown(reference)}' is a libcosim proxy FMU"
            if target is None:
                self.problems.append(f"{proxy} on another host (an FMU run in a separate process there): "
                                     "not supported")
            else:
                self.notes.append(f"{proxy} on this host: its FMU '{_shown(target)}' runs in this process "
                                  "(libcosim runs it in a separate one; the values are the same)")
                reference = target
        if inside is None and not reference.startswith("proxyfmu:"):
            inside = _inside(self.folder, reference, f"{where}: source", self.problems, self.root)
        source = self.folder / reference if inside is None else inside
        if inside is not None and not _fmu_file(source):
            source = next((d / source.name for d in self.fmu_dirs if (d / source.name).is_file()), source)
        has_fmu = False
        if inside is None:
            pass  # refused above
        elif element.get("type", "application/x-fmu-sharedlibrary") != "application/x-fmu-sharedlibrary":
            self.problems.append(f"{where}: only FMU components are supported (type {element.get('type')!r})")
        elif not _fmu_file(source):
            looked = [str(p) for p in (source.resolve(),
                                       *(d.resolve() / source.name for d in self.fmu_dirs))]
            places = "not in the archive" if self.label.endswith(f":{SSD_NAME}") else \
                f"looked for {', '.join(dict.fromkeys(looked))}"  # a folder: absolute paths
            self.problems.append(f"{where}: FMU '{reference}' is missing ({places})")
        else:
            has_fmu = True
        before = len(self.problems)
        sets = self._bindings(element, where, strip_prefix=True, path=path)
        if len(self.problems) > before:
            self.partial.add(name)
        if not has_fmu:
            self.no_fmu.add(name)
        self.components[path] = Component(name, source, tuple(_connectors(element, where, self.problems)
                                                              .values()), tuple(sets))

    def _connection(self, element: etree._Element, path: tuple[str, ...], where: str) -> None:
        ends = [element.get(a) for a in ("startElement", "startConnector", "endElement", "endConnector")]
        if ends[1] is None or ends[3] is None:
            return  # the schema requires both connectors and has reported it
        shown = f"{'.'.join(e for e in ends[:2] if e)} -> {'.'.join(e for e in ends[2:] if e)}"
        if element.get("startIndices") is not None or element.get("endIndices") is not None:
            self.problems.append(f"{where}: connection {shown} joins elements of array connectors "
                                 "(startIndices/endIndices, SSP 2.0): array connectors are not supported")
            return
        transformation = element.find("ssc:LinearTransformation", NS)
        if element.find("ssc:*", NS) is not None and transformation is None:
            self.problems.append(f"{where}: connection {shown} has a transformation other than "
                                 "LinearTransformation (not supported)")
        factor, offset = 1.0, 0.0
        if transformation is not None:
            factor = _number(transformation.get("factor"), 1.0)
            offset = _number(transformation.get("offset"), 0.0)
            if not (math.isfinite(factor) and math.isfinite(offset)):
                self.problems.append(f"{where}: connection {shown}: LinearTransformation factor={factor!r} "
                                     f"offset={offset!r} is not finite")
        start = ((*path, ends[0]) if ends[0] else path, ends[1])
        end = ((*path, ends[2]) if ends[2] else path, ends[3])
        suppress = element.get("suppressUnitConversion", "false").strip() in ("true", "1")
        self.edges.append(_Edge(start, end, factor, offset, path, suppress))

    def _bindings(self, element: etree._Element, where: str, strip_prefix: bool,
                  path: tuple[str, ...]) -> list[ParameterSet]:
        """The parameter sets an element's ParameterBindings give, in order: prefix and mapping
        applied (names relative to the element). Problems go to ``self.problems``."""
        found: list[ParameterSet] = []
        for binding in element.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
            prefix = binding.get("prefix", "")
            kind = binding.get("type", "application/x-ssp-parameter-set")
            if kind != "application/x-ssp-parameter-set":
                self.problems.append(f"{where}: ParameterBinding of type {kind!r}: only SSV parameter sets "
                                     "(application/x-ssp-parameter-set) are supported")
                continue
            sets: list[ParameterSet] = []
            if binding.get("source") is not None:
                origin = binding.get("source", "")
                file = _inside(self.folder, origin, f"{where}: ParameterBinding source", self.problems,
                               self.root)
                if file is not None:
                    ps, problems = _read_ssv(file, f"{self.label}: {origin}", origin,
                                             prefix if strip_prefix else "")
                    self.problems.extend(problems)
                    sets += [ps] if ps is not None else []
            for inline in binding.findall("ssd:ParameterValues/ssv:ParameterSet", NS):
                inline_problems: list[str] = []
                units = tuple(read_units(inline, "ssv:Units", NS).values())
                sets.append(_parameter_set(inline,
                                           f"{self.label} (inline values of '{_flat(path) or 'the system'}')",
                                           prefix if strip_prefix else "", inline_problems, units))
                self.problems.extend(inline_problems)
            mapping = self._mapping(binding, where)
            for ps in sets:
                if prefix and not strip_prefix:
                    ps = replace(ps, parameters=tuple(replace(p, name=prefix + p.name)
                                                      for p in ps.parameters))
                found.append(_mapped(ps, mapping, self.problems) if mapping else ps)
        return found

    def _mapping(self, binding: etree._Element, where: str) -> dict[str, list[_Mapping]]:
        """The binding's ParameterMapping (an .ssm file or inline): source name -> its entries."""
        element = binding.find("ssd:ParameterMapping", NS)
        if element is None:
            return {}
        if element.get("source") is not None:
            reference = element.get("source", "")
            file = _inside(self.folder, reference, f"{where}: ParameterMapping source", self.problems,
                           self.root)
            if file is None:
                return {}
            ssm, problems = _load(file, "SystemStructureParameterMapping.xsd", f"{self.label}: {reference}")
            self.problems.extend(problems)
            label = reference
        else:
            ssm = element.find("ssm:ParameterMapping", NS)
            label = f"{self.label} (inline mapping)"
        if ssm is None:
            return {}
        entries: dict[str, list[_Mapping]] = {}
        for entry in ssm.findall("ssm:MappingEntry", NS):
            source, target = entry.get("source"), entry.get("target")
            if source is None or target is None:
                continue  # the schema requires both and has reported it
            origin = f"{label}: MappingEntry '{source}' -> '{target}'"
            keep_unit = entry.get("suppressUnitConversion", "false") not in ("true", "1")
            linear = entry.find("ssc:LinearTransformation", NS)
            table = next((t for t in entry.findall("ssc:*", NS) if etree.QName(t).localname.endswith(
                "MappingTransformation")), None)
            if linear is not None:
                mapped = _Mapping(target, origin, _number(linear.get("factor"), 1.0),
                                  _number(linear.get("offset"), 0.0), None, True, keep_unit)
            elif table is not None:
                pairs = tuple((e.get("source", ""), e.get("target", ""))
                              for e in table.findall("ssc:MapEntry", NS))
                mapped = _Mapping(target, origin, table=pairs, keep_unit=keep_unit)
            else:
                mapped = _Mapping(target, origin, keep_unit=keep_unit)
            entries.setdefault(source, []).append(mapped)
        return entries

    # -- flattening -----------------------------------------------------------------------------
    def flatten(self) -> tuple[tuple[Component, ...], tuple[Connection, ...],
                               tuple[tuple[str, Parameter], ...]]:
        """The flat components (their parameter sets in precedence order), the connections between
        components, and the values bound to system connectors (``sub.connector``)."""
        reversed_ = [e for e in self.edges if (e.factor, e.offset) == (1.0, 0.0)
                     and (self._role(e.start, e.system), self._role(e.end, e.system)) == ("sink", "source")]
        if reversed_:
            example = reversed_[0]
            self.notes.append(f"{self.label}: {len(reversed_)} connection(s) written from an input to an "
                              f"output (e.g. {_name(example.start)} -> {_name(example.end)}) read the other "
                              "way round, as OMSimulator reads them")
            self.edges = [replace(e, start=e.end, end=e.start) if e in reversed_ else e for e in self.edges]
        into: dict[Node, _Edge] = {}
        for edge in self.edges:
            if edge.end[0] in self.systems:
                if edge.end in into:
                    first = into[edge.end].start
                    self.problems.append(f"{self.label}: system connector {_name(edge.end)} is connected "
                                         f"twice (from {_name(first)} and {_name(edge.start)})")
                    continue
                into[edge.end] = edge
        connections: list[Connection] = []
        feeds: dict[Node, list[tuple[PortRef, _Edge]]] = {}
        for edge in self.edges:
            if edge.end[0] in self.systems:
                continue  # reached through the chain from the component it ends at
            traced = self._trace(edge, into)
            if traced is None:
                continue
            start = traced.start
            end = PortRef(_flat(edge.end[0]), edge.end[1])
            if start[0] in self.systems:
                feeds.setdefault(start, []).append((end, traced))
            else:
                connections.append(Connection(PortRef(_flat(start[0]), start[1]), end, traced.factor,
                                              traced.offset, traced.suppress))
        sets: dict[tuple[str, ...], list[tuple[int, int, ParameterSet]]] = {}
        order = 0
        for path, component in self.components.items():
            for ps in component.parameter_sets:
                sets.setdefault(path, []).append((-len(path), order, ps))
                order += 1
        values: dict[str, Parameter] = {}
        for info in self.systems.values():
            for ps in info.bindings:
                order += 1
                self._bind(info, ps, into, feeds, sets, values, order)
        components = tuple(replace(c, parameter_sets=tuple(ps for *_, ps in sorted(sets.get(path, []),
                                                                                    key=lambda s: s[:2])))
                           for path, c in self.components.items())
        return components, tuple(connections), tuple(values.items())

    def _role(self, node: Node, system: tuple[str, ...]) -> str:
        """Whether a connection end declared in ``system`` gives a value ("source"), takes one
        ("sink"), or neither is known (""): a component's output or calculated parameter gives, its
        input or parameter takes; a system's own input or parameter connector gives inside it, a
        subsystem's takes."""
        path, name = node
        if path in self.components:
            kind = next((k.kind for k in self.components[path].connectors if k.name == name), "")
            own = False
        elif path in self.systems and name in self.systems[path].connectors:
            kind, own = self.systems[path].connectors[name].kind, path == system
        else:
            return ""
        gives = kind in ("output", "calculatedParameter")
        takes = kind in ("input", "parameter")
        if own:
            gives, takes = takes, gives
        return "source" if gives else "sink" if takes else ""

    def _trace(self, edge: _Edge, into: Mapping[Node, _Edge]) -> _Edge | None:
        """Where the value arriving over ``edge`` comes from: a component's connector (or an unknown
        element, which the system reports), or a system connector nothing feeds; as one edge with
        the composed transformation (suppressing unit conversion when any connection on the way
        does). None (and a problem) for a cycle through system connectors."""
        factor, offset, node, seen = edge.factor, edge.offset, edge.start, {edge.end}
        suppress = edge.suppress
        while node[0] in self.systems:
            if node in seen:
                self.problems.append(f"{self.label}: connections through system connector {_name(node)} form "
                                     "a cycle")
                return None
            seen.add(node)
            feeding = into.get(node)
            if feeding is None:
                break
            factor, offset = factor * feeding.factor, factor * feeding.offset + offset
            suppress = suppress or feeding.suppress
            node = feeding.start
        return _Edge(node, edge.end, factor, offset, edge.system, suppress)

    def _resolve(self, path: tuple[str, ...], name: str) -> Node | None:
        """A hierarchical name inside system ``path``: (component path, variable), (system path,
        connector) for a system connector, None when it names nothing (longest element name first:
        names may contain dots)."""
        info = self.systems[path]
        for element in sorted(info.elements, key=len, reverse=True):
            if name.startswith(element + ".") and len(name) > len(element) + 1:
                rest = name[len(element) + 1:]
                if info.elements[element] == "component":
                    return (*path, element), rest
                found = self._resolve((*path, element), rest)
                if found is not None:
                    return found
        return (path, name) if name in info.connectors else None

    def _bind(self, info: _SystemInfo, ps: ParameterSet, into: Mapping[Node, _Edge],
              feeds: Mapping[Node, list[tuple[PortRef, _Edge]]],
              sets: dict[tuple[str, ...], list[tuple[int, int, ParameterSet]]],
              values: dict[str, Parameter], order: int) -> None:
        """Distribute one system-level parameter set over the components (and system connectors)
        its names reach. A name that reaches nothing is ignored with a note, as SSP 1.0 says (a
        file written for a larger system), but an SSM entry's target that reaches nothing is an
        error. A value reaching a component through a system connector applies after every binding
        (a connection: OMSimulator too gives the connector's value at initialization)."""
        reached: dict[tuple[str, ...], list[Parameter]] = {}
        through: dict[tuple[str, ...], list[Parameter]] = {}
        system = f"system '{_flat(info.path) or info.name}'"
        for p in ps.parameters:
            origin = p.origin or ps.origin
            node = self._resolve(info.path, p.name)
            if node is None and p.origin is not None:
                self.problems.append(f"{origin}: the target '{p.name}' names no element or connector of "
                                     f"{system}")
                continue
            if node is None:
                self.notes.append(f"{origin}: '{p.name}' names no element or connector of {system}: ignored "
                                  "(SSP 1.0 ignores names that match nothing)")
                continue
            if node[0] in self.components:
                reached.setdefault(node[0], []).append(replace(p, name=node[1], origin=origin))
                continue
            name = _name(node)
            if node in into:
                source = into[node].start
                self.problems.append(f"{origin}: system connector {name} is fed by {_name(source)}: a value "
                                     "given for it would be overwritten")
                continue
            values[name] = replace(p, origin=origin)
            for port, edge in feeds.get(node, []):
                path = tuple(port.component.split(".")) if port.component else ()
                target = next((k for k, c in self.components.items() if c.name == port.component), path)
                via = f"{origin} (through system connector {name})"
                passed = _transformed(replace(p, name=port.connector, origin=via), edge.factor, edge.offset,
                                      edge.suppress)
                through.setdefault(target, []).append(passed)
        for rank, found in ((-len(info.path), reached), (1, through)):
            for path, parameters in found.items():
                sets.setdefault(path, []).append((rank, order, replace(ps, parameters=tuple(parameters))))


def _connectors(element: etree._Element, where: str, problems: list[str]) -> dict[str, Connector]:
    """The connectors an element (component or system) declares, by name. Of SSP 2.0's additions,
    two are refused, one line each naming the element and the connector: a structural parameter
    (it would change the FMU's structure, which an orchestrator of fixed FMUs cannot) and an array
    connector (``ssc:Dimension``; the masters exchange scalars)."""
    connectors: dict[str, Connector] = {}
    for c in element.findall("ssd:Connectors/ssd:Connector", NS):
        name, kind = c.get("name"), c.get("kind")
        if name is None or kind is None:
            continue  # the schema requires both and has reported it
        if name in connectors:
            problems.append(f"{where}: connector '{name}' is declared more than once")
            continue
        if kind == "structuralParameter":
            problems.append(f"{where}: connector '{name}' is a structural parameter (SSP 2.0): not supported "
                            "(the FMUs are run as they are built)")
            continue
        dimensions = c.findall("ssc:Dimension", NS)
        if dimensions:
            problems.append(f"{where}: connector '{name}' is an array ({len(dimensions)} ssc:Dimension): "
                            "array connectors are not supported (connect scalar variables)")
            continue
        type_ = next((t for t in TYPES if c.find(f"ssc:{t}", NS) is not None), None)
        typed = c.find(f"ssc:{type_}", NS)
        unit = typed.get("unit") if type_ in ("Real", "Float64", "Float32") and typed is not None else None
        interval = _number(typed.get("intervalDecimal"), None) if type_ == "Clock" and typed is not None \
            else None
        clocks = tuple(k.get("name", "") for k in c.findall("ssd:Clock", NS))
        connectors[name] = Connector(name, kind, type_, unit or None, clocks, interval)  # unit="": none
    return connectors


def _mapped(ps: ParameterSet, mapping: Mapping[str, list[_Mapping]], problems: list[str]) -> ParameterSet:
    """``ps`` through a ParameterMapping: each parameter a mapping entry names becomes one parameter
    per entry (its target, the value transformed); the others keep their names."""
    parameters: list[Parameter] = []
    for p in ps.parameters:
        for entry in mapping.get(p.name, [None]):
            if entry is None:
                parameters.append(p)
                continue
            value: float | int | bool | str = p.value
            if entry.linear:
                if p.type != "Real":
                    problems.append(f"{entry.origin}: a LinearTransformation applies to Real values "
                                    f"('{p.name}' is {p.type})")
                    continue
                mapped = replace(p, name=entry.target, origin=entry.origin)
                parameters.append(_transformed(mapped, entry.factor, entry.offset, not entry.keep_unit))
                continue
            if entry.table is not None:
                table = {_literal_of(p.type, s): t for s, t in entry.table}
                if _literal(p.value) not in table:
                    problems.append(f"{entry.origin}: value {_literal(p.value)} of '{p.name}' is not in the "
                                    f"mapping table ({', '.join(table)})")
                    continue
                try:
                    value = _convert(p.type, table[_literal(p.value)])
                except ValueError:
                    problems.append(f"{entry.origin}: mapped value {table[_literal(p.value)]!r} is not a "
                                    f"{p.type}")
                    continue
            unit = p.unit if entry.keep_unit else None
            parameters.append(Parameter(entry.target, p.type, value, unit, entry.origin))
    return replace(ps, parameters=tuple(parameters))


def _transformed(p: Parameter, factor: float, offset: float, suppress_units: bool) -> Parameter:
    """``p`` passed through a LinearTransformation (of an SSM entry or a connection). A Real value in a
    unit of its own keeps it and the transformation waits in ``transform``, so that the System
    converts the value to the variable's unit first (SSP 1.0.1, 5.3.2); with ``suppress_units`` or
    no unit the transformation applies now (and the result is in the variable's unit)."""
    if p.type != "Real" or (factor, offset) == (1.0, 0.0):
        return replace(p, unit=None) if suppress_units else p
    if p.unit is not None and not suppress_units:
        before = p.transform or (1.0, 0.0)
        return replace(p, transform=(factor * before[0], factor * before[1] + offset))
    value = float(p.value)
    if p.transform is not None:
        value = p.transform[0] * value + p.transform[1]
    return replace(p, value=factor * value + offset, unit=None, transform=None)


def _literal_of(type_: str, text: str) -> str:
    """A MapEntry's value in the form :func:`_literal` writes values (``1`` -> ``true`` for a Boolean)."""
    try:
        return _literal(_convert(type_, text))
    except ValueError:
        return text


def _read_experiment(root: etree._Element, system: etree._Element, label: str,
                     problems: list[str]) -> Experiment:
    """Start/stop from DefaultExperiment; the step and the algorithm from libcosim's or OMSimulator's
    annotation (the step: libcosim's first when both are there). A value that is not a finite
    number is a problem (and left at its default).

    libcosim's ``osp:FixedStepAlgorithm`` is its fixed-step algorithm, which the ``jacobi`` master
    reproduces (every connection one step late); OMSimulator's ``oms:FixedStepMaster`` (``oms-ma``)
    steps every FMU and then updates the inputs in dependency order at the new time, as
    ``gauss-seidel`` does. A file with both was written for both tools (``write_ssd`` writes both,
    so that each reads the step): it names no one algorithm, and gets the default, gauss-seidel.
    The ``relativeTolerance`` of OMSimulator's annotation is the tolerance OMSimulator passes every
    FMU in ``fmi2SetupExperiment`` (``toleranceDefined``), which an FMU with its own variable-step
    solver (Dymola's) integrates with: it must be a positive finite number."""
    experiment = root.find("ssd:DefaultExperiment", NS)
    start, stop, step, tolerance = 0.0, None, None, None
    algorithm, algorithm_from = None, ""

    def finite(element: etree._Element, attribute: str, default: float | None) -> float | None:
        text = element.get(attribute)
        value = _number(text, None)
        if text is None:
            return default
        if value is None or not math.isfinite(value):
            problems.append(f"{label}: {etree.QName(element).localname} {attribute}={text!r} is not a finite "
                            "number")
            return default
        return value

    if experiment is not None:
        start_time = finite(experiment, "startTime", 0.0)
        assert start_time is not None  # the default is returned when the attribute is bad or missing
        start = start_time
        stop = finite(experiment, "stopTime", None)
        osp = experiment.find(f"ssd:Annotations/ssc:Annotation[@type='{OSP_ANNOTATION}']"
                              "/osp:Algorithm/osp:FixedStepAlgorithm", NS)
        if osp is not None:
            step = finite(osp, "baseStepSize", None)
            algorithm, algorithm_from = "jacobi", (f"{label}: libcosim's osp:FixedStepAlgorithm in the "
                                                   "DefaultExperiment (every connection one step late)")
    oms = system.find(f"ssd:Annotations/ssc:Annotation[@type='{OMS_ANNOTATION}']"
                      "/oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", NS)
    if oms is not None:  # read (and checked) also when libcosim's annotation gives the step
        oms_step = finite(oms, "stepSize", None)
        step = oms_step if step is None else step
        tolerance = finite(oms, "relativeTolerance", None)
        if tolerance is not None and tolerance <= 0:
            problems.append(f"{label}: FixedStepMaster relativeTolerance={oms.get('relativeTolerance')!r} is "
                            "not a positive number")
            tolerance = None
        algorithm, algorithm_from = "gauss-seidel", (
            f"{label}: OMSimulator's oms:FixedStepMaster in the System (all FMUs step, then inputs are "
            "updated in dependency order at the new time)" if algorithm is None else
            f"{label}: both libcosim's osp:FixedStepAlgorithm and OMSimulator's oms:FixedStepMaster (a file "
            "written for both tools, as orchestrate writes its own): the default, OMSimulator's")
    return Experiment(start, stop, step, algorithm, algorithm_from, tolerance)


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
        parameter = _element(parameters, "ssv:Parameter", name=p.name)
        value = _element(parameter, f"ssv:{p.type}", value=_literal(p.value))
        if p.unit is not None:
            value.set("unit", p.unit)
    _write(root, path)
    return path


def _version(structure: SystemStructure) -> str:
    """The SSP version a structure is written as: "1.0" (what every tool reads), or "2.0" when a
    connector needs it (an FMI 3.0 type such as Float64 or Clock, a clock association)."""
    needs_2 = any(k.type not in (*TYPES[:6], None) or k.clocks or k.interval is not None
                  for c in structure.components for k in c.connectors)
    return "2.0" if needs_2 else "1.0"


def write_ssd(folder: str | os.PathLike, structure: SystemStructure) -> Path:
    """Write ``folder/SystemStructure.ssd`` and the ``.ssv`` file of every parameter set bound by a
    component (file named by its ``origin``); returns the SSD's path.

    Every ``.ssv`` carries the system's name as its set name: one named parameter set spread over
    one file per component, because libcosim applies only a component's first binding and Ecos
    applies one named set (the union of the files carrying that name)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    nsmap = {prefix: NS[prefix] for prefix in ("ssd", "ssc", "ssv", "osp", "oms")}
    root = _element(None, "ssd:SystemStructureDescription", nsmap, version=_version(structure),
                    name=structure.name)
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
                typed = _element(connector, f"ssc:{k.type}")
                if k.unit is not None:
                    typed.set("unit", k.unit)
                if k.interval is not None:
                    typed.set("intervalDecimal", repr(k.interval))
            for clock in k.clocks:
                _element(connector, "ssd:Clock", name=clock)
        if c.parameter_sets:
            bindings = _element(element, "ssd:ParameterBindings")
            for ps in c.parameter_sets:
                write_ssv(folder / ps.origin, ps, structure.name)
                _element(bindings, "ssd:ParameterBinding", source=ps.origin)
    # SSP's schema wants at least one Connection inside Connections: none, no element.
    connections = _element(system, "ssd:Connections") if structure.connections else None
    for link in structure.connections:
        connection = _element(connections, "ssd:Connection", startElement=link.start.component,
                              startConnector=link.start.connector, endElement=link.end.component,
                              endConnector=link.end.connector)
        if link.suppress_units:
            connection.set("suppressUnitConversion", "true")
        if link.transformed:
            _element(connection, "ssc:LinearTransformation", factor=repr(link.factor),
                     offset=repr(link.offset))
    ex = structure.experiment
    if ex.step is not None:
        annotation = _element(_element(system, "ssd:Annotations"), "ssc:Annotation", type=OMS_ANNOTATION)
        information = _element(_element(annotation, "oms:Annotations"), "oms:SimulationInformation")
        _element(information, "oms:FixedStepMaster", description="oms-ma", stepSize=repr(ex.step))
    experiment = _element(root, "ssd:DefaultExperiment", startTime=repr(ex.start_time))
    if ex.stop_time is not None:
        experiment.set("stopTime", repr(ex.stop_time))
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
    placed under ``resources/`` (stored, not compressed again); written to a temporary name first so
    a failed build leaves no half-written archive. The same files give the same bytes: members in
    sorted order, with a fixed date and mode (not the files' modification times)."""
    source, target = Path(folder), Path(dest)
    members = [(path.relative_to(source).as_posix(), path) for path in sorted(source.rglob("*"))
               if path.is_file() and not path.name.startswith(".")]
    members += [(f"resources/{name}", Path(fmu)) for name, fmu in sorted(fmus.items())]
    with files.replacing(target) as partial, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, path in members:
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            # an FMU is a zip of compressed members already: stored, it unpacks at the cost of a copy
            info.compress_type = zipfile.ZIP_STORED if name.endswith(".fmu") else zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with path.open("rb") as src, zf.open(info, "w") as dst:
                shutil.copyfileobj(src, dst, 1 << 20)
    return target
