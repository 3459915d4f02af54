"""Wall time of a co-simulation run, split into time inside FMU calls and the master's own overhead
per communication step, and the same .ssp run by libcosim (numWorkerThreads="0") for a ratio.

    python benchmarks/cosim_step.py [--scenario build/ssp/example1.ssp] [--stop-time 30] [--master ...]

Method: (1) a plain run of the stepping loop (results recorded and streamed to a CSV, as
``orchestrate run`` does) gives the loop's wall time; (2) a second run with every FMU call
(fmi2DoStep/GetReal/SetReal, through ctypes) wrapped in a timer gives the time spent inside the
FMUs; overhead per step = (plain loop time - FMU time) / steps. The wrappers' own cost lands outside
both measured quantities. (3) libcosim runs the same archive, observing the same output variables
in a time-series observer; its ``simulate_until`` is the comparable loop. Whole-run times (load,
initialization, loop, results) are reported too. Build the archives first: ``orchestrate build``.
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


def _loop(scenario: Path, stop: float, master: str, csv: Path | None,
          instrument: bool) -> tuple[float, float, int, list[str]]:
    """Run the stepping loop; return (loop seconds, seconds inside FMU calls or nan, steps, outputs)."""
    inside = [0]
    perf = time.perf_counter_ns

    def timed(fn):
        def call(*args):
            start = perf()
            status = fn(*args)
            inside[0] += perf() - start
            return status
        return call

    with ExitStack() as stack:
        system = orchestrator.load(scenario, stack)
        m = MASTERS[master](system, system.structure.experiment.start_time, stop,
                            system.structure.experiment.step or 1e-3, csv)
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
        inside[0] = 0
        n = len(m.times) - 1
        start = time.perf_counter()
        for k in range(n):
            m.step(k)
        m.recorder.flush()
        loop = time.perf_counter() - start
        m.terminate()
        outputs = [f"{c.name}.{o}" for c in system.components.values() for o in c.outputs]
    return loop, (inside[0] / 1e9 if instrument else float("nan")), n, outputs


def main() -> None:
    """Measure (best of ``--repeat`` interleaved runs, the machine may be shared) and print."""
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

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "result.csv"
        for _ in range(args.repeat):
            loop, _, n, outputs = _loop(args.scenario, args.stop_time, args.master, csv, instrument=False)
            keep("loop", loop)
            loop_memory, _, _, _ = _loop(args.scenario, args.stop_time, args.master, None, instrument=False)
            keep("loop_memory", loop_memory)
            _, inside, _, _ = _loop(args.scenario, args.stop_time, args.master, None, instrument=True)
            keep("inside", inside)
            start = time.perf_counter()
            orchestrator.run(args.scenario, stop_time=args.stop_time, master=args.master, output=csv)
            keep("whole", time.perf_counter() - start)
            start = time.perf_counter()
            _, lc_loop = run_libcosim(args.scenario, args.stop_time, ["time"] + outputs)
            keep("lc_whole", time.perf_counter() - start)
            keep("lc_loop", lc_loop)
    b = best
    print(f"scenario {args.scenario}, {n} steps of {args.stop_time / n * 1e3:g} ms, master {args.master}, "
          f"best of {args.repeat}")
    per = 1e6 / n
    print(f"  stepping loop, results in memory : {b['loop_memory']:7.3f} s  "
          f"{b['loop_memory'] * per:6.1f} us/step")
    print(f"    inside FMU calls (instrumented): {b['inside']:7.3f} s  {b['inside'] * per:6.1f} us/step")
    print(f"    master overhead                : {b['loop_memory'] - b['inside']:7.3f} s  "
          f"{(b['loop_memory'] - b['inside']) * per:6.1f} us/step")
    print(f"  stepping loop, CSV streamed      : {b['loop']:7.3f} s  {b['loop'] * per:6.1f} us/step")
    print(f"  libcosim simulate_until          : {b['lc_loop']:7.3f} s  {b['lc_loop'] * per:6.1f} us/step")
    print(f"  whole run: orchestrator.run + CSV: {b['whole']:7.3f} s")
    print(f"  whole run: libcosim load+run+read: {b['lc_whole']:7.3f} s")
    print(f"  ratio ours / libcosim: loop (CSV) {b['loop'] / b['lc_loop']:.3f}, "
          f"loop (memory) {b['loop_memory'] / b['lc_loop']:.3f}, whole run {b['whole'] / b['lc_whole']:.3f}")


if __name__ == "__main__":
    main()
