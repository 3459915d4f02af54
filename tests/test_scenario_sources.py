# SPDX-License-Identifier: BSD-2-Clause
"""The committed scenario sources are exactly what ``ssp/generate.py`` writes from the examples'
data (``fmu_src/models/examples.py``): edit the data and regenerate, never the XML alone."""

from __future__ import annotations

import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def test_committed_sources_are_generated(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("ssp_generate", REPO / "ssp" / "generate.py")
    generate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generate)
    generate.main(tmp_path)
    written = {p.relative_to(tmp_path): p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    committed = {p.relative_to(REPO / "ssp"): p.read_bytes()
                 for p in sorted((REPO / "ssp").rglob("*")) if p.is_file() and p.suffix in (".ssd", ".ssv")}
    assert sorted(written) == sorted(committed)
    stale = [str(name) for name in written if written[name] != committed[name]]
    assert not stale, f"regenerate with 'python ssp/generate.py': {stale}"
