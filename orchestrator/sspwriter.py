"""Write SSP 1.0 files the way every tool reads them (SPEC section 7).

Literal ``ssd:``/``ssc:``/``ssv:`` prefixes, ``version="1.0"``, every connector declared with its
causality and type, parameter bindings on components (one ``.ssv`` each: libcosim applies only the
first binding of a component), the communication step both where libcosim reads it
(``osp:FixedStepAlgorithm baseStepSize``) and where OMSimulator does (``oms:FixedStepMaster
stepSize``), with the tool namespaces declared on the root element.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .ssp import NS, OMS_ANNOTATION, OSP_ANNOTATION, SSD_NAME

__all__ = ["ComponentSpec", "ConnectionSpec", "pack_ssp", "write_ssd", "write_ssv"]


@dataclass(frozen=True)
class ComponentSpec:
    """A component: FMU file name under ``resources/``, its connectors ``(name, kind, type)`` and the
    parameter values written to ``<name>.ssv`` (none: no binding)."""

    name: str
    fmu: str
    connectors: Sequence[tuple[str, str, str]]
    parameters: Mapping[str, float | int | bool] = field(default_factory=dict)


@dataclass(frozen=True)
class ConnectionSpec:
    """``"component.connector"`` -> ``"component.connector"``, optionally ``factor * x + offset``."""

    start: str
    end: str
    factor: float | None = None
    offset: float | None = None


def _type_of(value: float | int | bool) -> str:
    if isinstance(value, bool):
        return "Boolean"
    if isinstance(value, int):
        return "Integer"
    return "Real"


def _literal(value: float | int | bool) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else repr(value)


def write_ssv(path: str | os.PathLike, name: str, parameters: Mapping[str, float | int | bool]) -> None:
    """Write a parameter set; names are written as given (no prefix)."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<ssv:ParameterSet xmlns:ssv="{NS["ssv"]}" version="1.0" name={quoteattr(name)}>',
             "  <ssv:Parameters>"]
    for key, value in parameters.items():
        lines += [f"    <ssv:Parameter name={quoteattr(key)}>",
                  f'      <ssv:{_type_of(value)} value="{_literal(value)}"/>',
                  "    </ssv:Parameter>"]
    lines += ["  </ssv:Parameters>", "</ssv:ParameterSet>", ""]
    Path(path).write_text("\n".join(lines), encoding="utf-8")


def write_ssd(folder: str | os.PathLike, name: str, components: Iterable[ComponentSpec],
              connections: Iterable[ConnectionSpec], start_time: float, stop_time: float, step: float,
              description: str = "") -> None:
    """Write ``folder/SystemStructure.ssd`` and one ``<component>.ssv`` per component with parameters."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<ssd:SystemStructureDescription xmlns:ssd="{NS["ssd"]}" xmlns:ssc="{NS["ssc"]}"',
           f'    xmlns:ssv="{NS["ssv"]}" xmlns:osp="{NS["osp"]}"',
           f'    xmlns:oms="{NS["oms"]}" version="1.0" name={quoteattr(name)}>',
           f"  <ssd:System name={quoteattr(name)} description={quoteattr(description)}>",
           "    <ssd:Elements>"]
    for c in components:
        out.append(f'      <ssd:Component name={quoteattr(c.name)} type="application/x-fmu-sharedlibrary" '
                   f'source="resources/{c.fmu}">')
        out.append("        <ssd:Connectors>")
        for connector, kind, type_ in c.connectors:
            out.append(f'          <ssd:Connector name={quoteattr(connector)} kind="{kind}"><ssc:{type_}/>'
                       "</ssd:Connector>")
        out.append("        </ssd:Connectors>")
        if c.parameters:
            write_ssv(folder / f"{c.name}.ssv", c.name, c.parameters)
            out += ["        <ssd:ParameterBindings>",
                    f'          <ssd:ParameterBinding source="{c.name}.ssv"/>',
                    "        </ssd:ParameterBindings>"]
        out.append("      </ssd:Component>")
    out += ["    </ssd:Elements>", "    <ssd:Connections>"]
    for k in connections:
        (se, sc), (ee, ec) = k.start.split(".", 1), k.end.split(".", 1)
        head = (f'      <ssd:Connection startElement="{se}" startConnector="{sc}" '
                f'endElement="{ee}" endConnector="{ec}"')
        if k.factor is None and k.offset is None:
            out.append(head + "/>")
        else:
            out += [head + ">",
                    f'        <ssc:LinearTransformation factor="{1.0 if k.factor is None else k.factor!r}" '
                    f'offset="{0.0 if k.offset is None else k.offset!r}"/>',
                    "      </ssd:Connection>"]
    out += ["    </ssd:Connections>",
            "    <ssd:Annotations>",
            f'      <ssc:Annotation type="{OMS_ANNOTATION}">',
            "        <oms:Annotations>",
            "          <oms:SimulationInformation>",
            f'            <oms:FixedStepMaster description="oms-ma" stepSize="{step!r}"/>',
            "          </oms:SimulationInformation>",
            "        </oms:Annotations>",
            "      </ssc:Annotation>",
            "    </ssd:Annotations>",
            "  </ssd:System>",
            f'  <ssd:DefaultExperiment startTime="{start_time!r}" stopTime="{stop_time!r}">',
            "    <ssd:Annotations>",
            f'      <ssc:Annotation type="{OSP_ANNOTATION}">',
            "        <osp:Algorithm>",
            f'          <osp:FixedStepAlgorithm baseStepSize="{step!r}" numWorkerThreads="0"/>',
            "        </osp:Algorithm>",
            "      </ssc:Annotation>",
            "    </ssd:Annotations>",
            "  </ssd:DefaultExperiment>",
            "</ssd:SystemStructureDescription>",
            ""]
    (folder / SSD_NAME).write_text("\n".join(out), encoding="utf-8")


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
