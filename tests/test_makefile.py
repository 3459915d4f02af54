# SPDX-License-Identifier: BSD-2-Clause
"""Every make target a newcomer may type after ``make run`` installs what its recipe needs.

``make run`` installs the package alone; the test dependencies (pytest, libcosimpy,
ruff ...) come with ``.venv/.installed-dev``. ``make hostile``, ``make executors``, ``make
bench`` ... on a fresh clone ran pytest or libcosim without them: ``No module named pytest``.

Oracle: make's own dry run (``make -n -B TARGET``: every recipe of the target's prerequisites, as
make resolves them from the Makefile); a target whose recipe runs pytest or a benchmark must reach
the recipe that installs the test extra.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
INSTALLS_TEST_EXTRA = "install --quiet -e '.[test"


def _targets() -> list[str]:
    """The Makefile's own targets (``name: ...`` at the start of a line, no pattern, no variable)."""
    text = (REPO / "Makefile").read_text()
    return sorted({m.group(1) for m in re.finditer(r"^([a-z][a-z0-9-]*):(?!=)", text, re.MULTILINE)})


def _dry_run(target: str) -> str:
    done = subprocess.run(["make", "-n", "-B", target], cwd=REPO, capture_output=True, text=True,
                          timeout=60, check=True)
    return done.stdout


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_targets_that_run_tests_or_benchmarks_install_the_test_extra():
    targets = _targets()
    assert {"run", "test", "hostile", "bench"} <= set(targets)  # the list is the Makefile's
    runs_tests = {}
    for target in targets:
        commands = _dry_run(target)
        if "-m pytest" in commands or "benchmarks/" in commands:
            runs_tests[target] = INSTALLS_TEST_EXTRA in commands
    assert {"test", "hostile", "executors", "bench"} <= runs_tests.keys()
    missing = sorted(t for t, installs in runs_tests.items() if not installs)
    assert not missing, f"these targets run pytest or a benchmark without $(DEV_STAMP): {missing}"
