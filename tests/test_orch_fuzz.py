# SPDX-License-Identifier: BSD-2-Clause
"""Fuzzing the readers: mutated SSD and SSV files (elements and attributes dropped, duplicated and
renamed; numbers like ``nan``, ``1e400``, ``-0``; empty strings; unicode names) must either run or be
refused with one line per problem, never a traceback, a crash or a hang.

``validate`` (the command, in-process) and ``run`` (the engine, with a wall-clock limit) must agree:
a scenario with an error is refused by both; one without runs or fails with an OrchestratorError.
Inputs the fuzzing found (and the tracebacks first reported by hand, issue 13) are kept as
regression cases below, each with the line it must now give.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import stat
import zipfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree
from orch_helpers import loop_scenario

import orchestrator
from orchestrator import RunOptions
from orchestrator.cli import main
from orchestrator.errors import OrchestratorError, ScenarioError
from orchestrator.ssp import SSD_NAME

pytestmark = pytest.mark.system

FILES = (SSD_NAME, "gain.ssv", "integrator.ssv", "source.ssv")
VALUES = ("nan", "NaN", "INF", "-INF", "1e400", "-1e400", "1e308", "-0", "0", "-1", "1e-400", "", " ",
          "abc", "ünïcødé", "a.b", "x" * 300, "0x10", "1_000", "true", "gain", "integrator", "u", "y", "x",
          "resources/Gain.fmu", "../escape.fmu", "/etc/passwd", "input", "output", "parameter")
TAGS = ("Component", "Connector", "Connection", "Connectors", "Real", "Integer", "Boolean", "String",
        "Parameter", "ParameterBinding", "DefaultExperiment", "LinearTransformation", "Elements", "Foo")
OPERATIONS = ("drop", "duplicate", "rename_tag", "drop_attribute", "set_attribute", "rename_attribute",
              "add_attribute")
ATTRIBUTES = ("name", "value", "factor", "offset", "startTime", "stopTime", "stepSize", "baseStepSize",
              "source", "kind", "prefix", "version", "unit", "startElement", "endConnector")


@pytest.fixture(scope="module")
def base(test_fmus, tmp_path_factory) -> Path:
    """The loop scenario as a folder (SSD, three .ssv files, resources/ with the FMUs)."""
    return loop_scenario(tmp_path_factory.mktemp("fuzz") / "loop", test_fmus, stop=0.1, pack=False)


def mutate(base: Path, dest: Path, mutations: list[tuple[str, int, str, int, str]]) -> Path:
    """A copy of ``base`` (FMUs hard-linked, not copied: a symbolic link to them would lead outside the
    scenario, which is refused) with ``mutations`` applied: (file, element index, operation,
    attribute or tag index, value)."""
    dest.mkdir()
    shutil.copytree(base / "resources", dest / "resources", copy_function=os.link)
    trees = {name: etree.parse(str(base / name)) for name in FILES}
    for file, index, operation, which, value in mutations:
        root = trees[file].getroot()
        elements = list(root.iter(etree.Element))
        element = elements[index % len(elements)]
        parent = element.getparent()
        attributes = list(element.attrib)
        if operation == "drop" and parent is not None:
            parent.remove(element)
        elif operation == "duplicate" and parent is not None:
            parent.insert(parent.index(element), etree.fromstring(etree.tostring(element)))
        elif operation == "rename_tag":
            element.tag = f"{{{etree.QName(element).namespace}}}{TAGS[which % len(TAGS)]}"
        elif operation == "drop_attribute" and attributes:
            del element.attrib[attributes[which % len(attributes)]]
        elif operation == "set_attribute" and attributes:
            element.set(attributes[which % len(attributes)], value)
        elif operation == "rename_attribute" and attributes:
            old = attributes[which % len(attributes)]
            text = element.attrib.pop(old)
            element.set(ATTRIBUTES[which % len(ATTRIBUTES)], text)
        elif operation == "add_attribute":
            element.set(ATTRIBUTES[which % len(ATTRIBUTES)], value)
    for name, tree in trees.items():
        tree.write(str(dest / name), xml_declaration=True, encoding="UTF-8")
    return dest


def check(folder: Path) -> str:
    """validate then run ``folder``; assert the outcome is clean and the two agree. Returns what
    happened ('ran', 'failed: ...', 'refused: ...')."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["validate", str(folder)])  # any exception here fails the test
    lines = out.getvalue().splitlines()
    assert status in (0, 1), out.getvalue()
    prefixes = ("error: ", "warning: ", "ok: ", "failed: ")
    assert lines and all(line.startswith(prefixes) for line in lines), lines
    assert not err.getvalue(), err.getvalue()
    try:
        orchestrator.run(folder, RunOptions(timeout=10.0))
    except ScenarioError as exc:
        assert str(exc) and "Traceback" not in str(exc)
        return f"refused: {exc}"
    except OrchestratorError as exc:
        assert status == 0, f"validate found errors the run did not refuse: {lines}"
        return f"failed: {exc}"
    assert status == 0, f"validate found errors but the run went through: {lines}"
    return "ran"


mutation = st.tuples(st.sampled_from(FILES), st.integers(0, 200), st.sampled_from(OPERATIONS),
                     st.integers(0, 50), st.sampled_from(VALUES))


@settings(max_examples=100, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(mutations=st.lists(mutation, min_size=1, max_size=3))
def test_mutated_scenarios_run_or_are_refused_cleanly(base, tmp_path, mutations):
    folder = tmp_path / "m"
    if folder.exists():
        shutil.rmtree(folder)
    check(mutate(base, folder, mutations))


def _ssd(base: Path, dest: Path, old: str, new: str, file: str = SSD_NAME) -> Path:
    """A copy of ``base`` with ``old`` replaced by ``new`` in ``file`` (once, and it must be there)."""
    dest.mkdir()
    shutil.copytree(base / "resources", dest / "resources", copy_function=os.link)
    for name in FILES:
        text = (base / name).read_text()
        if name == file:
            assert old in text, old
            text = text.replace(old, new, 1)
        (dest / name).write_text(text)
    return dest


# (file, text, replacement, what the run must say); the first nine were tracebacks (issue 13)
REGRESSIONS = [
    (SSD_NAME, 'stopTime="0.1"', 'stopTime="1e400"',
     "DefaultExperiment stopTime='1e400' is not a finite number"),
    (SSD_NAME, 'startTime="0.0"', 'startTime="1e308"',
     "the start time 1e+308 s is not a finite time within +-4.61e+09 s"),
    (SSD_NAME, 'baseStepSize="0.01"', 'baseStepSize=""',
     "FixedStepAlgorithm baseStepSize='' is not a finite number"),
    (SSD_NAME, 'baseStepSize="0.01"', 'baseStepSize=" "',
     "FixedStepAlgorithm baseStepSize=' ' is not a finite number"),
    (SSD_NAME, 'baseStepSize="0.01"', 'baseStepSize="abc"',
     "FixedStepAlgorithm baseStepSize='abc' is not a finite number"),
    (SSD_NAME, 'stepSize="0.01"', 'stepSize=""', "FixedStepMaster stepSize='' is not a finite number"),
    (SSD_NAME, 'stepSize="0.01"', 'stepSize=" "', "FixedStepMaster stepSize=' ' is not a finite number"),
    (SSD_NAME, 'stepSize="0.01"', 'stepSize="abc"', "FixedStepMaster stepSize='abc' is not a finite number"),
    (SSD_NAME, '<ssd:Connector name="u" kind="input">\n            <ssc:Real/>\n          </ssd:Connector>',
     '<ssd:Connector name="u" kind="input"/><ssd:Connector name="u" kind="input"/>',
     "component 'gain': connector 'u' is declared more than once"),
    (SSD_NAME, 'endElement="integrator" endConnector="u"/>',
     'endElement="integrator" endConnector="u"><ssc:LinearTransformation factor="INF"/></ssd:Connection>',
     "connection gain.y -> integrator.u: LinearTransformation factor=inf offset=0.0 is not finite"),
    (SSD_NAME, 'stopTime="0.1"', 'stopTime="1e12"', "the stop time 1e+12 s is not a finite time"),
]


@pytest.mark.parametrize("file, old, new, message", REGRESSIONS)
def test_regression_cases(base, tmp_path, file, old, new, message):
    outcome = check(_ssd(base, tmp_path / "r", old, new, file))
    assert outcome.startswith("refused: ") and message in outcome, outcome


def test_an_xml_error_message_that_spans_lines_is_one_line(base, tmp_path):
    """main (third attack, 500 + 200 unseeded mutants): a NUL byte at the SSD's second byte made
    lxml's message span two lines ('Char 0x0 out of allowed range\\n, line 1, column 2'), so
    validate printed a line that was no error, warning or verdict."""
    outcome = check(_ssd(base, tmp_path / "r", "<?xml", "<\x00xml"))
    assert outcome.startswith("refused: ") and "Char 0x0 out of allowed range" in outcome, outcome


def test_a_removed_connection_runs_with_a_warning(base, tmp_path):
    """Found as 'corrupted double-linked list' by the first fuzzing pass (heap corruption at exit,
    fixed in the FMU shim); here a clean run with the input at its start value."""
    folder = _ssd(base, tmp_path / "r", '<ssd:Connection startElement="integrator" startConnector="x" '
                  'endElement="gain" endConnector="u"/>', "")
    assert check(folder) == "ran"


# -- bytes, encodings and FMU members (issue 20) ---------------------------------------------------------
ENCODINGS = ("utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-32", "latin-1", "cp1252", "ascii")
MEMBER_NAMES = ("resources\\x.txt", "c:x.txt", "resources/c:x", "../x.txt", "/abs.txt", "a/../../x",
                "binaries/linux64/../../../x.so", "ünïcødé/x", "x" * 300, "modelDescription.xml",
                "documentation/", "resources/ok.txt")


def _bytes_mutant(data: bytes, edits: list[tuple[int, bytes]], encoding: str | None, declared: bool) -> bytes:
    """``data`` (an XML file, UTF-8) re-encoded (its declaration kept, changed or dropped), then with
    ``edits`` (position, bytes) written over it."""
    if encoding is not None:
        text = data.decode("utf-8")
        if not declared:
            text = text.split("?>", 1)[-1]
        data = text.encode(encoding, "replace")
    out = bytearray(data)
    for position, chunk in edits:
        at = position % (len(out) + 1)
        out[at:at + len(chunk)] = chunk
    return bytes(out)


def _fmu_mutant(fmu: Path, operation: str, name: str, position: int, chunk: bytes) -> bytes:
    """``fmu`` with a member added (name fuzzed), a symbolic link member, or bytes of the raw zip
    overwritten (headers, data, directory: zipfile and the CRC catch them)."""
    if operation == "flip":
        data = bytearray(fmu.read_bytes())
        at = position % len(data)
        data[at:at + len(chunk)] = chunk
        return bytes(data)
    buffer = io.BytesIO()
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for info in source.infolist():
            zf.writestr(info, source.read(info))
        member = zipfile.ZipInfo(name or "x")
        if operation == "symlink":
            member.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(member, b"/etc/passwd" if operation == "symlink" else chunk)
    return buffer.getvalue()


byte_edits = st.lists(st.tuples(st.integers(0, 4000), st.binary(min_size=1, max_size=4)), max_size=3)


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(file=st.sampled_from(FILES), edits=byte_edits, encoding=st.none() | st.sampled_from(ENCODINGS),
       declared=st.booleans(), fmu=st.sampled_from(("Gain.fmu", "Integrator.fmu", "Source.fmu")),
       operation=st.sampled_from(("none", "add", "symlink", "flip")),
       name=st.sampled_from(MEMBER_NAMES) | st.text(min_size=1, max_size=40),
       position=st.integers(0, 1 << 20), chunk=st.binary(min_size=1, max_size=4))
def test_mutated_bytes_encodings_and_fmu_members_run_or_are_refused_cleanly(
        base, tmp_path, file, edits, encoding, declared, fmu, operation, name, position, chunk):
    """An SSD or SSV file with bytes overwritten and re-encoded (UTF-16/32, Latin-1, a BOM; the
    declaration kept or dropped), and an FMU with a member added under a hostile name, a symbolic
    link member, or raw bytes of the zip overwritten: one line per problem, validate and run agree."""
    folder = tmp_path / "m"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir()
    shutil.copytree(base / "resources", folder / "resources", copy_function=os.link)
    for other in FILES:
        data = (base / other).read_bytes()
        mutated = _bytes_mutant(data, edits, encoding, declared) if other == file else data
        (folder / other).write_bytes(mutated)
    if operation != "none":
        target = folder / "resources" / fmu
        mutant = _fmu_mutant(base / "resources" / fmu, operation, name, position, chunk)
        target.unlink()  # a hard link to the base's FMU: replaced, never written through
        target.write_bytes(mutant)
    check(folder)


@pytest.mark.parametrize(("operation", "name", "expected"), [
    ("add", "resources\\x.txt", "has a backslash or a colon in its name"),
    ("add", "../x.txt", "points outside the archive folder"),
    ("add", "x" * 300, "has a name part longer than 255 bytes"),  # validate said ok, run OSError
    ("symlink", "resources/link", "is a symbolic link"),
    ("symlink", "\r", "member '\\r' is a symbolic link"),  # third attack: the name broke the line
    ("add", "a\u2028b\x85\\c", "member 'a\\u2028b\\x85\\c' has a backslash"),
    ("flip", "", "cannot be unpacked"),
])
def test_fmu_member_regressions(base, tmp_path, operation, name, expected):
    """Tracebacks of run before issue 20 (fmpy's 'Illegal path', BadZipFile 'Bad CRC-32'), and
    the members check_zip refused already."""
    folder = _ssd(base, tmp_path / "r", "", "")
    target = folder / "resources" / "Gain.fmu"
    source = base / "resources" / "Gain.fmu"
    with zipfile.ZipFile(source) as zf:  # the middle of the largest member's data
        big = max(zf.infolist(), key=lambda i: i.compress_size)
        middle = big.header_offset + 30 + len(big.filename.encode()) + len(big.extra) + big.compress_size // 2
    mutant = _fmu_mutant(source, operation, name, middle, b"\x00\xff")
    target.unlink()
    target.write_bytes(mutant)
    outcome = check(folder)
    assert outcome.startswith("refused: ") and expected in outcome, outcome
