# SPDX-License-Identifier: BSD-2-Clause
"""MkDocs hook: pages generated from the code at build time, so they cannot drift from it.

``reference/cli.md`` is every ``orchestrate`` subcommand's ``--help`` as argparse prints it, and
``license.md`` the repository's LICENSE file.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps the subcommands on its _SubParsersAction
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def cli_reference() -> str:
    """Markdown of ``orchestrate --help`` and of each subcommand's help, in name order."""
    from orchestrator.cli import _parser

    parser = _parser()
    parts = ["# Command line: `orchestrate`\n",
             "Generated from the installed command's own help when the site is built.\n",
             "```text\n" + parser.format_help() + "```\n"]
    for name, sub in sorted(_subcommands(parser).items()):
        parts.append(f"## `orchestrate {name}`\n\n```text\n{sub.format_help()}```\n")
    return "\n".join(parts)


def on_page_content(html: str, **_: Any) -> str:
    """Drop the Sphinx roles (``:class:``, ``:func:`` ...) the docstrings use before a code span:
    mkdocstrings renders the span, not the role."""
    return re.sub(r":(?:class|func|meth|mod|attr|data|exc|obj):(?=<code)", "", html)


def on_files(files: Files, config: Any) -> Files:
    """Add the generated pages to the site."""
    files.append(File.generated(config, "reference/cli.md", content=cli_reference()))
    licence = (ROOT / "LICENSE").read_text(encoding="utf-8")
    files.append(File.generated(config, "license.md",
                                content="# Licence\n\n```text\n" + licence + "```\n"))
    return files
