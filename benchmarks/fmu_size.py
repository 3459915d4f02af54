# SPDX-License-Identifier: BSD-2-Clause
"""What an FMU weighs and what its size costs a host at start-up (issue 46).

    python benchmarks/fmu_size.py [--before CHECKOUT] [--repeat N]

For this checkout's ``build/`` (and ``--before``'s, another checkout built with its own
``orchestrate build``, whose package then exports its container):

* the size of every FMI 2.0 FMU, and of FixedTimeController.fmu part by part (deflated bytes in
  the archive: each platform's interpreter, standard-library zip, extension modules, ...);
* the exported example1 container (``orchestrate export example1``, the build's SSP);
* start-up, CPU seconds (user + system, the process and its children; median of ``--repeat``) of
  a one-step run: fmusim on FixedTimeController.fmu (no Python: the FMU's own runtime) and on the
  exported container, FMPy (``simulate_fmu``, in its Python) on FixedTimeController.fmu, and
  libcosim (libcosimpy, if installed) on example1.ssp. Each host unpacks the FMUs it is given.
"""

from __future__ import annotations

import argparse
import collections
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PYTHON = REPO / ".venv" / "bin" / "python"
FMUSIM = REPO.parent / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
MODEL = "FixedTimeController"
STEP = "0.001"
FMPY = ("import sys, fmpy; "
        "fmpy.simulate_fmu(sys.argv[1], stop_time=float(sys.argv[2]), output_interval=float(sys.argv[2]))")
LIBCOSIM = """
import sys
from libcosimpy import CosimLogging
from libcosimpy.CosimExecution import CosimExecution
CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
if not CosimExecution.from_ssp_file(sys.argv[1]).simulate_until(round(float(sys.argv[2]) * 1e9)):
    sys.exit("libcosim failed")
"""


def part(name: str) -> str:
    """The group of an archive member (``binaries/linux64/python/lib`` ...)."""
    parts = name.split("/")
    if name.startswith("binaries/") and "python" in parts:
        return "/".join(parts[:4])
    return "/".join(parts[:3] if name.startswith("binaries/") else parts[:2])


def parts(fmu: Path) -> dict[str, int]:
    """Deflated bytes per group of ``fmu``'s members, largest first."""
    sizes: dict[str, int] = collections.Counter()
    with zipfile.ZipFile(fmu) as archive:
        for info in archive.infolist():
            sizes[part(info.filename)] += info.compress_size
    return dict(sorted(sizes.items(), key=lambda item: -item[1]))


def cpu(command: Sequence[str], cwd: Path) -> float:
    """CPU seconds of ``command`` run to completion in ``cwd`` (its children included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, check=True, cwd=cwd, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def export(checkout: Path, target: Path) -> Path:
    """example1 exported as one FMU from ``checkout``'s built SSP, by that checkout's exporter
    (another checkout's as it was built: 633067d's Makefile compiles an extension after packing
    the archives, which its stale-build check then refuses)."""
    command = [str(PYTHON), "-m", "orchestrator", "export", str(checkout / "build" / "ssp" / "example1.ssp"),
               "-o", str(target), "--quiet", *(["--allow-stale"] if checkout.resolve() != REPO else [])]
    subprocess.run(command, check=True, cwd=checkout, env={**os.environ, "PYTHONPATH": str(checkout)})
    return target


def startup(build: Path, container: Path, repeat: int, tmp: Path) -> dict[str, float]:
    """Median CPU seconds of one-step runs in each host."""
    fmu = build / "fmus" / f"{MODEL}.fmu"
    commands = {}
    if FMUSIM.is_file():
        fmusim = [str(FMUSIM), "--interface-type", "cs", "--stop-time", STEP, "--output-interval", STEP]
        commands[f"fmusim, {MODEL}.fmu"] = [*fmusim, "--output-file", str(tmp / "a.csv"), str(fmu)]
        commands["fmusim, example1 container"] = [*fmusim, "--output-file", str(tmp / "b.csv"),
                                                  str(container)]
    commands[f"FMPy, {MODEL}.fmu"] = [str(PYTHON), "-c", FMPY, str(fmu), STEP]
    if subprocess.run([str(PYTHON), "-c", "import libcosimpy"], capture_output=True).returncode == 0:
        ssp = build / "ssp" / "example1.ssp"
        commands["libcosim, example1.ssp"] = [str(PYTHON), "-c", LIBCOSIM, str(ssp), STEP]
    return {label: statistics.median(cpu(command, tmp) for _ in range(repeat))
            for label, command in commands.items()}


def measure(checkout: Path, repeat: int, tmp: Path) -> dict[str, float]:
    """Every figure of ``checkout``'s build (MB, or CPU seconds for start-up)."""
    build = checkout / "build"
    fmus = sorted((build / "fmus").glob("*.fmu"))
    figures = {f"{fmu.stem}.fmu, MB": fmu.stat().st_size / 1e6 for fmu in fmus}
    figures |= {f"  {name}, MB": size / 1e6
                for name, size in parts(build / "fmus" / f"{MODEL}.fmu").items() if size > 20_000}
    container = export(checkout, tmp / "example1.fmu")
    figures["example1 exported container, MB"] = container.stat().st_size / 1e6
    starts = startup(build, container, repeat, tmp)
    figures |= {f"start-up CPU s, {label}": value for label, value in starts.items()}
    return figures


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, metavar="CHECKOUT")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    checkouts = ({"before": args.before} if args.before else {}) | {"now": REPO}
    results = {}
    for label, checkout in checkouts.items():
        with tempfile.TemporaryDirectory(prefix="fmu_size-") as tmp:
            results[label] = measure(checkout, args.repeat, Path(tmp))
    before = f" --before {args.before}" if args.before else ""
    print(f"python benchmarks/fmu_size.py --repeat {args.repeat}{before}")
    rows = list(dict.fromkeys(row for figures in results.values() for row in figures))
    print(f"{'':60s}" + "".join(f"{label:>10s}" for label in results))
    for row in rows:
        cells = (f"{r[row]:10.3f}" if row in r else f"{'-':>10s}" for r in results.values())
        print(f"{row:60s}" + "".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
