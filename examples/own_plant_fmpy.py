# SPDX-License-Identifier: BSD-2-Clause
"""The controller FMU around your own plant, in a plain fmpy loop (no SSP, no orchestrator).

The plant here is not the paper's: a mass-spring-damper driven by a force u,

    m x'' + c x' + s x = u,   y = x,

written as system (1) of the paper with n = 2: x1' = x2, x2' = (u - c x2 - s x1) / m, so
g_2 = 1/m (the controller's ``b_max`` is its bound). The controller FMU is stepped at h = 1 ms
with fmpy's FMU2Slave, the plant integrated with RK4 over each step with u held. Run:

    python examples/own_plant_fmpy.py [build/fmus/FixedTimeController.fmu]

It prints the tracking error after the transient; the test (tests/test_examples.py) checks it
against the controller's promise: |y - yd| small after the first second.
"""

from __future__ import annotations

import math
import shutil
import sys
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

M, C, S = 2.0, 0.4, 3.0  # mass (kg), damping (N s/m), stiffness (N/m)
H, STOP = 1e-3, 5.0


def plant_rhs(x: tuple[float, float], u: float) -> tuple[float, float]:
    """The mass-spring-damper's state derivative for a held force u."""
    return x[1], (u - C * x[1] - S * x[0]) / M


def rk4(x: tuple[float, float], u: float, h: float) -> tuple[float, float]:
    """One classical Runge-Kutta step of the plant with u held."""
    k1 = plant_rhs(x, u)
    k2 = plant_rhs((x[0] + h / 2 * k1[0], x[1] + h / 2 * k1[1]), u)
    k3 = plant_rhs((x[0] + h / 2 * k2[0], x[1] + h / 2 * k2[1]), u)
    k4 = plant_rhs((x[0] + h * k3[0], x[1] + h * k3[1]), u)
    return (x[0] + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
            x[1] + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))


def simulate(fmu: Path) -> list[tuple[float, float, float, float]]:
    """Rows (t, y, yd, v) of the closed loop over [0, STOP]."""
    description = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in description.modelVariables}
    folder = extract(str(fmu))
    slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                      modelIdentifier=description.coSimulation.modelIdentifier, instanceName="controller")
    try:
        slave.instantiate()
        # The semi-implicit law at the communication step, b_max = 1/m (the plant's input gain).
        slave.setReal([vr["sample_time"], vr["b_max"]], [H, 1.0 / M])
        slave.setInteger([vr["discretization"]], [1])
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        x, rows = (0.5, 0.0), []
        inputs = [vr[n] for n in ("x1", "x2", "yd", "yd_dot", "yd_ddot")]
        for k in range(round(STOP / H) + 1):
            t = k * H
            yd = (math.sin(t), math.cos(t), -math.sin(t))  # the reference and its two derivatives
            slave.setReal(inputs, [x[0], x[1], *yd])
            (v,) = slave.getReal([vr["v"]])
            rows.append((t, x[0], yd[0], v))
            if k * H < STOP:
                slave.doStep(currentCommunicationPoint=t, communicationStepSize=H)
                x = rk4(x, v, H)
        slave.terminate()
        return rows
    finally:
        slave.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def main(argv: list[str]) -> int:
    fmu = Path(argv[1] if len(argv) > 1 else "build/fmus/FixedTimeController.fmu")
    rows = simulate(fmu)
    late = [abs(y - yd) for t, y, yd, _ in rows if t >= 1.0]
    print(f"mass-spring-damper under FixedTimeController: {len(rows)} rows, "
          f"max |y - yd| after 1 s = {max(late):.2e}, peak |v| = {max(abs(r[3]) for r in rows):.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
