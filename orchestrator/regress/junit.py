# SPDX-License-Identifier: BSD-2-Clause
"""JUnit XML of a regression suite, the test-result format CI services show (GitHub Actions through
a reporter action, GitLab's ``artifacts:reports:junit``, Jenkins, Azure Pipelines).

One ``testcase`` per scenario (``classname`` the folder it was found in, ``name`` the scenario): a
regression is a ``failure`` whose text is the table of the signals outside their tubes, a scenario
that did not run an ``error``, one not run (interrupted suite) ``skipped``; warnings go to
``system-err``. Written to the Jenkins/Ant schema (``junit-10.xsd`` of Jenkins' xUnit plugin),
which the tests validate each file against.
"""

from __future__ import annotations

import os
import re
import socket
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

from lxml import etree

from .. import files
from ..cli import version_line
from .suite import ERROR, FAIL, NOT_RUN, Outcome
from .tubes import format_comparison

__all__ = ["junit_xml", "write_junit"]

SUITE_NAME = "orchestrate regress"
# characters XML 1.0 cannot hold (an FMU's log message may carry them)
_NOT_XML = re.compile("[^\u0009\u000a\u000d\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _text(value: str) -> str:
    return _NOT_XML.sub("\ufffd", value)


def _seconds(value: float) -> str:
    return f"{max(value, 0.0):.3f}"  # the schema's time: digits and at most three decimals


def junit_xml(outcomes: Sequence[Outcome], seconds: float, name: str = SUITE_NAME) -> bytes:
    """The JUnit XML document of a suite's outcomes (UTF-8 bytes)."""
    failures = sum(o.status == FAIL for o in outcomes)
    errors = sum(o.status == ERROR for o in outcomes)
    skipped = sum(o.status == NOT_RUN for o in outcomes)
    counts = {"tests": str(len(outcomes)), "failures": str(failures), "errors": str(errors)}
    root = etree.Element("testsuites", name=name, time=_seconds(seconds), **counts)
    suite = etree.SubElement(root, "testsuite", name=name, skipped=str(skipped), time=_seconds(seconds),
                             timestamp=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                             hostname=socket.gethostname(), **counts)
    properties = etree.SubElement(suite, "properties")
    etree.SubElement(properties, "property", name="orchestrate", value=version_line())
    for o in outcomes:
        case = etree.SubElement(suite, "testcase", classname=_text(o.case.group), name=_text(o.case.name),
                                time=_seconds(o.seconds))
        _verdict(case, o)
        out = etree.SubElement(case, "system-out")
        out.text = _text(f"scenario: {o.case.scenario}\nbaseline: {o.case.baseline}\n{o.message}\n")
        if o.warnings:
            err = etree.SubElement(case, "system-err")
            err.text = _text("".join(f"warning: {w}\n" for w in o.warnings))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _verdict(case: etree._Element, o: Outcome) -> None:
    """The test case's failure (the comparison's table), error (its detail) or skipped element;
    nothing for a pass."""
    if o.status == FAIL:
        failure = etree.SubElement(case, "failure", type="regression", message=_text(o.message))
        failure.text = _text(format_comparison(o.comparison) if o.comparison is not None else o.message)
    elif o.status == ERROR:
        error = etree.SubElement(case, "error", type="error", message=_text(o.message))
        error.text = _text(o.detail or o.message)
    elif o.status == NOT_RUN:
        etree.SubElement(case, "skipped", message=_text(o.message))


def write_junit(outcomes: Sequence[Outcome], seconds: float, path: str | os.PathLike) -> Path:
    """Write :func:`junit_xml` to ``path`` (atomically: a CI service never reads half a file)."""
    with files.replacing(path) as temporary:
        temporary.write_bytes(junit_xml(outcomes, seconds))
    return Path(path)
