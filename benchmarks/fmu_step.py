"""Cost of one fmi2DoStep of each FMU called from fmpy, in microseconds (median of many).

Also the cost of reading the outputs after new inputs (the direct-feedthrough getters). The
plants are measured with their default integrator (Dormand-Prince 5(4), ``method`` 0) and with
the fixed-step RK4 (``method`` 1, 40 sub-steps per 1 ms).
Usage: ``python benchmarks/fmu_step.py [--steps N] [--fmus DIR]`` (builds into a temp dir by default).
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from fmu_src.build import FMU_SCRIPTS, build_all

H = 1e-3


def inputs_at(model: str, k: int, out: dict[str, float]) -> dict[str, float]:
    """Inputs of the size a closed loop produces, changing every step (plants under a PD law:
    open loop the pendulum diverges)."""
    t = k * H
    return {
        "Reference": {},
        "FixedTimeController": {
            "x1": 0.5 * math.cos(t),
            "x2": 0.3 * math.sin(t),
            "yd": 0.5 * math.sin(t),
            "yd_dot": 0.5 * math.cos(t),
            "yd_ddot": -0.5 * math.sin(t),
        },
        "Actuator": {"v": 2.0 * math.sin(t), "x1": 0.1, "x2": 0.2},
        "Example1Plant": {"uf": math.sin(t) - 20.0 * out.get("x1", 0.0) - 10.0 * out.get("x2", 0.0)},
        "PendulumPlant": {"uf": math.sin(t) - 20.0 * out.get("x1", 0.0) - 10.0 * out.get("x2", 0.0)},
    }[model]


def measure(path: Path, steps: int, method: int | None = None) -> tuple[float, float]:
    """(median doStep, median get-outputs/set-inputs/get-outputs) in microseconds; ``method`` sets
    a plant's integrator."""
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    fmu = FMU2Slave(
        guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.modelName, instanceName="bench"
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
            out = dict(zip(outputs, fmu.getReal([vr[n] for n in outputs]), strict=True))
            values = inputs_at(md.modelName, k, out)
            if values:
                fmu.setReal([vr[n] for n in values], list(values.values()))
                fmu.getReal([vr[n] for n in outputs])  # direct-feedthrough outputs for the new inputs
            middle = time.perf_counter_ns()
            fmu.doStep(currentCommunicationPoint=k * H, communicationStepSize=H)
            end = time.perf_counter_ns()
            io_times.append(middle - start)
            step_times.append(end - middle)
        fmu.terminate()
    finally:
        fmu.freeInstance()
    return statistics.median(step_times) / 1e3, statistics.median(io_times) / 1e3


def main(argv: list[str] | None = None) -> int:
    """Print one line per FMU."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=3000, help="doSteps per FMU (default 3000)")
    parser.add_argument("--fmus", type=Path, help="folder with the built FMUs (default: build now)")
    options = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = options.fmus or Path(tmp)
        if options.fmus is None:
            build_all(folder)
        print(
            f"{'FMU':<22}{'doStep [us]':>14}{'get+set+get [us]':>19}   (median of {options.steps}, h = 1 ms)"
        )
        for model in FMU_SCRIPTS:
            for method in (None, 1) if "Plant" in model else (None,):
                step, io = measure(folder / f"{model}.fmu", options.steps, method)
                label = model if method is None else f"{model} RK4"
                print(f"{label:<22}{step:>14.1f}{io:>19.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
