# SPDX-License-Identifier: BSD-2-Clause
"""Shell completion of ``orchestrate`` (bash, zsh, fish), by argcomplete.

argcomplete completes from the command's own argparse parser, so subcommands, options and their
choices never drift from what ``orchestrate`` accepts. The shell runs ``orchestrate`` with
``_ARGCOMPLETE`` set (the function ``orchestrate completion SHELL`` prints); :func:`complete` then
answers and exits before anything runs. Argcomplete is imported only then: other commands start
no slower. Beyond argparse's own, it completes:

* SCENARIO: the built scenarios' names (``build/ssp/NAME.ssp``), ``.ssp`` files and folders;
* ``--set`` and ``--expose``: ``COMPONENT.VARIABLE=`` for every parameter and input of the
  scenario already on the line, read from its SSD and the FMUs' ``modelDescription.xml`` inside
  the archive (nothing is unpacked or instantiated: about 0.1 s for example1);
* ``--plot-variables``, ``--output-variables``, ``--signal``: ``COMPONENT.VARIABLE`` of its
  inputs and outputs (result columns).

Usage: ``eval "$(orchestrate completion bash)"`` (see docs/shell-completion.md).
"""

from __future__ import annotations

import argparse
import os
import zipfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import IO

from lxml import etree

from .locate import built_scenarios, fmu_dirs
from .ssp import DEFAULT_LIMITS, NS, SSD_NAME

__all__ = ["complete", "scenario_names", "shellcode", "variables"]
SCENARIO_DESTS = ("scenario", "scenarios")
SETTABLE = ("parameter", "input")
SIGNALS = ("input", "output")


def shellcode(shell: str) -> str:
    """The script that makes ``shell`` complete ``orchestrate`` (argcomplete's, for this command)."""
    import argcomplete

    return argcomplete.shellcode(["orchestrate"], shell=shell)


def scenario_names(prefix: str) -> list[str]:
    """What SCENARIO may be: built scenario names, then ``.ssp`` files and folders matching ``prefix``."""
    names = [n for n in built_scenarios() if n.startswith(prefix)]
    folder, _, start = prefix.rpartition("/")
    base = Path(folder or ".")
    try:
        entries = sorted(os.scandir(base), key=lambda e: e.name)
    except OSError:
        entries = []
    for entry in entries:
        if not entry.name.startswith(start) or (entry.name.startswith(".") and not start.startswith(".")):
            continue
        shown = f"{folder}/{entry.name}" if folder else entry.name
        if entry.is_dir():
            names.append(shown + "/")
        elif entry.name.endswith(".ssp"):
            names.append(shown)
    return names


@contextmanager
def _opener(scenario: Path) -> Iterator[Callable[[str], IO[bytes] | None]]:
    """``open(member)`` for the files of a scenario archive or folder (None: not there); a folder's
    missing FMUs are looked up where ``run`` looks (:func:`~orchestrator.locate.fmu_dirs`)."""
    with ExitStack() as stack:
        if scenario.is_file():
            archive = stack.enter_context(zipfile.ZipFile(scenario))
            names = set(archive.namelist())

            def member(name: str) -> IO[bytes] | None:
                return stack.enter_context(archive.open(name)) if name in names else None
        else:
            dirs = [scenario, *fmu_dirs(scenario)]

            def member(name: str) -> IO[bytes] | None:
                for d in dirs:
                    path = d / name if d == scenario else d / Path(name).name
                    if path.is_file():
                        return stack.enter_context(open(path, "rb"))
                return None
        yield member


def _xml(stream: IO[bytes]) -> etree._Element:
    """A bounded, safe parse (no entities, no network), as the scenario's checks read XML."""
    data = stream.read(DEFAULT_LIMITS.xml + 1)
    if len(data) > DEFAULT_LIMITS.xml:
        raise ValueError("too large")
    return etree.fromstring(data, etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False))


def variables(scenario: str | os.PathLike, causalities: Iterable[str] = SETTABLE) -> list[str]:
    """``COMPONENT.VARIABLE`` of every variable of ``causalities`` of each component of
    ``scenario`` (a path or built name), from the SSD and each FMU's model description; [] when
    they cannot be read (completion never fails loudly)."""
    from .locate import resolve_scenario

    wanted = set(causalities)
    found: list[str] = []
    try:
        path = resolve_scenario(scenario)
        with _opener(path) as member:
            ssd = member(SSD_NAME)
            if ssd is None:
                return []
            for component in _xml(ssd).iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
                name, source = component.get("name"), component.get("source")
                fmu = member(source) if name and source else None
                if fmu is None:
                    continue
                with zipfile.ZipFile(fmu) as inner, inner.open("modelDescription.xml") as md:
                    root = _xml(md)
                holder = root.find("ModelVariables")
                for v in holder if holder is not None else ():
                    if isinstance(v.tag, str) and v.get("causality") in wanted and v.get("name"):
                        found.append(f"{name}.{v.get('name')}")
    except Exception:  # noqa: BLE001 - a scenario that cannot be read: what was found, never a traceback
        return found
    return found


def _scenario_of(parsed: argparse.Namespace) -> str | None:
    scenario = getattr(parsed, "scenario", None)
    if scenario is None:
        scenarios = getattr(parsed, "scenarios", None) or []
        scenario = scenarios[0] if scenarios else None
    return scenario if isinstance(scenario, str) else None


def _settable(prefix: str, parsed_args: argparse.Namespace, **_: object) -> list[str]:
    scenario = _scenario_of(parsed_args)
    return [] if scenario is None else [f"{v}=" for v in variables(scenario) if v.startswith(prefix)]


def _signals(prefix: str, parsed_args: argparse.Namespace, **_: object) -> list[str]:
    scenario = _scenario_of(parsed_args)
    return [] if scenario is None else [v for v in variables(scenario, SIGNALS) if v.startswith(prefix)]


def _scenarios(prefix: str, **_: object) -> list[str]:
    return scenario_names(prefix)


COMPLETERS: dict[str, Callable[..., list[str]]] = {
    "--set": _settable, "--expose": _settable, "--plot-variables": _signals, "--output-variables": _signals,
    "--signal": _signals}


def _subparsers(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):
                yield from _subparsers(sub)


def complete(parser: argparse.ArgumentParser) -> None:
    """Answer the shell's completion request (``_ARGCOMPLETE`` set) and exit; returns at once
    otherwise (argcomplete's contract)."""
    import argcomplete

    for p in _subparsers(parser):
        for action in p._actions:
            if action.dest in SCENARIO_DESTS and not action.option_strings:
                action.completer = _scenarios  # type: ignore[attr-defined]
            for option in action.option_strings:
                if option in COMPLETERS:
                    action.completer = COMPLETERS[option]  # type: ignore[attr-defined]
    argcomplete.autocomplete(parser)
