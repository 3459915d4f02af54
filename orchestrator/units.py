# SPDX-License-Identifier: BSD-2-Clause
"""Units of values and connectors: SSP 1.0 ``ssc:Unit`` / SSV ``unit`` / FMI 2.0 ``UnitDefinitions``.

A unit is what FMI 2.0 and SSP 1.0 both define: exponents of the SI base units (kg, m, s, A, K,
mol, cd) and rad, with ``value_SI = factor * value + offset``. A value given in one unit is
converted to another when both have the same exponents; different exponents (ms -> m) are an
error. Names are resolved from the definitions in the files (FMU ``UnitDefinitions``, SSD and SSV
``Units``) first, then from :data:`KNOWN`, the common names. A variable without a unit is
dimensionless, and so is the unit ``"1"``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

from lxml import etree

__all__ = ["BASE", "KNOWN", "UnitDef", "UnitError", "conversion", "convert", "read_units", "split_value"]

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


class UnitError(ValueError):
    """A unit that is unknown, or a conversion between units of different dimensions."""


@dataclass(frozen=True)
class UnitDef:
    """``value_SI = factor * value + offset`` in the SI base units with ``exponents`` (BASE order)."""

    name: str
    exponents: tuple[int, ...] = (0,) * len(BASE)
    factor: float = 1.0
    offset: float = 0.0

    def dimension(self) -> str:
        """The base units, e.g. ``m.s-2`` (``1`` when dimensionless)."""
        parts = [f"{b}{'' if e == 1 else e}" for b, e in zip(BASE, self.exponents, strict=True) if e]
        return ".".join(parts) or "1"


def _unit(name: str, factor: float = 1.0, offset: float = 0.0, **exponents: int) -> UnitDef:
    return UnitDef(name, tuple(exponents.get(b, 0) for b in BASE), factor, offset)


KNOWN: dict[str, UnitDef] = {u.name: u for u in (
    _unit("1"), _unit("%", 0.01),
    _unit("s", s=1), _unit("ms", 1e-3, s=1), _unit("us", 1e-6, s=1), _unit("ns", 1e-9, s=1),
    _unit("min", 60.0, s=1), _unit("h", 3600.0, s=1),
    _unit("1/s", s=-1), _unit("Hz", s=-1), _unit("1/s2", s=-2),
    _unit("rad", rad=1), _unit("deg", math.pi / 180, rad=1), _unit("mrad", 1e-3, rad=1),
    _unit("rad/s", rad=1, s=-1), _unit("deg/s", math.pi / 180, rad=1, s=-1),
    _unit("rpm", 2 * math.pi / 60, rad=1, s=-1), _unit("rad/s2", rad=1, s=-2),
    _unit("deg/s2", math.pi / 180, rad=1, s=-2),
    _unit("m", m=1), _unit("mm", 1e-3, m=1), _unit("cm", 1e-2, m=1), _unit("km", 1e3, m=1),
    _unit("m/s", m=1, s=-1), _unit("km/h", 1 / 3.6, m=1, s=-1), _unit("m/s2", m=1, s=-2),
    _unit("kg", kg=1), _unit("g", 1e-3, kg=1),
    _unit("N", kg=1, m=1, s=-2), _unit("N.m", kg=1, m=2, s=-2), _unit("Nm", kg=1, m=2, s=-2),
    _unit("kg.m2", kg=1, m=2), _unit("N.m.s/rad", kg=1, m=2, s=-1, rad=-1),
    _unit("A", A=1), _unit("V", kg=1, m=2, s=-3, A=-1), _unit("W", kg=1, m=2, s=-3),
    _unit("K", K=1), _unit("degC", 1.0, 273.15, K=1),
)}


def read_units(root: etree._Element, path: str, namespaces: Mapping[str, str]) -> dict[str, UnitDef]:
    """The ``ssc:Unit`` definitions under ``path`` (e.g. ``ssd:Units``) of an SSD or SSV root."""
    found = {}
    for u in root.findall(f"{path}/ssc:Unit", namespaces):
        base = u.find("ssc:BaseUnit", namespaces)
        if u.get("name") is None or base is None:
            continue  # the schema requires both and has reported it
        found[u.get("name")] = UnitDef(u.get("name"), tuple(int(base.get(b, 0)) for b in BASE),
                                       float(base.get("factor", 1.0)), float(base.get("offset", 0.0)))
    return found


def resolve(name: str | None, *definitions: Mapping[str, UnitDef]) -> UnitDef:
    """The definition of unit ``name`` (None or '': dimensionless), the first of ``definitions``
    that has it, else :data:`KNOWN`; UnitError when unknown."""
    if not name:
        return KNOWN["1"]
    for table in (*definitions, KNOWN):
        if name in table:
            return table[name]
    raise UnitError(f"unknown unit '{name}' (define it in the file's Units, or use one of "
                    f"{', '.join(sorted(KNOWN))})")


def conversion(source: UnitDef, target: UnitDef) -> tuple[float, float]:
    """``(factor, offset)`` with ``value_target = factor * value_source + offset``; UnitError when
    the dimensions differ."""
    if source.exponents != target.exponents:
        raise UnitError(f"{source.name} ({source.dimension()}) cannot be converted to {target.name} "
                        f"({target.dimension()})")
    return source.factor / target.factor, (source.offset - target.offset) / target.factor


def convert(value: float, source: UnitDef, target: UnitDef) -> float:
    """``value`` in ``source`` expressed in ``target`` (UnitError when the dimensions differ)."""
    factor, offset = conversion(source, target)
    return value if (factor, offset) == (1.0, 0.0) else factor * value + offset


_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)"
                          r"(?:\s+(\S+)|([^\s\d.+-]\S*))?\s*$")


def split_value(text: str) -> tuple[str, str | None]:
    """``"8000ms"`` or ``"8000 ms"`` -> ``("8000", "ms")``; a value without a unit -> ``(text, None)``."""
    match = _NUMBER_UNIT.match(text)
    unit = None if match is None else match.group(2) or match.group(3)
    return (text, None) if match is None or unit is None else (match.group(1), unit)
