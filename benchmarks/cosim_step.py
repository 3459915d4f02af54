# SPDX-License-Identifier: BSD-2-Clause
"""Cost of one communication step of a co-simulation, before and after the FMU speed-ups of issue 10,
split per FMU call, and the same archives run by libcosim, all in one run.

    python benchmarks/cosim_step.py [--scenarios example1 pendulum] [--stop-time 30] [--repeat 1]
        [--before c566841] [--master gauss-seidel|jacobi]

Builds, into a temporary folder, the current FMUs and the FMUs of revision ``--before`` (default:
the last commit before issue 10; sources taken with ``git archive``, built by that revision's own
``fmu_src.toolchain.build``), and packs each scenario of ``ssp/`` with either set. Then, per scenario:

* ``before``: the old FMUs (plants: RK4 with 40 sub-steps per 1 ms; controller: the general-n
  law, four evaluations per step; pythonfmu's per-variable getter/setter lambdas);
* ``now, plant method 1``: the current FMUs with the plant's old integrator (RK4, ``max_step``
  25 us), everything else new: the difference to ``before`` is the controller and get/set work,
  the difference to ``now`` the plant integrator;
* ``now, through pythonfmu``: the current FMUs with the shim's direct calls off
  (``FTC_FMU_DIRECT=0``): every FMI call goes through pythonfmu's binary, as before the shim made
  the step's calls itself;
* ``now``: the current FMUs (Dormand-Prince 5(4) plants, n = 2 scalar controller, attribute get/set,
  the shim's direct fmi2DoStep/GetReal/SetReal), stepped by the Python master;
* ``now, compiled``: the same, stepped by the compiled executor (blocks of steps in C, the rows
  handed back to the recorder);
* ``now, FMI 3.0`` and ``now, FMI 3.0, compiled``: the scenario's FMI 3.0 twin (the same SSD with
  the FMUs' FMI 3.0 variants);
* libcosim (``from_ssp_file``, the archive's serial algorithm, ``simulate_until``) on the ``before``
  and ``now`` archives, with no observer: libcosim as it is usually run. (Before issue 34 it ran with
  a last-value observer reading every variable at every step, which cost it 13-17 us per step.)

Method. Times are CPU times of this process (``time.process_time``), so other processes on the
shared machine do not distort them. The stepping loop of ``orchestrate``'s executors runs with
results in memory. For the Python master, a second run wraps every fmi2DoStep/GetReal/SetReal
(ctypes) in a CPU timer, corrected for the timer's own cost inside the timed window (calibrated on
a no-op call); it gives the FMU breakdown, and ``rest = loop - inside FMU calls`` estimates the
master's own overhead (the two come from different runs: a few us of noise, it can come out
negative). Every figure is the best of ``--repeat`` runs. The in-process cost of the controller's
two paths is in ``benchmarks/controller_step.py``.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from pathlib import Path

import orchestrator
from orchestrator.experiments.scenarios import FMI3_SUFFIX, SCENARIO_DIR, build_scenarios, component_sources
from orchestrator.fmi import interpreter_guard
from orchestrator.master import BLOCK, MASTERS, Master
from orchestrator.native import Stepper
from orchestrator.ssp import pack_ssp

REPO = Path(__file__).resolve().parent.parent
BEFORE = "c566841"  # the last commit before issue 10 changed the FMUs
clock = time.process_time_ns
FUNCTIONS = ("do_step", "get_real", "set_real")
FMI_NAMES = {"do_step": "fmi2DoStep", "get_real": "fmi2GetReal", "set_real": "fmi2SetReal"}


def timer_bias(calls: int = 20000) -> float:
    """CPU ns that one timed window adds around a call that does nothing."""

    def noop(*args: object) -> int:
        return 0

    total = 0
    for _ in range(calls):
        start = clock()
        noop(1, 2, 3, 4)
        total += clock() - start
    return total / calls


def libcosim_cpu(archive: Path, stop: float) -> float:
    """CPU ns of libcosim's ``simulate_until`` on ``archive`` (its own algorithm, no observer)."""
    from libcosimpy import CosimLogging
    from libcosimpy.CosimExecution import CosimExecution

    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
    with interpreter_guard():
        execution = CosimExecution.from_ssp_file(str(archive))
        start = clock()
        if not execution.simulate_until(round(stop * 1e9)):
            raise SystemExit(f"libcosim failed on {archive}")
        cpu = clock() - start
        del execution
    return cpu


def loop(scenario: Path, stop: float, master: str, overrides: Mapping[str, object],
         instrument: bool, compiled: bool = False) -> dict[str, object]:
    """Run the stepping loop once (results in memory; ``compiled``: the compiled executor's blocks).
    Returns its CPU ns, the number of steps, the output columns and, for an instrumented run, CPU ns
    and calls per (component, FMI function)."""
    inside: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0])

    def timed(key: tuple[str, str], fn: Callable[..., int]) -> Callable[..., int]:
        cell = inside[key]

        def call(*args: object) -> int:
            start = clock()
            status = fn(*args)
            cell[0] += clock() - start
            cell[1] += 1
            return status

        return call

    with ExitStack() as stack:
        system = stack.enter_context(orchestrator.open_system(scenario, overrides=overrides))
        experiment = system.structure.experiment
        m = MASTERS[master](system, experiment.start_time, stop, experiment.step or 1e-3, None)
        m.setup(stack)
        stack.callback(m.recorder.close)
        if instrument:
            _instrument(m, timed)
        m.initialize()
        for cell in inside.values():
            cell[:] = [0, 0]
        n = len(m.times) - 1
        if compiled:
            stepper = Stepper(m.plan, m.instances)
            stack.callback(stepper.close)
            stop_flag = ctypes.c_int(0)
            start, k = clock(), 0
            while k < n:
                k += m._block(stepper, k, min(n - k, BLOCK), stop_flag)
            cpu = clock() - start
        else:
            start = clock()
            for k in range(n):
                m.step(k)
            cpu = clock() - start
        m.terminate()
        outputs = [f"{c.name}.{o}" for c in system.components.values() for o in c.outputs]
    return {"cpu": cpu, "steps": n, "outputs": outputs, "inside": {k: tuple(v) for k, v in inside.items()}}


def _instrument(m: Master, timed: Callable[[tuple[str, str], Callable[..., int]], Callable[..., int]]
                ) -> None:
    """Wrap every FMI function of the master's instances with ``timed`` and rebuild its call table."""
    for inst in m.instances:
        for name in FUNCTIONS:
            setattr(inst, name, timed((inst.name, name), getattr(inst, name)))
    values = m.values
    m._layout()  # rebuild the call table with the wrapped functions
    m.values[:] = values


def build_before(revision: str, names: list[str], dest: Path) -> dict[str, Path]:
    """The FMUs of ``revision`` (its fmu_src/ and controller/, built by that revision's own
    ``fmu_src.toolchain.build``, as it shipped them) packed with today's scenario sources; returns
    scenario -> archive."""
    source = dest / "src"
    source.mkdir(parents=True)
    archive = dest / "src.tar"
    with archive.open("wb") as out:
        subprocess.run(["git", "-C", str(REPO), "archive", revision, "fmu_src", "controller"], stdout=out,
                       check=True)
    with tarfile.open(archive) as tar:
        tar.extractall(source, filter="data")
    subprocess.run([sys.executable, "-m", "fmu_src.toolchain.build", str(dest / "fmus")], cwd=source,
                   check=True, stdout=subprocess.DEVNULL, env=os.environ | {"PYTHONPATH": str(source)})
    fmus = {p.name: p for p in sorted((dest / "fmus").glob("*.fmu"))}
    return {name: pack_ssp(SCENARIO_DIR / name, {c: fmus[c] for c in component_sources(SCENARIO_DIR / name)},
                           dest / "ssp" / f"{name}.ssp")
            for name in names}


def measure(scenario: str, archives: dict[str, Path], stop: float, master: str, repeat: int,
            bias: float) -> None:
    """Run every configuration of one scenario ``repeat`` times and print the best figures."""
    configurations = {  # label -> archive, overrides, compiled executor
        "before": (archives["before"], {}, False),
        "now, plant method 1 (RK4)": (archives["now"], {"plant.method": 1}, False),
        "now, through pythonfmu": (archives["now"], {}, False),
        "now": (archives["now"], {}, False),
        "now, compiled": (archives["now"], {}, True),
        "now, FMI 3.0": (archives["now3"], {}, False),
        "now, FMI 3.0, compiled": (archives["now3"], {}, True),
    }
    best: dict[str, float] = {}
    breakdown: dict[str, dict[tuple[str, str], float]] = {}
    calls: dict[str, float] = {}

    def keep(key: str, value: float) -> bool:
        better = value < best.get(key, float("inf"))
        if better:
            best[key] = value
        return better

    steps = 0
    for _ in range(repeat):
        for label, (archive, overrides, compiled) in configurations.items():
            # The shim reads FTC_FMU_DIRECT at fmi2Instantiate.
            os.environ["FTC_FMU_DIRECT"] = "0" if label == "now, through pythonfmu" else "1"
            plain = loop(archive, stop, master, overrides, instrument=False, compiled=compiled)
            steps = int(plain["steps"])
            keep(label, plain["cpu"])
            if compiled:
                continue  # the FMU calls are made in C: no Python wrapper can time them
            timed = loop(archive, stop, master, overrides, instrument=True)
            corrected = {k: ns - n * bias for k, (ns, n) in timed["inside"].items() if n}
            if keep(label + " inside", sum(corrected.values())):
                breakdown[label] = corrected
                calls[label] = sum(n for _, n in timed["inside"].values())
        os.environ["FTC_FMU_DIRECT"] = "1"
        for which in ("before", "now"):  # libcosim has no FMI 3.0
            keep(f"libcosim {which}", libcosim_cpu(archives[which], stop))
    report(scenario, stop, master, repeat, bias, steps, best, breakdown, calls, list(configurations))


def report(scenario: str, stop: float, master: str, repeat: int, bias: float, steps: int,
           best: dict[str, float], breakdown: dict[str, dict[tuple[str, str], float]],
           calls: dict[str, float], configurations: list[str]) -> None:
    """Print one scenario's figures (CPU us per communication step)."""
    def us(ns: float) -> str:
        return f"{ns / steps / 1e3:7.1f}"

    step_ms = stop / steps * 1e3
    print(f"\n{scenario}: {steps} steps of {step_ms:g} ms, master {master}, best of {repeat}, "
          f"CPU us per communication step (timer bias {bias:.0f} ns/call corrected)")
    print(f"  {'configuration':34s} {'loop':>7s} {'in FMUs':>7s} {'rest':>7s} {'FMI calls/step':>15s}")
    for label in configurations:
        total, inside = best[label], best.get(label + " inside")
        if inside is None:
            print(f"  {label:34s} {us(total)} {'(in C)':>7s}")
            continue
        print(f"  {label:34s} {us(total)} {us(inside)} {us(total - inside)} "
              f"{calls[label] / steps:15.0f}")
    for which, ours in (("before", "before"), ("now", "now, compiled")):
        lc = best[f"libcosim {which}"]
        print(f"  {'libcosim (no observer), ' + which:34s} {us(lc)}   ratio {ours} / libcosim "
              f"{best[ours] / lc:.3f}")
    print(f"  speed-up now vs before: {best['before'] / best['now']:.2f}x "
          f"({us(best['before']).strip()} -> {us(best['now']).strip()} us/step); compiled: "
          f"{best['before'] / best['now, compiled']:.2f}x")
    print(f"  FMI 3.0 twin / FMI 2.0: Python master {best['now, FMI 3.0'] / best['now']:.3f}, compiled "
          f"{best['now, FMI 3.0, compiled'] / best['now, compiled']:.3f}")
    through = best["now, through pythonfmu"]
    print(f"  the shim's direct calls: {through / best['now']:.2f}x "
          f"({us(through).strip()} -> {us(best['now']).strip()} us/step)")
    _print_breakdown(breakdown, configurations, us)


def _print_breakdown(breakdown: dict[str, dict[tuple[str, str], float]], configurations: list[str],
                     us: Callable[[float], str]) -> None:
    """Per component, the CPU per communication step of each FMI function in every instrumented
    configuration (``us``: ns of the run -> us per step, formatted)."""
    components = sorted({c for b in breakdown.values() for c, _ in b})
    measured = [label for label in configurations if label in breakdown]
    print(f"  FMU breakdown, CPU us per communication step: {' / '.join(measured)}")
    for component in components:
        cells = []
        for name in FUNCTIONS:
            figures = [breakdown[label].get((component, name)) for label in measured]
            if any(f is not None for f in figures):
                cells.append(f"{FMI_NAMES[name]} " + _figures(figures, us))
        print(f"    {component:11s} " + "   ".join(cells))


def _figures(figures: list[float | None], us: Callable[[float], str]) -> str:
    """One function's figures of the configurations, ``a / b / -``."""
    return " / ".join(us(f).strip() if f is not None else "-" for f in figures)


def main(argv: list[str] | None = None) -> int:
    """Build both FMU sets, measure every scenario and print."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", nargs="+", default=["example1", "pendulum"])
    parser.add_argument("--stop-time", type=float, default=30.0)
    parser.add_argument("--master", choices=list(MASTERS), default="gauss-seidel")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--before", default=BEFORE, help=f"git revision of the old FMUs (default {BEFORE})")
    args = parser.parse_args(argv)
    bias = timer_bias()
    with tempfile.TemporaryDirectory() as tmp:
        now = build_scenarios(args.scenarios, Path(tmp) / "now")
        before = build_before(args.before, args.scenarios, Path(tmp) / "before")
        for name in args.scenarios:
            archives = {"before": before[name], "now": now[name], "now3": now[name + FMI3_SUFFIX]}
            measure(name, archives, args.stop_time, args.master, args.repeat, bias)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
