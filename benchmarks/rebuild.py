# SPDX-License-Identifier: BSD-2-Clause
"""What ``orchestrate build`` costs after editing one model file, against a cold build.

    python benchmarks/rebuild.py [--files fmu_src/models/plants.py fmu_src/models/actuator.py]
        [--before CHECKOUT]

For this checkout (and ``--before``, another checkout with its own ``.venv`` and ``build/runtime``)
the sources (``controller``, ``fmu_src``, ``orchestrator``, ``ssp``) are copied to a temporary
folder with the runtimes' downloads (``build/runtime/debs``, ``build/runtime/win64/dists``; nothing
unpacked, compiled or cached),
and built there with that checkout's Python, as ``make build`` does (every FMU, its FMI 3.0 variant
and every scenario archive):

* cold: the first build;
* unchanged: the same build again (``make build`` after touching a file without changing it);
* after editing each of ``--files`` (a comment line appended), one after the other: the build again.

Figures are CPU seconds (user + system) of the build process and its children (``os.wait4``),
not wall time: the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SOURCES = ("controller", "fmu_src", "orchestrator", "ssp", "pyproject.toml")


def prepare(checkout: Path, dest: Path) -> None:
    """A copy of ``checkout``'s sources and fetched runtime in ``dest``."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in SOURCES:
        source = checkout / name
        if source.is_dir():
            shutil.copytree(source, dest / name, ignore=ignore)
        else:
            shutil.copy2(source, dest / name)
    runtime = checkout / "build" / "runtime"
    for part in ("debs", "win64/dists"):  # the downloads only: unpacking, compiling, deflating count
        if (runtime / part).is_dir():
            shutil.copytree(runtime / part, dest / "build" / "runtime" / part, symlinks=True)


def build(checkout: Path, folder: Path) -> float:
    """CPU seconds of ``orchestrate build`` of the copy in ``folder`` with ``checkout``'s Python."""
    command = [str(checkout / ".venv" / "bin" / "python"), "-m", "orchestrator", "build", "--sources", "ssp",
               "--dest", "build"]
    env = {**os.environ, "PYTHONPATH": str(folder)}
    process = subprocess.Popen(command, cwd=folder, env=env, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(process.pid, 0)
    if os.waitstatus_to_exitcode(status):
        raise SystemExit(f"the build in {folder} failed")
    return usage.ru_utime + usage.ru_stime


def measure(checkout: Path, files: Sequence[str]) -> dict[str, float]:
    with tempfile.TemporaryDirectory(prefix="rebuild-") as tmp:
        folder = Path(tmp)
        prepare(checkout, folder)
        figures = {"cold": build(checkout, folder), "unchanged": build(checkout, folder)}
        for name in files:
            with (folder / name).open("a", encoding="utf-8") as source:
                source.write("\n# edited by benchmarks/rebuild.py\n")
            figures[f"after editing {name}"] = build(checkout, folder)
    return figures


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--files", nargs="+",
                        default=["fmu_src/models/plants.py", "fmu_src/models/actuator.py"])
    parser.add_argument("--before", type=Path, metavar="CHECKOUT")
    args = parser.parse_args(argv)
    checkouts = {"now": REPO} | ({"before": args.before} if args.before is not None else {})
    results = {label: measure(checkout, args.files) for label, checkout in checkouts.items()}
    print("orchestrate build, CPU s (user + system, the build and its children); % of the cold build")
    labels = list(next(iter(results.values())))
    print(f"{'':45s}" + "".join(f"{label:>18s}" for label in results))
    for row in labels:
        cells = "".join(f"{r[row]:9.1f} s {100 * r[row] / r['cold']:4.0f} %" for r in results.values())
        print(f"{row:45s}{cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
