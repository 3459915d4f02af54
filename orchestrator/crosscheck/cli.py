# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate crosscheck``: the conformance matrix of the built scenarios in every SSP tool."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..cli import add_command, add_output, quiet, resolve_scenario
from ..errors import ScenarioError, UsageError
from . import TOOLS, select_tools
from .matrix import COLUMN, run_matrix, signals_of, write_csv, write_markdown
from .tools import Scenario

__all__ = ["DEFAULT_OUTPUT", "register"]

DEFAULT_OUTPUT = Path("results") / "crosscheck"
BUILT = Path("build") / "ssp"

DESCRIPTION = """\
Run every scenario, unchanged, in every installed SSP tool and in both of our masters, and write
the conformance matrix (matrix.md, matrix.csv). Each tool is compared with our master of the same
semantics: jacobi for delayed (Jacobi-like) masters, gauss-seidel for delay-free ones, on plant.y
(--signal chooses others; a scenario without plant.y: every output it declares). A scenario must
be an .ssp archive with a stop time and a step annotation (what the other tools read).

exit status: 0 every cell ok (tools not installed are listed, not failed), 1 a red cell,
2 usage error.
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``crosscheck`` to ``orchestrate``."""
    p = add_command(sub, "crosscheck", _crosscheck,
                    help="run the scenarios in other SSP tools: conformance matrix", description=DESCRIPTION,
                    quiet=True, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                   help=f"built scenario names or .ssp files (default: every {BUILT}/*.ssp)")
    p.add_argument("--tools", nargs="+", choices=list(TOOLS), metavar="TOOL",
                   help=f"tools to run (default: all installed; choose from {', '.join(TOOLS)})")
    p.add_argument("--signal", action="append", default=[], metavar="COMPONENT.OUTPUT",
                   help=f"output compared with ours (repeatable; default: {COLUMN}, or every output of a "
                        f"scenario without it)")
    add_output(p, "DIR", f"folder of matrix.md and matrix.csv (default: {DEFAULT_OUTPUT}/)",
               default=DEFAULT_OUTPUT)


def _archives(names: list[str]) -> list[Path]:
    if not names:
        found = sorted(BUILT.glob("*.ssp"))
        if not found:
            raise UsageError(f"no scenarios in {BUILT}/ (run 'orchestrate build' first)")
        return found
    paths = []
    for name in names:
        try:
            path = resolve_scenario(name)
        except ScenarioError as exc:  # a name that is nothing: how the command was called
            raise UsageError(str(exc)) from None
        if not path.is_file():
            raise UsageError(f"{path}: a folder; the other tools read .ssp archives (pack it with "
                             "'orchestrate build', or zip it)")
        paths.append(path)
    return paths


def _progress(line: str) -> None:
    if not quiet():
        print(f"crosscheck: {line}", file=sys.stderr, flush=True)


def _crosscheck(args: argparse.Namespace) -> int:
    scenarios = []
    for path in _archives(args.scenarios):
        try:
            scenario = Scenario.read(path)
            signals_of(scenario, args.signal)  # a signal it does not output: now, before any tool runs
        except ValueError as exc:
            raise ScenarioError(str(exc)) from exc
        scenarios.append(scenario)
    selected = select_tools(args.tools)
    for tool in selected:
        reason = tool.missing()
        if reason:
            _progress(f"{tool.key}: {reason}")
    cells = run_matrix(scenarios, selected, _progress, args.signal)
    md = write_markdown(cells, args.output / "matrix.md", selected)
    table = write_csv(cells, args.output / "matrix.csv")
    red = [c for c in cells if c.red]
    if not args.quiet:
        print(f"{md}\n{table}")
    if red:
        print(f"orchestrate: crosscheck: {len(red)} red cell(s): "
              + ", ".join(f"{c.scenario} in {c.tool}" for c in red), file=sys.stderr)
        return 1
    return 0
