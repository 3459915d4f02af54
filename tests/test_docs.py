# SPDX-License-Identifier: BSD-2-Clause
"""The documentation: the README is a short front page whose links resolve, and the MkDocs site
builds with warnings as errors (a broken link, a page missing from the navigation, a docstring
mkdocstrings cannot read all fail it), its generated pages matching the code."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from urllib.parse import urlsplit

import pytest
import yaml
from site_links import check_site

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def test_readme_is_a_front_page() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; the rest belongs in docs/"
    commands = [line for line in lines[:8] if line.startswith("make ")]
    assert [c.split()[1] for c in commands] == ["run", "test"], "the two set-up commands come first"


def test_readme_links_resolve() -> None:
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert targets, "the README links the docs"
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess]:
    """The site built as ``make docs`` builds it, into a temporary folder, and mkdocs' output."""
    folder = tmp_path_factory.mktemp("docs") / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(folder)],
                          cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    return folder, proc


@pytest.mark.system
def test_site_builds_strict(site: tuple[Path, subprocess.CompletedProcess]) -> None:
    folder, proc = site
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-4000:]
    cli = (folder / "reference" / "cli.html").read_text(encoding="utf-8")
    from orchestrator.cli import _parser

    parser = _parser()
    commands = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction").choices
    for name in commands:
        assert f"orchestrate {name}" in cli, f"the CLI reference lacks 'orchestrate {name}'"
    api = (folder / "reference" / "api.html").read_text(encoding="utf-8")
    assert "RunOptions" in api and "stop_time" in api, "the API reference lists RunOptions' fields"
    licence = (folder / "license.html").read_text(encoding="utf-8")
    assert "BSD 2-Clause License" in licence


def nav_pages(entries: list) -> list[str]:
    """The Markdown files of mkdocs.yml's navigation, in order."""
    pages: list[str] = []
    for entry in entries:
        value = next(iter(entry.values())) if isinstance(entry, dict) else entry
        pages += nav_pages(value) if isinstance(value, list) else [value]
    return pages


@pytest.mark.system
def test_site_works_from_the_file_system(site: tuple[Path, subprocess.CompletedProcess]) -> None:
    """Opened as the README says (build/site/index.html, no web server): each page of the
    navigation is a file of its own, every local link names an existing file and an existing
    anchor (no directory listing, no dead link), and nothing but http(s) leaves the site."""
    folder, proc = site
    assert proc.returncode == 0, proc.stderr[-4000:]
    config = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=yaml.BaseLoader)
    pages = nav_pages(config["nav"])
    missing = [p for p in pages if not (folder / p).with_suffix(".html").is_file()]
    assert not missing, f"navigation pages not built as files: {missing}"
    for template in ("github-actions.yml", "gitlab-ci.yml"):  # linked from regression.md
        assert (folder / "ci" / template).read_bytes() == (ROOT / "docs" / "ci" / template).read_bytes()
    check = check_site(folder)
    print(check.summary())
    assert check.problems == [], "\n".join(check.problems[:50]) + "\n" + check.summary()
    assert check.pages >= len(pages) and check.local > 20 * check.pages and check.anchors > 0
    assert {urlsplit(u).scheme for u in check.external} <= {"http", "https"}


def test_link_check_finds_each_kind_of_broken_link(tmp_path: Path) -> None:
    """The check on a hand-made site with one link of each kind, broken or not."""
    (tmp_path / "guide").mkdir()
    (tmp_path / "guide" / "page.html").write_text('<h2 id="a-b">x</h2><a name="old">y</a>')
    (tmp_path / "data.yml").write_text("x: 1\n")
    links = ["guide/page.html", "guide/page.html#a-b", "guide/page.html#old", "#top", "data.yml",
             "guide/page.html?q=1", "https://example.org/", "guide/",
             "guide/page.html#nowhere", "gone.html", "/guide/page.html", "file:///etc/passwd",
             "mailto:someone@example.org", "../outside.html", "data.yml#x", "//example.org/x.js"]
    (tmp_path / "index.html").write_text('<body id="top"><img src="data.yml">'
                                         + "".join(f'<a href="{link}">l</a>' for link in links))
    (tmp_path / "404.html").write_text('<a href="/guide/page.html#a-b">ok</a><a href="/guide/">dir</a>')
    check = check_site(tmp_path)
    assert (check.pages, check.local, check.anchors) == (3, 18, 6)
    assert check.external == ["https://example.org/"]
    assert check.problems == [
        "404.html: guide/: a directory, not a page",
        "index.html: guide/: a directory, not a page",
        "index.html: guide/page.html#nowhere: no #nowhere in guide/page.html",
        "index.html: gone.html: no such file",
        "index.html: /guide/page.html: leaves the site",
        "index.html: file:///etc/passwd: leaves the site",
        "index.html: mailto:someone@example.org: leaves the site",
        "index.html: ../outside.html: outside the site",
        "index.html: data.yml#x: no #x in data.yml",
        "index.html: //example.org/x.js: leaves the site",
    ]
