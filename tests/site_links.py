# SPDX-License-Identifier: BSD-2-Clause
"""Every link of a built documentation site, checked as a browser opening it from the file system
follows it: a local link names an existing file (a directory shows as a listing, not a page), its
``#fragment`` is an id of that page, and nothing but http(s) leaves the site (external links are
counted, not fetched). The links are those lxml.html finds (``iterlinks``: href, src, CSS url()).

``python tests/site_links.py build/site`` prints the counts and every problem (exit 1 if any).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlsplit

import lxml.html

# Served by a web server for a missing URL at any depth, so its links are root-absolute by design
# (MkDocs writes them so without a site_url); they are checked against the site's root.
NOT_FOUND_PAGE = "404.html"


@dataclass
class LinkCheck:
    """The counts of one site's check and its problems, one line each (page, link, what is wrong)."""

    pages: int = 0
    local: int = 0
    anchors: int = 0
    external: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line: the counts."""
        return (f"{self.pages} pages, {self.local} local links ({self.anchors} with an anchor), "
                f"{len(self.external)} external ({len(set(self.external))} distinct), "
                f"{len(self.problems)} problems")


def _ids(page: Path, cache: dict[Path, set[str]]) -> set[str]:
    """The fragments a page has: its elements' ids and its anchors' names."""
    if page not in cache:
        root = lxml.html.parse(str(page)).getroot()
        cache[page] = set(root.xpath("//@id")) | set(root.xpath("//a/@name"))
    return cache[page]


def check_site(site: Path) -> LinkCheck:
    """Check every link of every HTML file under ``site``."""
    site = site.resolve()
    result = LinkCheck()
    ids: dict[Path, set[str]] = {}
    for page in sorted(site.rglob("*.html")):
        result.pages += 1
        name = page.relative_to(site).as_posix()
        for _, _, link, _ in lxml.html.parse(str(page)).getroot().iterlinks():
            parts = urlsplit(link)
            if parts.scheme in ("http", "https"):
                result.external.append(link)
                continue
            result.local += 1
            base = page.parent
            if name == NOT_FOUND_PAGE and link.startswith("/") and not link.startswith("//"):
                base, link = site, link.lstrip("/")
                parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("/"):
                result.problems.append(f"{name}: {link}: leaves the site")
                continue
            target = (base / unquote(parts.path)).resolve() if parts.path else page
            if not target.is_relative_to(site):
                result.problems.append(f"{name}: {link}: outside the site")
            elif target.is_dir():
                result.problems.append(f"{name}: {link}: a directory, not a page")
            elif not target.is_file():
                result.problems.append(f"{name}: {link}: no such file")
            elif parts.fragment:
                result.anchors += 1
                if target.suffix != ".html" or unquote(parts.fragment) not in _ids(target, ids):
                    result.problems.append(f"{name}: {link}: no #{parts.fragment} in "
                                           f"{target.relative_to(site).as_posix()}")
    return result


if __name__ == "__main__":
    check = check_site(Path(sys.argv[1]))
    print(*check.problems, check.summary(), sep="\n")
    sys.exit(1 if check.problems else 0)
