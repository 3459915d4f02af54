# SPDX-License-Identifier: BSD-2-Clause
"""What ``orchestrate validate`` costs: against a 1 s run of the same file, and against the number of
variables an FMU declares.

    python benchmarks/validate_cost.py [--scenario PATH ...] [--variables 1000 10000 100000]
        [--repeat 3] [--before SRC]

* ratio: for each ``--scenario`` (default: the OSP demo case dp-ship when a copy is at
  ``$DEMO_CASES/dp-ship``, and libcosim's demo in ``tests/ssp_conformance``), the CPU (user +
  system, ``os.wait4``) of ``orchestrate validate`` and of ``orchestrate run --stop-time 1``, as
  whole processes, and validate / run;
* scaling: the Reference FMU Feedthrough with N extra local Real variables named ``block.x[i]``
  and ``variableNamingConvention="structured"`` (every name must be checked against FMI's grammar),
  in a one-component scenario: validate's CPU for each N, and the CPU per 1000 variables, which
  stays flat when validate is linear;
* ``--before SRC``: a folder holding an older ``orchestrator`` package (``git archive REV
  orchestrator | tar -x -C SRC``), measured the same way in the same alternation.

Medians of ``--repeat`` processes; one untimed validate first fills the FMU cache. CPU times, not
wall times: the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))
from ssd_text import feedthrough  # noqa: E402  (the tests' frame of a hand-written SSD)

REFERENCE_FMUS = REPO.parent / "shared" / "tools" / "reference-fmus" / "2.0"
LIBCOSIM_DEMO = REPO / "tests" / "ssp_conformance" / "libcosim" / "ssp" / "demo"
SSD = feedthrough("wide", 1, "resources/Wide.fmu")


def cpu(args: Sequence[str], before: Path | None = None) -> float:
    """CPU seconds (user + system) of ``python -m orchestrator ARGS`` as one process."""
    env = dict(os.environ)
    if before is not None:
        env["PYTHONPATH"] = str(before)
    # run outside this checkout: ``-m`` puts the working directory first on sys.path
    process = subprocess.Popen([sys.executable, "-m", "orchestrator", *args], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, env=env, cwd=tempfile.gettempdir())
    _, _, usage = os.wait4(process.pid, 0)
    return usage.ru_utime + usage.ru_stime


def median_cpu(args: Sequence[str], repeat: int, before: Path | None = None) -> float:
    return statistics.median(cpu(args, before) for _ in range(repeat))


def wide_scenario(folder: Path, n: int) -> Path:
    """A scenario whose one FMU (Feedthrough) declares ``n`` more variables, structured names."""
    with zipfile.ZipFile(REFERENCE_FMUS / "Feedthrough.fmu") as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
    xml = members["modelDescription.xml"].decode()
    local = 'causality="local" variability="continuous" initial="calculated"'
    extra = "".join(f'    <ScalarVariable name="block.x[{i}]" valueReference="{100000 + i}" {local}><Real/>'
                    '</ScalarVariable>\n' for i in range(1, n + 1))
    xml = xml.replace("<fmiModelDescription", '<fmiModelDescription variableNamingConvention="structured"',
                      1)
    xml = re.sub(r"(\s*</ModelVariables>)", "\n" + extra.rstrip("\n") + r"\1", xml, count=1)
    members["modelDescription.xml"] = xml.encode()
    (folder / "resources").mkdir(parents=True)
    with zipfile.ZipFile(folder / "resources" / "Wide.fmu", "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    (folder / "SystemStructure.ssd").write_text(SSD)
    return folder


def scenarios(given: Sequence[str]) -> list[tuple[Path, list[str]]]:
    """The scenarios of the ratio and the options each needs."""
    if given:
        return [(Path(s).resolve(), []) for s in given]
    found = [(LIBCOSIM_DEMO, ["--root", str(LIBCOSIM_DEMO.parents[1])])]
    demo = Path(os.environ.get("DEMO_CASES", "")) / "dp-ship"
    if os.environ.get("DEMO_CASES") and demo.is_dir():
        found.insert(0, (demo, []))
    return found


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", nargs="*", default=[])
    parser.add_argument("--variables", nargs="*", type=int, default=[1000, 10000, 100000])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--before", type=Path)
    args = parser.parse_args(argv)
    versions = [("after", None)] + ([("before", args.before)] if args.before else [])
    print("| scenario | version | validate CPU s | run 1 s CPU s | validate / run |")
    print("|---|---|---|---|---|")
    for scenario, extra in scenarios(args.scenario):
        for label, before in versions:
            cpu(["validate", str(scenario), *extra], before)  # fills the FMU cache
            validate = median_cpu(["validate", str(scenario), *extra], args.repeat, before)
            run = median_cpu(["run", str(scenario), *extra, "--stop-time", "1", "--no-plot", "--output",
                              os.devnull, "--allow-stale"], args.repeat, before)
            print(f"| {scenario.name} | {label} | {validate:.2f} | {run:.2f} | {validate / run:.1f} |",
                  flush=True)
    print()
    print("| variables | version | validate CPU s | per 1000 variables ms |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="validate-cost-") as tmp:
        for n in args.variables:
            folder = wide_scenario(Path(tmp) / str(n), n)
            for label, before in versions:
                cpu(["validate", str(folder)], before)
                seconds = median_cpu(["validate", str(folder)], args.repeat, before)
                print(f"| {n} | {label} | {seconds:.2f} | {1000 * 1000 * seconds / n:.1f} |", flush=True)
            shutil.rmtree(folder)


if __name__ == "__main__":
    main()
