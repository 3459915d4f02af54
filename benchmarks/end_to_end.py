# SPDX-License-Identifier: BSD-2-Clause
"""End to end, as a user runs it: ``orchestrate run`` against libcosim on the same archive.

    python benchmarks/end_to_end.py [--scenarios example1 pendulum] [--repeat 5] [--stop-time 30]
        [--before CHECKOUT] [--no-others]

For each built scenario (``build/ssp/<name>.ssp``, run ``make build`` first) this times whole
processes, started one after the other in alternation (ours, libcosim, ours, ...), so that a
change of the machine's load hits both alike:

* ``orchestrate run`` with the full CSV (every column, every step), with ``--output /dev/null``
  and with ``--output-interval STOP`` (a CSV of two rows): the ways the CLI writes nothing;
* libcosim (libcosimpy) reading the archive's own algorithm (``from_ssp_file(path)``: its
  ``FixedStepAlgorithm`` with ``numWorkerThreads="0"``, serial), with its file observer writing
  every variable of every FMU to CSV, and with no observer;
* fmusim (the Modelica Association's reference importer, ``../shared/tools/fmusim``) and FMPy
  (``simulate_fmu`` in this checkout's Python, every output recorded in memory at every step) on
  the scenario exported as one FMU (``orchestrate export``: the same FMUs, connections and grid
  inside a C container), as users of those tools run an SSP they cannot read; fmusim writes every
  output to CSV;
* start-up: each with a stop time of one step;
* with ``--before CHECKOUT`` (another checkout of this repository with its own ``make build``):
  that revision's ``orchestrate run`` on its own build of the scenario, in the same alternation.

Each figure is the median of ``--repeat`` processes: wall time (``perf_counter`` around the
process) and CPU time (user + system of the process and its children, ``getrusage``). The CPU per
step is ``(CPU of the whole run - CPU of the one-step run) / steps``. Ratios are ours / libcosim's
from the same run. Before timing, one untimed run of each fills the FMU cache
(:mod:`orchestrator.fmucache`); the first run on a machine (cache empty, ``ORCHESTRATE_CACHE``
pointing at a new folder) is timed separately, once.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FMUSIM = REPO.parent / "shared" / "tools" / "fmusim" / "bin" / "fmusim"
FMPY = ("import sys, fmpy; fmpy.simulate_fmu(sys.argv[1], stop_time=float(sys.argv[2]), "
        "output_interval=float(sys.argv[3]))")

LIBCOSIM = """
import sys
from libcosimpy import CosimLogging
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimObserver import CosimObserver
CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
execution = CosimExecution.from_ssp_file(sys.argv[1])
if sys.argv[3]:
    observer = CosimObserver.create_to_dir(sys.argv[3])
    execution.add_observer(observer)
if not execution.simulate_until(round(float(sys.argv[2]) * 1e9)):
    sys.exit("libcosim failed")
"""


def as_a_user_runs() -> None:
    """Let the processes timed write their bytecode, as a user's first run does. Where
    PYTHONDONTWRITEBYTECODE is set (this machine's shells set it), the untimed first run wrote
    none, and every timed run compiled each module changed since the last written ``.pyc`` again:
    16 copies of example1 measured 49.0 MB instead of 48.0 MB after four engine modules changed."""
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


def timed(command: Sequence[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[float, float]:
    """Run ``command`` to completion in ``cwd`` (a neutral folder: ``python -m`` children of an
    older checkout must not import this checkout's package); its wall and CPU seconds (children's
    user + system)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL, cwd=cwd)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def step_of(archive: Path) -> float:
    """The communication step the archive's SSD gives."""
    from orchestrator import open_system

    with open_system(archive) as system:
        step = system.structure.experiment.step
    if step is None:
        raise SystemExit(f"{archive}: no step annotation")
    return step


def export(archive: Path, target: Path) -> Path:
    """``archive`` exported as one FMU by this checkout (``orchestrate export``)."""
    subprocess.run([str(REPO / ".venv" / "bin" / "orchestrate"), "export", str(archive), "-o", str(target),
                    "--quiet"], check=True, cwd=target.parent)
    return target


def commands(archive: Path, stop: float, out: Path, before: Path | None, h: float,
             container: Path | None) -> dict[str, list[str]]:
    """The timed command lines, by label (fmusim and FMPy on ``container``, if given)."""
    def run(checkout: Path, scenario: Path) -> list[str]:
        return [str(checkout / ".venv" / "bin" / "orchestrate"), "run", str(scenario), "--quiet", "--no-plot",
                "--stop-time", repr(stop)]

    def variants(who: str, command: list[str]) -> dict[str, list[str]]:
        return {f"{who}, CSV": [*command, "--output", str(out / f"{who}.csv")],
                f"{who}, /dev/null": [*command, "--output", os.devnull],
                f"{who}, 2 rows": [*command, "--output", str(out / f"{who}-2.csv"), "--output-interval",
                                   repr(stop)]}

    lib = [sys.executable, "-c", LIBCOSIM, str(archive), repr(stop)]
    labels = variants("ours", run(REPO, archive))
    if before is not None:
        labels.update(variants("before", run(before, before / "build" / "ssp" / archive.name)))
    labels.update({"libcosim, CSV": [*lib, str(out / "libcosim")], "libcosim, none": [*lib, ""]})
    if container is not None:
        if FMUSIM.is_file():
            labels["fmusim, CSV"] = [str(FMUSIM), "--interface-type", "cs", "--stop-time", repr(stop),
                                     "--output-interval", repr(h), "--output-file", str(out / "fmusim.csv"),
                                     str(container)]
        labels["FMPy, in memory"] = [sys.executable, "-c", FMPY, str(container), repr(stop), repr(h)]
    return labels


def measure(archive: Path, stop: float, repeat: int, before: Path | None,
            others: bool) -> dict[str, tuple[float, float]]:
    """Median (wall, CPU) per label for the whole run and for one step (labels ending in
    ``start-up``), alternating the processes; with ``others``, fmusim and FMPy on the export."""
    h = step_of(archive)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        container = export(archive, out / f"{archive.stem}.fmu") if others else None
        runs = {**commands(archive, stop, out, before, h, container),
                **{f"{k} start-up": v for k, v in commands(archive, h, out, before, h, container).items()}}
        for command in runs.values():  # untimed: fills the FMU cache, warms the page cache
            timed(command, out)
        samples: dict[str, list[tuple[float, float]]] = {k: [] for k in runs}
        for _ in range(repeat):
            for label, command in runs.items():
                samples[label].append(timed(command, out))
    return {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
            for k, v in samples.items()}


def cold_start(archive: Path) -> float:
    """Wall seconds of a one-step run with an empty FMU cache (a machine's first run)."""
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "ORCHESTRATE_CACHE": cache}
        command = [str(REPO / ".venv" / "bin" / "orchestrate"), "run", str(archive), "--quiet", "--no-plot",
                   "--stop-time", repr(step_of(archive)), "--output", str(Path(tmp, "r.csv"))]
        return timed(command, Path(tmp), env)[0]


def report(name: str, stop: float, steps: int, figures: dict[str, tuple[float, float]], cold: float) -> None:
    """Print one scenario's table."""
    print(f"\n{name}: {stop:g} s, {steps} steps (median of the alternating processes)")
    print(f"{'':18s} {'wall s':>8s} {'CPU s':>8s} {'start-up wall':>14s} {'start-up CPU':>13s} "
          f"{'CPU us/step':>12s} {'/ libcosim':>11s}")

    def per_step(label: str) -> float:
        return (figures[label][1] - figures[f"{label} start-up"][1]) / steps * 1e6

    for label in [k for k in figures if not k.endswith("start-up")]:
        wall, cpu = figures[label]
        start_wall, start_cpu = figures[f"{label} start-up"]
        base = "libcosim, CSV" if label.endswith("CSV") else "libcosim, none"
        print(f"{label:18s} {wall:8.3f} {cpu:8.3f} {start_wall:14.3f} {start_cpu:13.3f} "
              f"{per_step(label):12.1f} {per_step(label) / per_step(base):11.2f}")
    ratio = figures["ours, CSV"][0] / figures["libcosim, CSV"][0]
    bare = figures["ours, CSV"][0] / figures["libcosim, none"][0]
    print(f"wall ratio ours/libcosim, both with full CSV: {ratio:.2f}; ours with CSV / libcosim with no "
          f"output: {bare:.2f}; start-up ours/libcosim: "
          f"{figures['ours, CSV start-up'][0] / figures['libcosim, none start-up'][0]:.2f}")
    if "before, CSV" in figures:
        print(f"wall ratio before/libcosim, both with full CSV: "
              f"{figures['before, CSV'][0] / figures['libcosim, CSV'][0]:.2f}")
    print("CPU per step / libcosim's: writing CSV against its CSV, writing nothing against no observer")
    for host in ("fmusim, CSV", "FMPy, in memory"):
        if host in figures:
            own = per_step(host)
            print(f"CPU per step, ours / {host.split(',')[0]}: with CSV {per_step('ours, CSV') / own:.2f}, "
                  f"writing nothing {per_step('ours, /dev/null') / own:.2f}")
    print(f"first run on a machine (empty FMU cache), start-up wall: {cold:.3f} s")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=["example1", "pendulum"])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stop-time", type=float, default=30.0)
    parser.add_argument("--before", type=Path, metavar="CHECKOUT",
                        help="another checkout (with its .venv and build/) to time beside this one")
    parser.add_argument("--no-others", dest="others", action="store_false",
                        help="leave out fmusim and FMPy on the exported scenario")
    args = parser.parse_args(argv)
    as_a_user_runs()
    if args.before is not None and not (args.before / ".venv" / "bin" / "orchestrate").is_file():
        parser.error(f"{args.before}: no .venv/bin/orchestrate (run 'make build' there)")
    for name in args.scenarios:
        archive = REPO / "build" / "ssp" / f"{name}.ssp"
        if not archive.is_file():
            parser.error(f"{archive} does not exist: run 'make build' first")
        figures = measure(archive, args.stop_time, args.repeat, args.before, args.others)
        steps = round(args.stop_time / step_of(archive))
        report(name, args.stop_time, steps, figures, cold_start(archive))
    return 0


if __name__ == "__main__":
    sys.exit(main())
