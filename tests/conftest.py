"""Fixtures shared by the system tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from orchestrator.cli import main

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``orchestrate build`` into a temporary folder, once per test process: FMUs under fmus/,
    archives under ssp/."""
    dest = tmp_path_factory.mktemp("build")
    assert main(["build", "--sources", str(REPO / "ssp"), "--dest", str(dest)]) == 0
    return dest
