# SPDX-License-Identifier: BSD-2-Clause
"""Every source file of ours names its licence in an SPDX line (issue 33): BSD-2-Clause, as LICENSE
and pyproject say, so a file copied out of the project still says under which terms."""

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TAG = "SPDX-License-Identifier: BSD-2-Clause"
# transcribed from musl (MIT), their licence beside them (controller/fmath-LICENSE.txt)
MIT = {name: "controller/fmath-LICENSE.txt" for name in ("controller/fmath.py", "controller/fmath.h",
                                                                  "controller/fmath_pow.h")}


def _sources() -> list[str]:
    names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    ours = [n for n in names if n.endswith((".py", ".c", ".h", ".sh")) or n in ("Makefile", ".ci/run")]
    # vendored third-party files keep their own licence beside them (fmu_src/cbase/fmi/)
    return [n for n in ours if not list((ROOT / n).parent.glob("LICENSE*"))]


def test_every_source_file_carries_the_spdx_line() -> None:
    sources = _sources()
    assert len(sources) > 100  # the project's own files, listed by git (a clean clone has .git)
    missing = [n for n in sources if (ROOT / n).is_file() and n not in MIT
               and TAG not in "".join((ROOT / n).read_text().splitlines(True)[:3])]
    assert not missing, f"no '{TAG}' in the first three lines of: {', '.join(missing)}"


def test_the_vendored_fmi_headers_keep_their_own_licence() -> None:
    headers = ROOT / "fmu_src" / "cbase" / "fmi"
    assert "Modelica Association" in (headers / "LICENSE.txt").read_text()
    assert not [h.name for h in headers.glob("*.h") if TAG in h.read_text()]


def test_the_vendored_xz_decoder_keeps_its_own_licence() -> None:
    decoder = ROOT / "fmu_src" / "toolchain" / "shim" / "xz"
    assert "Permission to use, copy, modify" in (decoder / "LICENSE").read_text()
    files = sorted([*decoder.glob("*.c"), *decoder.glob("*.h")])
    assert len(files) == 10
    assert not [f.name for f in files if "SPDX-License-Identifier: 0BSD" not in f.read_text().splitlines()[0]]


def test_the_musl_derived_files_say_mit_and_carry_its_notices() -> None:
    for name, licence in MIT.items():
        assert "SPDX-License-Identifier: MIT" in (ROOT / name).read_text().splitlines()[0]
        text = (ROOT / licence).read_text()
        assert "Copyright © 2005-2020 Rich Felker" in text and "Sun Microsystems" in text
        assert "Sun Microsystems" in (ROOT / name).read_text()  # "provided that this notice is preserved"


def test_the_licence_the_lines_name_is_the_projects() -> None:
    assert (ROOT / "LICENSE").read_text().startswith("BSD 2-Clause License")
    text = (ROOT / "pyproject.toml").read_text()
    assert 'license = "BSD-2-Clause AND MIT"' in text and '"controller/fmath-LICENSE.txt"' in text
