# SPDX-License-Identifier: BSD-2-Clause
"""Co-simulation regression: scenarios run against stored baselines inside tubes, as a CI step.

``orchestrate regress PATH...`` runs a suite of scenarios (each with its baseline and tolerances
beside it) in parallel processes and writes JUnit XML and a self-contained HTML report;
``orchestrate baseline`` writes baselines and reviews their updates; ``orchestrate compare``
checks one result file against one baseline; ``pytest --ssp-regress DIR`` (the plugin
:mod:`orchestrator.regress.pytest_plugin`) makes each scenario a pytest item. This application
imports only the engine. docs/regression.md describes the layout and the CI templates.
"""

from __future__ import annotations

from .suite import Case, Outcome, check_case, find_cases, run_cases
from .tubes import (
    BASELINE_GRID,
    TOLERANCES_NAME,
    Comparison,
    RegressionError,
    SignalCheck,
    Tolerance,
    Tolerances,
    compare,
    compare_files,
    format_comparison,
    load_tolerances,
    output_columns,
    resample,
    thin,
    write_baseline,
)

__all__ = [
    "BASELINE_GRID",
    "TOLERANCES_NAME",
    "Case",
    "Comparison",
    "Outcome",
    "RegressionError",
    "SignalCheck",
    "Tolerance",
    "Tolerances",
    "check_case",
    "compare",
    "compare_files",
    "find_cases",
    "format_comparison",
    "load_tolerances",
    "output_columns",
    "resample",
    "run_cases",
    "thin",
    "write_baseline",
]
