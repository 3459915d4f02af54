"""Time of a co-simulation run, split into time inside FMU calls and the master's own overhead per
communication step, and the same .ssp run by libcosim (numWorkerThreads="0") for a ratio.

    orchestrate build && python benchmarks/cosim_step.py [--scenario build/ssp/example1.ssp]
        [--stop-time 30] [--master gauss-seidel|jacobi] [--repeat 3]

Method. Times are CPU times of this process (``time.process_time``), so that other processes on a
shared machine do not distort them; wall times are printed beside them. (1) The stepping loop of
``orchestrate run`` (results recorded in memory; once more with the CSV streamed to the writer
process, whose own CPU time is not ours) gives the loop time. (2) A second run with every FMU call
(fmi2DoStep/GetReal/SetReal through ctypes) wrapped in a CPU timer gives the time inside the FMUs,
corrected for the part of the timer calls that falls inside the timed window (calibrated on a no-op
call). Overhead per step = (loop - inside FMUs) / steps. (3) libcosim runs the same archive with a
time-series observer on the same outputs; its ``simulate_until`` is the comparable loop. Every
figure is the best of ``--repeat`` interleaved runs.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import orchestrator
from orchestrator.crosscheck import run_libcosim
from orchestrator.master import MASTERS

clock = time.process_time_ns


def _timer_bias(calls: int = 20000) -> float:
    """CPU ns that one timed window adds around a call that does nothing."""
    def noop(*args):
        return 0

    total = 0
    for _ in range(calls):
        start = clock()
        noop(1, 2, 3, 4)
        total += clock() - start
    return total / calls


def _loop(scenario: Path, stop: float, master: str, csv: Path | None,
          instrument: bool) -> dict[str, float]:
    """Run the stepping loop once; CPU and wall seconds of the loop, CPU seconds inside FMU calls
    (instrumented runs only), number of steps and calls."""
    inside = [0, 0]

    def timed(fn):
        def call(*args):
            start = clock()
            status = fn(*args)
            inside[0] += clock() - start
            inside[1] += 1
            return status
        return call

    with ExitStack() as stack:
        system = stack.enter_context(orchestrator.open_system(scenario))
        experiment = system.structure.experiment
        m = MASTERS[master](system, experiment.start_time, stop, experiment.step or 1e-3, csv)
        m.setup(stack)
        stack.callback(m.recorder.close)
        if instrument:
            for inst in m.instances:
                inst.do_step, inst.get_real, inst.set_real = (timed(inst.do_step), timed(inst.get_real),
                                                              timed(inst.set_real))
            values = m.values
            m._layout()
            m.values[:] = values
        m.initialize()
        inside[:] = [0, 0]
        n = len(m.times) - 1
        wall, cpu = time.perf_counter(), clock()
        for k in range(n):
            m.step(k)
        m.recorder.flush()
        cpu, wall = (clock() - cpu) / 1e9, time.perf_counter() - wall
        m.terminate()
        outputs = [f"{c.name}.{o}" for c in system.components.values() for o in c.outputs]
    return {"cpu": cpu, "wall": wall, "inside": inside[0] / 1e9, "calls": inside[1], "steps": n,
            "outputs": outputs}


def main() -> None:
    """Measure and print."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", type=Path, default=Path("build/ssp/example1.ssp"))
    parser.add_argument("--stop-time", type=float, default=30.0)
    parser.add_argument("--master", choices=list(MASTERS), default="gauss-seidel")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    best: dict[str, float] = {}

    def keep(name: str, value: float) -> None:
        best[name] = min(value, best.get(name, float("inf")))

    bias = _timer_bias()
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "result.csv"
        for _ in range(args.repeat):
            plain = _loop(args.scenario, args.stop_time, args.master, None, instrument=False)
            keep("loop_cpu", plain["cpu"])
            keep("loop_wall", plain["wall"])
            streamed = _loop(args.scenario, args.stop_time, args.master, csv, instrument=False)
            keep("csv_cpu", streamed["cpu"])
            keep("csv_wall", streamed["wall"])
            timed = _loop(args.scenario, args.stop_time, args.master, None, instrument=True)
            keep("inside", timed["inside"] - timed["calls"] * bias / 1e9)
            wall, cpu = time.perf_counter(), time.process_time()
            orchestrator.run(args.scenario, stop_time=args.stop_time, master=args.master, output=csv)
            keep("whole_cpu", time.process_time() - cpu)
            keep("whole_wall", time.perf_counter() - wall)
            cpu = time.process_time()
            wall = time.perf_counter()
            _, timing = run_libcosim(args.scenario, args.stop_time, ["time"] + plain["outputs"])
            keep("lc_whole_cpu", time.process_time() - cpu)
            keep("lc_whole_wall", time.perf_counter() - wall)
            keep("lc_wall", timing["wall"])
            keep("lc_cpu", timing["cpu"])
    b, n = best, plain["steps"]
    print(f"{args.scenario}: {n} steps of {args.stop_time / n * 1e3:g} ms, master {args.master}, "
          f"best of {args.repeat}; timer bias {bias:.0f} ns/call corrected")

    def row(label: str, cpu: float, wall: float | None = None, per_step: bool = True) -> None:
        text = f"  {label:36s} cpu {cpu:6.2f} s"
        if per_step:
            text += f" = {cpu / n * 1e6:6.1f} us/step"
        if wall is not None:
            text += f"   (wall {wall:6.2f} s)"
        print(text)

    row("stepping loop, results in memory", b["loop_cpu"], b["loop_wall"])
    row("  inside FMU calls", b["inside"])
    row("  master overhead", b["loop_cpu"] - b["inside"])
    row("stepping loop, CSV streamed", b["csv_cpu"], b["csv_wall"])
    row("libcosim simulate_until", b["lc_cpu"], b["lc_wall"])
    row("whole run, orchestrator.run + CSV", b["whole_cpu"], b["whole_wall"], per_step=False)
    row("whole run, libcosim load+run+read", b["lc_whole_cpu"], b["lc_whole_wall"], per_step=False)
    print(f"  ratio ours / libcosim: stepping loop cpu {b['loop_cpu'] / b['lc_cpu']:.3f} "
          f"(CSV streamed {b['csv_cpu'] / b['lc_cpu']:.3f}); whole run cpu "
          f"{b['whole_cpu'] / b['lc_whole_cpu']:.3f}, wall {b['whole_wall'] / b['lc_whole_wall']:.3f}")


if __name__ == "__main__":
    main()
