# SPDX-License-Identifier: BSD-2-Clause
"""Regenerate the scenario sources in ssp/<scenario>/ (SSD + one .ssv per component).

    python ssp/generate.py

The files are committed and reviewable as diffs. The values come from the paper's examples
(``fmu_src/models/examples.py``); a test checks that the committed files are what this writes.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from controller.params import Discretization, Mode
from fmu_src.controller_core import DERIVATIVES, controller_model, input_names, output_names
from fmu_src.models.examples import EXAMPLE1, EXAMPLE2, MANIPULATOR, Example
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, write_ssd

HERE = Path(__file__).resolve().parent

ACTUATOR = [("v", "input", "Real"), ("x1", "input", "Real"), ("x2", "input", "Real"),
            ("uf", "output", "Real"), ("u_dz", "output", "Real")]
GAINS = ("k", "q", "a", "kappa", "rho", "rho_bar")  # per backstepping step: FMU parameters k1, k2, ...


def connectors(example: Example) -> dict[str, list[tuple[str, str, str]]]:
    """The connectors of every component for the example's plant order n: the reference's yd and n
    derivatives, the controller's inputs and outputs of order n, the plant's states and y."""
    n = example.controller.n
    return {
        "reference": [(name, "output", "Real") for name in DERIVATIVES[: n + 1]],
        "controller": [(name, "input", "Real") for name in input_names(n)]
        + [(name, "output", "Real") for name in output_names(n)],
        "actuator": ACTUATOR,
        "plant": [("uf", "input", "Real")] + [(name, "output", "Real") for name in (*example.states, "y")],
    }


def connections(example: Example) -> tuple[Connection, ...]:
    """reference -> controller (yd and its n derivatives), plant states -> controller, x1 and x2 ->
    actuator (its bias fault L(t)), controller -> actuator -> plant."""
    n = example.controller.n
    return tuple(Connection.between(start, end) for start, end in [
        *((f"reference.{s}", f"controller.{s}") for s in DERIVATIVES[: n + 1]),
        *((f"plant.{s}", f"controller.x{i}") for i, s in enumerate(example.states[:n], start=1)),
        ("plant.x1", "actuator.x1"), ("plant.x2", "actuator.x2"), ("controller.v", "actuator.v"),
        ("actuator.uf", "plant.uf")])


def parameters(example: Example, mode: Mode, t_fault: float | None,
               sample_time: float | None = None) -> dict[str, dict[str, float]]:
    """The FMU parameter values of one scenario, per component, from the example's data
    (``sample_time``: the controller's semi-implicit discretization at that sample time)."""
    c = example.controller
    controller = {f"{g}{i}": value for g in GAINS for i, value in enumerate(getattr(c, g), start=1)}
    controller |= {"alpha": c.alpha, "beta": c.beta, "mode": int(mode)}
    if sample_time is not None:
        controller |= {"discretization": int(Discretization.SEMI_IMPLICIT), "sample_time": sample_time,
                       "b_max": c.b_max}
    actuator = asdict(example.actuator) | ({} if t_fault is None else {"t_fault": t_fault})
    actuator.pop("u_max")  # the saturation stays off (the FMU's default): the paper's scenarios
    physical = asdict(example.plant) if example.plant else {}
    initial = dict(zip((f"{s}_0" for s in example.states), example.x0, strict=True))
    return {"reference": asdict(example.reference), "controller": controller, "actuator": actuator,
            "plant": physical | initial}


def scenario(dest: Path, name: str, example: Example, mode: Mode, description: str,
             t_fault: float | None = None, step: float = 1e-3, smooth: bool = False) -> None:
    """Write the scenario folder ``dest/name`` (communication step ``step`` in seconds; ``smooth``:
    the controller's semi-implicit discretization at that step)."""
    values = parameters(example, mode, t_fault, step if smooth else None)
    ports = connectors(example)
    fmus = {"reference": "Reference", "controller": controller_model(example.controller.n),
            "actuator": "Actuator", "plant": example.plant_fmu}
    components = tuple(component(name, f"{fmu}.fmu", ports[name], values[name]) for name, fmu in fmus.items())
    experiment = Experiment(0.0, example.stop_time, step)
    write_ssd(dest / name, SystemStructure(name, components, connections(example), experiment, description))


def main(dest: Path = HERE) -> None:
    """Write all scenarios of SPEC section 7 into ``dest`` (default: beside this script)."""
    scenario(dest, "example1", EXAMPLE1, Mode.FIXED_TIME,
             "Example 1 (eq. 85), fixed-time controller, actuator fault from t = 10 s")
    scenario(dest, "example1_finite_time", EXAMPLE1, Mode.FINITE_TIME,
             "Example 1, finite-time baseline controller [36], actuator fault from t = 10 s")
    scenario(dest, "example1_no_fault", EXAMPLE1, Mode.FIXED_TIME,
             "Example 1, fixed-time controller, fault never occurs (t_fault = 1e9 s)", t_fault=1e9)
    # 0.5 ms, not 1 ms: masters that delay every connection by one step (libcosim, Ecos, our
    # jacobi) put two steps of delay in the loop, and with |v(0)| = 15 218 the plant diverges at
    # t = 0.031 s at 1 ms; at 0.5 ms every tool runs it (README, "In other tools").
    scenario(dest, "pendulum", EXAMPLE2, Mode.FIXED_TIME,
             "Example 2 pendulum (eq. 99), fixed-time controller, actuator fault from t = 5 s",
             step=5e-4)
    scenario(dest, "pendulum_finite_time", EXAMPLE2, Mode.FINITE_TIME,
             "Example 2 pendulum, finite-time baseline controller [36], actuator fault from t = 5 s")
    # Issue 11: the controller's semi-implicit discretization (no chattering bursts), b_max from the
    # examples' input gains.
    scenario(dest, "example1_smooth", EXAMPLE1, Mode.FIXED_TIME,
             "Example 1, fixed-time controller with the semi-implicit discretization, fault from t = 10 s",
             smooth=True)
    scenario(dest, "pendulum_smooth", EXAMPLE2, Mode.FIXED_TIME,
             "Example 2 pendulum, fixed-time controller with the semi-implicit discretization, fault from "
             "t = 5 s", step=5e-4, smooth=True)  # 0.5 ms as pendulum: at 1 ms jacobi diverges at 0.064 s
    # Issue 35: a third-order plant from the literature under the same actuator, the order-3 controller
    # with the semi-implicit discretization at 1 ms (its explicit law diverges in the first step).
    scenario(dest, "manipulator", MANIPULATOR, Mode.FIXED_TIME,
             "Single-link manipulator driven by a DC motor (Dawson et al. 1994), order-3 fixed-time "
             "controller with the semi-implicit discretization, actuator fault from t = 10 s", smooth=True)


if __name__ == "__main__":
    main()
