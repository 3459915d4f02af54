# SPDX-License-Identifier: BSD-2-Clause
"""Build hook (the metadata is in pyproject.toml): the scenario sources and campaign designs of
the checkout's top-level ``ssp/`` ship inside the wheel as ``orchestrator/experiments/ssp/``, so
that an installed ``orchestrate build`` has them (an editable install reads ``ssp/`` in place)."""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPy(build_py):
    """``build_py`` that also copies ``ssp/`` (without its generator script) into the package."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        target = Path(self.build_lib, "orchestrator", "experiments", "ssp")
        shutil.copytree(Path(__file__).parent / "ssp", target, dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "generate.py"))


setup(cmdclass={"build_py": BuildPy})
