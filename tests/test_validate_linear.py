# SPDX-License-Identifier: BSD-2-Clause
"""validate's FMU checks: fmpy's findings, in time linear in the variables.

``orchestrator.system.fmu_findings`` replaces fmpy's ``validate_fmu`` (whose Earley parse of every
"structured" variable name made validate cost 30 s on the OSP demo dp-ship, minutes on an FMU with
10^5 variables). The oracle is fmpy itself: the same findings on every third-party FMU the tests
hold, and, name by name, the same verdict as fmpy's grammar for the names the fast path accepts.
The figures are in benchmarks/validate_cost.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.validation import _validate_variable_names, validate_fmu

from orchestrator.system import _PLAIN_NAME, _with_variables, fmu_findings

HERE = Path(__file__).resolve().parent
REFERENCE_FMUS = HERE.parents[1] / "shared" / "tools" / "reference-fmus"
FMUS = sorted([*(HERE / "ssp_conformance").rglob("*.fmu"), *REFERENCE_FMUS.rglob("*.fmu")])


@pytest.mark.parametrize("fmu", FMUS, ids=[f"{p.parent.name}/{p.name}" for p in FMUS])
def test_same_findings_as_fmpys_validate_fmu(fmu: Path) -> None:
    md = read_model_description(str(fmu), validate=False)
    assert sorted(fmu_findings(fmu, md)) == sorted(validate_fmu(str(fmu)))


NAMES = ["a", "_x", "a.b[2]", "a[1].b[2,3]", "der(x)", "der(x.y[1,2])", "der(x,2)", "x1.y2_z3",
         "2a", "a b", "a[]", "a[1", "a.", ".a", "der(a", "der(2a)", "a[-1]", "'quoted name'", "a.'b c'[1]",
         "der('q',1)", "a..b", "a[1,]", "a[x]", "A.B.C[10,20,30].d", "é", "a-b", "der (x)"]


@pytest.mark.skipif(not (REFERENCE_FMUS / "2.0" / "Feedthrough.fmu").is_file(),
                    reason=f"no Modelica Reference FMUs in {REFERENCE_FMUS}")
def test_fast_path_accepts_only_what_fmpys_grammar_accepts() -> None:
    """Every name the regular expression accepts passes fmpy's parser; the others are left to it."""
    md = read_model_description(str(REFERENCE_FMUS / "2.0" / "Feedthrough.fmu"), validate=False)
    md.variableNamingConvention = "structured"
    template = md.modelVariables[0]
    for name in NAMES:
        template.name = name
        fmpy_accepts = not _validate_variable_names(_with_variables(md, [template]))
        if _PLAIN_NAME.fullmatch(name):
            assert fmpy_accepts, name
    accepted = [n for n in NAMES if _PLAIN_NAME.fullmatch(n)]
    assert len(accepted) == 9, accepted  # the fast path is taken for the ordinary names
