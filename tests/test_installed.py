# SPDX-License-Identifier: BSD-2-Clause
"""orchestrator.installed against importlib.metadata, the oracle it stands in for: the same
versions and entry points for every distribution of this environment and for made-up site folders
(names to normalize, a distribution twice on the path, case-sensitive entry-point names)."""

from __future__ import annotations

import importlib.metadata as metadata
import sys
from pathlib import Path

import pytest

from orchestrator import installed


def _oracle_points(group: str) -> list[tuple[str, str, str]]:
    return sorted((e.name, e.value, e.group) for e in metadata.entry_points(group=group))


def test_every_distribution_of_this_environment() -> None:
    names = {d.metadata["Name"] for d in metadata.distributions()}
    assert {"fixed-time-cosim", "fmpy", "numpy"} <= {n.lower() for n in names}
    for name in names:
        assert installed.version(name) == metadata.version(name), name
    groups = {e.group for d in metadata.distributions() for e in d.entry_points}
    assert {"orchestrate.commands", "orchestrate.checks", "orchestrate.figures", "console_scripts"} <= groups
    for group in groups:
        assert [tuple(e) for e in installed.entry_points(group)] == _oracle_points(group), group
    assert installed.version("no-such-distribution") is None
    assert installed.entry_points("no.such.group") == []


def _dist(site: Path, folder: str, name: str, version: str, entry_points: str = "") -> None:
    info = site / folder
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    if entry_points:
        (info / "entry_points.txt").write_text(entry_points)


def test_made_up_site_folders(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    _dist(first, "Odd_Name.pkg-1.2.post3.dist-info", "Odd-Name.pkg", "1.2.post3",
          "[demo.group]\nCamelCase = odd.module:Thing.attr\nplain=odd.other\n\n[other]\nx = y\n")
    _dist(second, "odd_name_pkg-9.9.dist-info", "odd_name_pkg", "9.9",
          "[demo.group]\nshadowed = never:seen\n")
    _dist(second, "second_only-0.1.dist-info", "second-only", "0.1", "[demo.group]\nCamelCase = again:here\n")
    _dist(second, "no_points-2.0.dist-info", "no-points", "2.0")
    monkeypatch.setattr(sys, "path", [str(first), str(tmp_path / "missing"), str(second)])
    for name in ("odd-name-pkg", "ODD_NAME.PKG", "second_only", "no-points"):
        assert installed.version(name) == metadata.version(name), name
    assert installed.version("odd-name-pkg") == "1.2.post3"  # the first on the path
    for group in ("demo.group", "other"):
        assert [tuple(e) for e in installed.entry_points(group)] == _oracle_points(group), group
    assert [e.name for e in installed.entry_points("demo.group")] == ["CamelCase", "CamelCase", "plain"]


def test_a_damaged_entry_points_file_leaves_the_others(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """One distribution's unreadable entry_points.txt (no section header; not UTF-8) takes only its
    own entry points away: a run's checks still find the others'."""
    _dist(tmp_path, "broken-1.0.dist-info", "broken", "1.0", "name = no.section:here\n")
    _dist(tmp_path, "binary-1.0.dist-info", "binary", "1.0")
    (tmp_path / "binary-1.0.dist-info" / "entry_points.txt").write_bytes(b"[demo.group]\nx = \xff\xfe\n")
    _dist(tmp_path, "fine-2.0.dist-info", "fine", "2.0", "[demo.group]\nok = fine.module:check\n")
    monkeypatch.setattr(sys, "path", [str(tmp_path)])
    good = installed.EntryPoint("ok", "fine.module:check", "demo.group")
    assert installed.entry_points("demo.group") == [good]
    assert installed.version("broken") == "1.0"


def test_an_entry_point_loads_what_it_names() -> None:
    point = installed.EntryPoint("x", "os.path : join", "g")
    assert point.load() is __import__("os").path.join
    assert installed.EntryPoint("m", "json", "g").load() is __import__("json")

