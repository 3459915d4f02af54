# SPDX-License-Identifier: BSD-2-Clause
"""documentation/index.html of the controller FMUs (issue 35): present in every controller FMU (and
FMI 2.0's _main.html leading to it), every variable of the FMU's own model description in it with its
start value, and its worked example, a plant that is not the paper's, runs as printed and tracks."""

from __future__ import annotations

import html
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import pytest

from fmu_src.toolchain.controller_doc import controller_documentation

CONTROLLERS = {"FixedTimeController1": 1, "FixedTimeController": 2, "FixedTimeController3": 3,
               "FixedTimeController4": 4}


def page(fmu: Path) -> str:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read("documentation/index.html").decode("utf-8")


@pytest.mark.system
@pytest.mark.parametrize("model", CONTROLLERS)
def test_every_variable_is_documented_with_its_start_value(fmus: dict[str, Path], model: str) -> None:
    text = page(fmus[model])
    with zipfile.ZipFile(fmus[model]) as archive:
        assert b'url=index.html' in archive.read("documentation/_main.html")
        assert "documentation/licenses/pythonfmu-LICENSE.txt" in archive.namelist()  # beside the licences
    md = fmpy.read_model_description(str(fmus[model]))
    rows = dict(re.findall(r"<tr><td><code>(\w+)</code></td>(.*?)</tr>", text))
    assert set(rows) == {v.name for v in md.modelVariables}  # inputs, outputs, parameters: all of them
    for v in md.modelVariables:
        if v.causality == "parameter":
            assert f"<td>{v.start}</td>" in rows[v.name], v.name
        assert html.escape(v.description) in rows[v.name], v.name
    n = CONTROLLERS[model]
    assert f"order <b>n = {n}</b>" in text
    assert text.count("<svg") == 1 and "y = x_1" in text


@pytest.mark.system
@pytest.mark.parametrize("model", CONTROLLERS)
def test_worked_example_runs_as_printed_and_tracks(fmus: dict[str, Path], model: str,
                                                   tmp_path: Path) -> None:
    """The page's Python, copied out of the FMU, run beside it in a fresh interpreter: the plant that is
    not the paper's follows yd = 0.5 sin t within 0.01 after 5 s, and leaves nothing in TMPDIR."""
    found = re.search(r'<code class="language-python">(.*?)</code>', page(fmus[model]), re.S)
    assert found is not None
    code = html.unescape(found.group(1))
    (tmp_path / f"{model}.fmu").write_bytes(fmus[model].read_bytes())
    (tmp_path / "example.py").write_text(code)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    done = subprocess.run([sys.executable, "example.py"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300, env={**os.environ, "TMPDIR": str(scratch)})
    assert done.returncode == 0, done.stderr
    assert not any(scratch.iterdir()), "the example left its unpacked FMU behind"
    printed = re.search(r"tracking error at t = 5.0 s: (\S+)", done.stdout)
    assert printed is not None, done.stdout
    error = float(printed.group(1))
    assert abs(error) < 0.01, done.stdout


def test_a_variable_without_documentation_is_a_build_error() -> None:
    """The page cannot drift from the FMU: a parameter this module does not describe stops the build."""
    xml = b"""<fmiModelDescription fmiVersion="2.0" modelName="FixedTimeController3"><ModelVariables>
      <ScalarVariable name="k1" causality="parameter" description="d"><Real start="1"/></ScalarVariable>
      <ScalarVariable name="gain_new1" causality="parameter" description="d"><Real start="1"/>
      </ScalarVariable>
      </ModelVariables></fmiModelDescription>"""
    with pytest.raises(ValueError, match=r"FixedTimeController3: documentation/index.html describes no "
                                         r"gain_new1"):
        controller_documentation("FixedTimeController3", xml)
    assert controller_documentation("Reference", xml) == {}
