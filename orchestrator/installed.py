# SPDX-License-Identifier: BSD-2-Clause
"""What is installed: the version of a distribution and the entry points of a group, read from the
``.dist-info`` folders on ``sys.path`` as ``importlib.metadata`` reads them, without importing it.

Every ``orchestrate run`` asks both (the applications' checks, the versions in the result's
provenance). ``importlib.metadata`` imports ``email`` (with ``socket``, ``calendar`` ...) to parse
each distribution's ``METADATA`` for its version: 2.0 MB of a run's peak RSS (16 copies of
example1: 50.9 against 49.0 MB) and ~25 ms of its start-up. The PyPA's specification of
installed projects names the folder ``{name}-{version}.dist-info`` and writes ``entry_points.txt``
in configparser's INI form; this module reads those two and nothing else. As ``importlib.metadata``
does, the first folder of a distribution on ``sys.path`` wins. ``.egg-info`` installations (not
made by pip since 23.1) are not seen; ``tests/test_installed.py`` compares every distribution of
the environment with ``importlib.metadata``.
"""

from __future__ import annotations

import configparser
import importlib
import os
import re
import sys
from typing import Any, NamedTuple

__all__ = ["EntryPoint", "entry_points", "version"]


class EntryPoint(NamedTuple):
    """One entry point: ``value`` is ``module`` or ``module:attribute.path``."""

    name: str
    value: str
    group: str

    def load(self) -> Any:  # noqa: ANN401 - whatever the entry point names, as importlib.metadata's
        """The object the entry point names (imports its module)."""
        module, _, attribute = self.value.partition(":")
        found: Any = importlib.import_module(module.strip())
        for part in attribute.strip().split(".") if attribute.strip() else ():
            found = getattr(found, part)
        return found


def _normalized(name: str) -> str:
    """A distribution name as PEP 503 compares them (``Fixed_Time.cosim`` is ``fixed-time-cosim``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _distributions() -> dict[str, tuple[str, str]]:
    """Normalized name -> (version, dist-info folder) of every distribution on ``sys.path``, the
    first of a name winning."""
    found: dict[str, tuple[str, str]] = {}
    for entry in sys.path:
        try:
            names = sorted(os.listdir(entry or "."))
        except OSError:  # a zip, a missing folder
            continue
        for folder in names:
            if folder.endswith(".dist-info"):
                name, _, ver = folder[: -len(".dist-info")].partition("-")
                if ver:
                    found.setdefault(_normalized(name), (ver, os.path.join(entry or ".", folder)))
    return found


def version(name: str) -> str | None:
    """The installed version of distribution ``name``; None when it is not installed."""
    found = _distributions().get(_normalized(name))
    return found[0] if found else None


def entry_points(group: str) -> list[EntryPoint]:
    """The entry points of ``group`` of every installed distribution, sorted by name."""
    points = []
    for _, folder in _distributions().values():
        parser = configparser.ConfigParser(delimiters=("=",), interpolation=None)
        parser.optionxform = str  # type: ignore[assignment,method-assign]  # names keep their case
        try:
            parser.read(os.path.join(folder, "entry_points.txt"), encoding="utf-8")
        except (configparser.Error, UnicodeDecodeError):
            continue  # a damaged file of one distribution: the others' entry points still count
        if parser.has_section(group):
            points += [EntryPoint(name, value, group) for name, value in parser.items(group)]
    return sorted(points)
