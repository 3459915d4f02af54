# SPDX-License-Identifier: BSD-2-Clause
"""Cost of one communication step of each FMU, in microseconds: in a C host and from fmpy.

* **C host** (``benchmarks/fmu_step_host.c``, compiled here with ``cc``): per step fmi2SetReal of the
  inputs, fmi2GetReal of the outputs, fmi2DoStep, as a C/C++ master (libcosim, OMSimulator) makes
  them, with nothing of the host in the loop: the FMU's own share of a closed-loop step. CPU time of
  the host process per step (other processes on the machine do not change it) and the median over
  batches of 100 steps of the wall clock. The inputs are waves of the size a closed loop produces
  (the controller's: yd = 0.5 sin t with its derivatives, states near it).
* **fmpy** (Python ctypes, as before issue 35): the median doStep, and get outputs / set inputs /
  get outputs (the direct-feedthrough getters), each with fmpy's own per-call cost inside.

The controller's share of a closed-loop step (issue 35: at most 3 us) is the C host's figure of the
controller FMU. ``--before DIR`` measures the FMUs of an earlier build (e.g. the last commit's
``build/fmus``) in the same run, beside the current ones. The plants are measured with their
default integrator (Dormand-Prince 5(4)); ``--rk4`` adds the fixed-step RK4 (``method`` 1).

``--instructions`` prints instead each FMU's instructions per step in the C host, which the machine's
load does not move: ``valgrind --tool=callgrind`` counts the host for :data:`COUNTED_STEPS` and for
twice as many steps, one process after the other, and the difference is divided by
:data:`COUNTED_STEPS` (start-up cancels; at 1 000 steps, side by side, a one-off event of the
interpreter in one run moved the controller's count by 1 800, see ``step_instructions.py``).

Usage: ``python benchmarks/fmu_step.py [--steps N] [--fmus DIR] [--before DIR] [--rk4]
[--instructions]`` (builds into a temporary folder without ``--fmus``). Figures only: timings are never
asserted.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

import fmu_src.cbase as cbase
from fmu_src.toolchain.build import FMU_SCRIPTS, build_all

H = 1e-3
HOST = Path(__file__).with_name("fmu_step_host.c")
GOAL_US = 3.0  # issue 35: the controller's share of a closed-loop step
COUNTED_STEPS = 5000  # --instructions: the shorter run's steps under callgrind
HALF_PI = math.pi / 2


def waves(model: str, names: list[str]) -> dict[str, tuple[float, float, float]]:
    """Input name -> (amplitude, omega, phase) of a closed loop's size: the controller's reference
    yd = 0.5 sin t with its derivatives (consistent with it), states near them; a plant's or the
    actuator's input a bounded wave."""
    out = {}
    for name in names:
        if name.startswith("yd"):
            order = 0 if name == "yd" else name.count("d") - 1  # yd_dot: 1, yd_ddot: 2, ...
            out[name] = (0.5, 1.0, order * HALF_PI)
        elif name.startswith("x") and "Controller" in model:
            i = int(name[1:])
            out[name] = (0.5 + 0.1 * i, 1.0, (i - 1) * HALF_PI + 0.3)
        else:
            out[name] = (2.0 if name in ("v", "uf") else 0.3, 3.0, 0.1)
    return out


def fmpy_inputs(model: str, names: list[str], k: int) -> dict[str, float]:
    """The waves of :func:`waves` at step k (fmpy loop)."""
    t = k * H
    return {n: a * math.sin(w * t + p) for n, (a, w, p) in waves(model, names).items()}


def measure_fmpy(path: Path, steps: int, method: int | None = None) -> tuple[float, float]:
    """(median doStep, median get-outputs/set-inputs/get-outputs) in microseconds, from fmpy."""
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    folder = extract(str(path))
    fmu = FMU2Slave(
        guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bench",
    )
    fmu.instantiate()
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        if method is not None:
            fmu.setInteger([vr["method"]], [method])
        fmu.exitInitializationMode()
        step_times, io_times = [], []
        for k in range(steps):
            start = time.perf_counter_ns()
            _exchange(fmu, md.modelName, vr, inputs, outputs, k)
            middle = time.perf_counter_ns()
            fmu.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
            end = time.perf_counter_ns()
            io_times.append(middle - start)
            step_times.append(end - middle)
        fmu.terminate()
    finally:
        fmu.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)
    return statistics.median(step_times) / 1e3, statistics.median(io_times) / 1e3


def _exchange(fmu: FMU2Slave, model: str, vr: dict[str, int], inputs: list[str], outputs: list[str],
              k: int) -> None:
    """Step k's exchange as a master does it: get the outputs, set the inputs (a plant's under a PD
    law, as in the C host), get the direct-feedthrough outputs for the new inputs."""
    out = dict(zip(outputs, fmu.getReal([vr[n] for n in outputs]), strict=True))
    values = fmpy_inputs(model, inputs, k)
    if "Plant" in model:
        values["uf"] += -20.0 * out["x1"] - 10.0 * out["x2"]
    if values:
        fmu.setReal([vr[n] for n in values], list(values.values()))
        fmu.getReal([vr[n] for n in outputs])


def compile_host(where: Path) -> Path:
    """benchmarks/fmu_step_host.c compiled into ``where``."""
    target = where / "fmu_step_host"
    compiler = shutil.which("cc") or shutil.which("gcc") or "cc"
    subprocess.run([compiler, "-std=c11", "-O2", f"-I{cbase.FMI_HEADERS}", "-o", str(target), str(HOST),
                    "-ldl", "-lm"], check=True)
    return target


def measure_c(host: Path, path: Path, steps: int) -> tuple[float, float]:
    """(CPU us per step, median wall us per step) of the FMU in the C host."""
    with c_host(host, path, steps) as command:
        result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        raise RuntimeError(f"{path.name}: the C host failed ({result.returncode}): {result.stderr.strip()}")
    figures = dict(line.split() for line in result.stdout.splitlines())
    return float(figures["cpu_ns_per_step"]) / 1e3, float(figures["median_ns_per_step"]) / 1e3


def count_instructions(host: Path, path: Path, steps: int) -> float:
    """Instructions per step of the FMU in the C host: ``valgrind --tool=callgrind`` counts the host
    process for ``steps`` and for twice as many, one after the other; the difference divided by
    ``steps`` (start-up cancels). The machine's load does not move it."""
    totals = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in (steps, 2 * steps):
            out = Path(tmp, f"{n}.out")
            with c_host(host, path, n) as command:
                counting = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *command]
                done = subprocess.run(counting, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                      timeout=1200)
            if done.returncode != 0:
                failure = done.stderr[-2000:]
                raise RuntimeError(f"{path.name}: callgrind failed ({done.returncode}): {failure}")
            totals.append(int(next(line.split()[1] for line in out.read_text().splitlines()
                                   if line.startswith("summary:"))))
    return (totals[1] - totals[0]) / steps


@contextmanager
def c_host(host: Path, path: Path, steps: int) -> Iterator[list[str]]:
    """The C host's command line stepping the FMU ``path`` (unpacked meanwhile) for ``steps``."""
    md = read_model_description(str(path))
    folder = Path(extract(str(path)))
    binary = folder / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    variables = {v.name: v for v in md.modelVariables}
    inputs = [n for n, v in variables.items() if v.causality == "input"]
    args = [f"i:{variables[n].valueReference}={a!r},{w!r},{p!r}" for n, (a, w, p) in waves(md.modelName,
                                                                                             inputs).items()]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    args += [f"o:{variables[n].valueReference}" for n in outputs]
    if "Plant" in md.modelName:  # under a PD law, as in a loop: open loop a plant leaves its range
        args += [f"f:{outputs.index('x1')},0=-20.0", f"f:{outputs.index('x2')},0=-10.0"]
    resources = folder.joinpath("resources").as_uri()
    try:
        yield [str(host), str(binary), resources, md.guid, str(steps), repr(H), "100", *args]
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _measure(host: Path, path: Path, name: str, options: argparse.Namespace) -> float:
    """Print the FMU's line (and, with --rk4, its RK4 line for a plant); its CPU us per step in C."""
    if options.instructions:
        print(f"{name:<32}{count_instructions(host, path, COUNTED_STEPS):>12.0f}", flush=True)
        return 0.0
    cpu, wall = measure_c(host, path, options.steps)
    step, io = measure_fmpy(path, options.steps)
    print(f"{name:<32}{cpu:>12.2f}{wall:>9.2f}{step:>13.1f}{io:>13.1f}")
    if options.rk4 and "Plant" in name:
        step, io = measure_fmpy(path, options.steps, method=1)
        print(f"{name + ' RK4':<32}{'-':>12}{'-':>9}{step:>13.1f}{io:>13.1f}")
    return cpu


def main(argv: list[str] | None = None) -> int:
    """Print one line per FMU (and per earlier FMU with ``--before``), then the controller's share."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=3000, help="communication steps per FMU (default 3000)")
    parser.add_argument("--fmus", type=Path, help="folder with the built FMUs (default: build now)")
    parser.add_argument("--before", type=Path, help="folder with FMUs of an earlier build, measured beside")
    parser.add_argument("--rk4", action="store_true", help="also the plants with RK4 (fmpy only)")
    parser.add_argument("--instructions", action="store_true",
                        help="instead: instructions per step in the C host (callgrind, 5000 and 10000 steps)")
    options = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = options.fmus or Path(tmp)
        if options.fmus is None:
            build_all(folder)
        host = compile_host(Path(tmp))
        sets = [("", folder)] + ([("before: ", options.before)] if options.before else [])
        if options.instructions:
            print(f"{'FMU':<32}{'C host':>12}   (instructions per step, callgrind, h = 1 ms)")
        else:
            print(f"{'FMU':<32}{'C host: CPU':>12}{'median':>9}{'fmpy doStep':>13}{'get+set+get':>13}"
                  f"   (us per step, {options.steps} steps, h = 1 ms)")
        share: dict[str, float] = {}
        for label, where in sets:
            for model in FMU_SCRIPTS:
                path = where / f"{model}.fmu"
                if path.is_file():
                    share[label + model] = _measure(host, path, label + model, options)
        controllers = {} if options.instructions else {n: v for n, v in share.items() if "Controller" in n}
        for name, cpu in controllers.items():
            verdict = "within" if cpu <= GOAL_US else "above"
            print(f"controller's share, {name}: {cpu:.2f} us per communication step, {verdict} the "
                  f"{GOAL_US:g} us goal")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
