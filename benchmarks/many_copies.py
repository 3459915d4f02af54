# SPDX-License-Identifier: BSD-2-Clause
"""The same FMUs used many times: N copies of a scenario's loop in one system, against libcosim.

    python benchmarks/many_copies.py [--scenario example1] [--copies 1 16] [--repeat 3]
        [--stop-time 2] [--before CHECKOUT]

For each N, the scenario's SSD (``build/ssp/<scenario>.ssp``, run ``make build`` first) is written
with every component and connection N times (``reference_3``, ``plant_3`` ...; the same FMU files
and parameter files), packed once into a temporary folder, and run as whole processes one after
the other in alternation (ours, libcosim, ours ...):

* start-up: a run of one step (``orchestrate run --no-plot --output /dev/null``; libcosim:
  ``from_ssp_file``, serial, no observer): CPU (user + system) and peak RSS of the process,
  read by its own small parent (``benchmarks/rusage_of.c``: a child's peak RSS starts at its
  parent's, and this Python process is 44 MB);
* per step: ``--stop-time`` seconds, ``(CPU of the run - CPU of the start-up) / steps / N``: the
  cost of one copy's step, which should not grow with N;
* with ``--before CHECKOUT`` (another checkout with its own ``.venv``): that revision's
  ``orchestrate run`` on the same archive, in the same alternation.

Medians of ``--repeat`` processes; one untimed run of each first fills the FMU cache. CPU times,
not wall times: the machine may be shared.
"""

from __future__ import annotations

import argparse
import copy
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path

from lxml import etree

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "benchmarks"))
from end_to_end import as_a_user_runs  # noqa: E402 - the benchmarks share it

SSD = "SystemStructure.ssd"
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}
LIBCOSIM = """
import sys
from libcosimpy import CosimLogging
from libcosimpy.CosimExecution import CosimExecution
CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
execution = CosimExecution.from_ssp_file(sys.argv[1])
if not execution.simulate_until(round(float(sys.argv[2]) * 1e9)):
    sys.exit("libcosim failed")
"""


def copies(archive: Path, n: int, dest: Path) -> Path:
    """``archive`` with its system's components and connections written ``n`` times (suffix
    ``_<i>``), the same member files; returns the new archive."""
    with zipfile.ZipFile(archive) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist() if not i.is_dir()}
    root = etree.fromstring(members[SSD])
    system = root.find("ssd:System", NS)
    elements, connections = system.find("ssd:Elements", NS), system.find("ssd:Connections", NS)
    components = list(elements)
    links = list(connections) if connections is not None else []
    for i in range(2, n + 1):
        for c in components:
            twin = copy.deepcopy(c)
            twin.set("name", f"{c.get('name')}_{i}")
            elements.append(twin)
        for link in links:
            twin = copy.deepcopy(link)
            for end in ("startElement", "endElement"):
                if twin.get(end):
                    twin.set(end, f"{twin.get(end)}_{i}")
            connections.append(twin)
    members[SSD] = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    target = dest / f"{archive.stem}_x{n}.ssp"
    with zipfile.ZipFile(target, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data, zipfile.ZIP_STORED if name.endswith(".fmu") else zipfile.ZIP_DEFLATED)
    return target


def rusage_of(folder: Path) -> Path:
    """benchmarks/rusage_of.c compiled into ``folder``: the process that forks each measured one."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if compiler is None:
        raise SystemExit("no C compiler for benchmarks/rusage_of.c")
    target = folder / "rusage_of"
    subprocess.run([compiler, "-O2", "-o", str(target), str(REPO / "benchmarks" / "rusage_of.c")], check=True)
    return target


def timed(command: Sequence[str], cwd: Path, meter: Path) -> tuple[float, float]:
    """CPU seconds (user + system) and peak RSS (MB) of one process run to completion, measured by
    ``meter`` (rusage_of), its small parent: read here from this 44 MB process, a child's peak RSS
    starts at this process's (before: /bin/true measured 44.4 MB, and 16 copies 1.46x libcosim)."""
    with tempfile.NamedTemporaryFile("r", dir=cwd, suffix=".rusage") as out:
        status = subprocess.run([str(meter), out.name, *command], cwd=cwd,
                                stdout=subprocess.DEVNULL).returncode
        if status:
            raise SystemExit(f"failed ({status}): {' '.join(command)}")
        peak_kb, cpu = out.read().split()
    return float(cpu), int(peak_kb) / 1024


def commands(archive: Path, stop: float, before: Path | None) -> dict[str, list[str]]:
    def ours(checkout: Path) -> list[str]:
        return [str(checkout / ".venv" / "bin" / "orchestrate"), "run", str(archive), "--quiet", "--no-plot",
                "--output", os.devnull, "--stop-time", repr(stop)]

    found = {"ours": ours(REPO)}
    if before is not None:
        found["before"] = ours(before)
    found["libcosim"] = [sys.executable, "-c", LIBCOSIM, str(archive), repr(stop)]
    return found


def measure(archive: Path, step: float, stop: float, repeat: int, before: Path | None,
            cwd: Path, meter: Path) -> dict[str, dict[str, float]]:
    """Median start-up CPU, peak RSS and run CPU per label."""
    runs = {f"{label} {kind}": command for kind, t in (("start-up", step), ("run", stop))
            for label, command in commands(archive, t, before).items()}
    for command in runs.values():
        timed(command, cwd, meter)  # untimed: fills the FMU cache, warms the page cache
    samples: dict[str, list[tuple[float, float]]] = {k: [] for k in runs}
    for _ in range(repeat):
        for label, command in runs.items():
            samples[label].append(timed(command, cwd, meter))
    return {label: {"cpu": statistics.median(c for c, _ in v), "rss": statistics.median(r for _, r in v)}
            for label, v in samples.items()}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="example1")
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 16])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--stop-time", type=float, default=2.0)
    parser.add_argument("--step", type=float, default=1e-3)
    parser.add_argument("--before", type=Path, metavar="CHECKOUT")
    args = parser.parse_args(argv)
    as_a_user_runs()
    archive = REPO / "build" / "ssp" / f"{args.scenario}.ssp"
    if not archive.is_file():
        parser.error(f"{archive} does not exist: run 'make build' first")
    steps = round(args.stop_time / args.step)
    print(f"{args.scenario}, N copies in one system; start-up = one step; per step: {steps} steps, "
          "CPU per step per copy; medians of the alternating processes")
    print(f"{'N':>3s} {'who':10s} {'start-up CPU s':>15s} {'peak RSS MB':>12s} {'CPU us/step/copy':>17s}")
    with tempfile.TemporaryDirectory() as tmp:
        meter = rusage_of(Path(tmp))
        bare = timed(["/bin/true"], Path(tmp), meter)[1]
        print(f"    (/bin/true measured so: {bare:.1f} MB; this process: "
              f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.1f} MB)")
        for n in args.copies:
            scenario = copies(archive, n, Path(tmp))
            figures = measure(scenario, args.step, args.stop_time, args.repeat, args.before, Path(tmp), meter)
            for who in [k.removesuffix(" run") for k in figures if k.endswith(" run")]:
                start, run = figures[f"{who} start-up"], figures[f"{who} run"]
                per_step = (run["cpu"] - start["cpu"]) / steps / n * 1e6
                print(f"{n:3d} {who:10s} {start['cpu']:15.3f} {start['rss']:12.1f} {per_step:17.2f}")
            ours, lib = figures["ours start-up"], figures["libcosim start-up"]
            print(f"    ours / libcosim: start-up CPU {ours['cpu'] / lib['cpu']:.2f}, peak RSS "
                  f"{ours['rss'] / lib['rss']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
