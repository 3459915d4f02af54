# SPDX-License-Identifier: BSD-2-Clause
"""pytest plugin (entry point ``pytest11``): ``pytest --ssp-regress PATH`` makes each scenario of a
regression suite one pytest item, so that a project's own pytest run, its ``-k`` selection, its
``-n`` workers (pytest-xdist) and its ``--junitxml`` include them.

PATH is what ``orchestrate regress`` takes (a folder searched for scenarios, an ``.ssp`` archive or a
scenario folder), with the same layout of baselines and tolerances (docs/regression.md). It follows
pytest's documented pattern for non-Python test files: a collector for each PATH yields one item
per scenario; an item fails with the table of the signals outside their tubes, and errors when its
scenario cannot run or has no baseline. Without ``--ssp-regress`` the plugin does nothing.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from ..errors import UsageError
from .suite import ERROR, FAIL, Case, Outcome, Settings, check_case, check_setup, find_cases
from .tubes import format_comparison

__all__ = ["ScenarioItem", "SuiteCollector"]

OPTION = "--ssp-regress"


def pytest_addoption(parser: pytest.Parser) -> None:
    """The plugin's options."""
    group = parser.getgroup("ssp-regress", "co-simulation regression (orchestrate regress)")
    group.addoption(OPTION, action="append", default=[], metavar="PATH", dest="ssp_regress",
                    help="run the scenarios found in PATH against their baselines, one item per scenario "
                         "(repeatable; PATH as for 'orchestrate regress')")
    group.addoption("--ssp-baselines", metavar="DIR", dest="ssp_baselines",
                    help="the folder of every baseline and tolerances.json (default: baselines/ beside each "
                         "scenario)")
    group.addoption("--ssp-timeout", type=float, metavar="SECONDS", dest="ssp_timeout",
                    help="wall-clock limit of each scenario's run")


def _roots(config: pytest.Config) -> list[Path]:
    return [Path(p).resolve() for p in config.getoption("ssp_regress") or []]


def pytest_configure(config: pytest.Config) -> None:
    """Collect every PATH of ``--ssp-regress`` too (besides the run's own test paths), unless a
    path pytest already collects contains it."""
    roots = _roots(config)
    for root in roots:
        if not root.exists():
            raise pytest.UsageError(f"{OPTION} {root}: no such file or folder")
    given = [Path(a.split("::")[0]).resolve() for a in config.args]
    for root in roots:
        if not any(root == g or g in root.parents for g in given):
            config.args.append(str(root))


def _settings(config: pytest.Config) -> Settings:
    return Settings(timeout=config.getoption("ssp_timeout"))


def _baselines(config: pytest.Config) -> str | None:
    folder = config.getoption("ssp_baselines")
    return str(Path(folder).resolve()) if folder else None


def pytest_collect_directory(path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    """A folder given to ``--ssp-regress`` is collected as a suite (one item per scenario)."""
    if path.resolve() in _roots(parent.config):
        return SuiteCollector.from_parent(parent, path=path)
    return None


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    """An ``.ssp`` archive given to ``--ssp-regress`` is collected as a suite of one."""
    if file_path.resolve() in _roots(parent.config) and file_path.suffix.lower() == ".ssp":
        return SuiteFile.from_parent(parent, path=file_path)
    return None


def _items(collector: pytest.Collector, path: Path) -> Iterator[ScenarioItem]:
    try:
        cases = find_cases([path], _baselines(collector.config))
    except UsageError as exc:
        raise pytest.UsageError(f"{OPTION} {path}: {exc}") from None
    for case in cases:
        inside = case.scenario != path
        name = case.scenario.relative_to(path).with_suffix("").as_posix() if inside else case.name
        yield ScenarioItem.from_parent(collector, name=name, case=case)


class SuiteCollector(pytest.Directory):
    """A folder of scenarios: one :class:`ScenarioItem` per scenario found in it (or the folder
    itself, when it is a scenario)."""

    def collect(self) -> Iterator[ScenarioItem]:
        """The scenarios, sorted by path."""
        yield from _items(self, self.path)


class SuiteFile(pytest.File):
    """An ``.ssp`` archive given on the command line: one item."""

    def collect(self) -> Iterator[ScenarioItem]:
        """The archive's scenario."""
        yield from _items(self, self.path)


class RegressionFailure(Exception):  # noqa: N818 - a test failure, not an error
    """A scenario's run outside its baseline's tubes (or missing a signal, or short)."""

    def __init__(self, outcome: Outcome) -> None:
        super().__init__(outcome.message)
        self.outcome = outcome


class ScenarioRunError(Exception):
    """A scenario that did not run to its end, or cannot run as set up (no baseline, ...)."""


class ScenarioItem(pytest.Item):
    """One scenario run and compared with its baseline (:func:`orchestrator.regress.check_case`)."""

    def __init__(self, *, case: Case, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.case = case

    def setup(self) -> None:
        """Refuse a scenario without a readable baseline or tolerances, or a stale build."""
        try:
            check_setup([self.case], need_baseline=True)
        except UsageError as exc:
            raise ScenarioRunError(str(exc)) from None

    def runtest(self) -> None:
        """Run the scenario; a regression or a failed run raises."""
        outcome = check_case(self.case, _settings(self.config))
        if outcome.warnings:
            self.add_report_section("call", "stderr", "".join(f"warning: {w}\n" for w in outcome.warnings))
        if outcome.status == FAIL:
            raise RegressionFailure(outcome)
        if outcome.status == ERROR:
            raise ScenarioRunError(f"{outcome.message}\n{outcome.detail}".rstrip())

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> str | Any:
        """The table of the signals outside their tubes, or the one line of why it did not run."""
        error = excinfo.value
        if isinstance(error, RegressionFailure):
            c = error.outcome.comparison
            return format_comparison(c) if c is not None else str(error)
        if isinstance(error, ScenarioRunError):
            return str(error)
        return super().repr_failure(excinfo, style)

    def reportinfo(self) -> tuple[Path, int | None, str]:
        """Where the item is: its scenario."""
        return self.case.scenario, None, f"scenario {self.case.name}"
