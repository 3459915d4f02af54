"""Regenerate the scenario sources in ssp/<scenario>/ (SSD + one .ssv per component).

    python ssp/generate.py

The files are committed and reviewable as diffs; edit the tables below and rerun, or edit the
XML by hand (the orchestrator and the tests read the XML, not this script).
"""

from __future__ import annotations

from pathlib import Path

from orchestrator.sspwriter import ComponentSpec, ConnectionSpec, write_ssd

HERE = Path(__file__).resolve().parent

REFERENCE = [("yd", "output", "Real"), ("yd_dot", "output", "Real"), ("yd_ddot", "output", "Real")]
CONTROLLER = [(n, "input", "Real") for n in ("x1", "x2", "yd", "yd_dot", "yd_ddot")] + [
    (n, "output", "Real") for n in ("v", "z1", "z2", "zeta1", "eta1_hat", "eta2_hat", "r")]
ACTUATOR = [("v", "input", "Real"), ("x1", "input", "Real"), ("x2", "input", "Real"),
            ("uf", "output", "Real"), ("u_dz", "output", "Real")]
PLANT = [("uf", "input", "Real")] + [(n, "output", "Real") for n in ("x1", "x2", "z", "y")]

CONNECTIONS = [ConnectionSpec(f"reference.{s}", f"controller.{s}") for s in ("yd", "yd_dot", "yd_ddot")] + [
    ConnectionSpec("plant.x1", "controller.x1"), ConnectionSpec("plant.x2", "controller.x2"),
    ConnectionSpec("plant.x1", "actuator.x1"), ConnectionSpec("plant.x2", "actuator.x2"),
    ConnectionSpec("controller.v", "actuator.v"), ConnectionSpec("actuator.uf", "plant.uf")]

ALPHA_BETA = {"alpha": 1.5, "beta": 0.75}
ACTUATOR_PARAMETERS = {"m_r": 1.0, "m_l": 1.2, "b_r": 0.5, "b_l": 0.6,
                       "K_inf": 0.4, "K_amp": 0.6, "K_rate": 0.2, "L_gain": 1.0, "L_bias": 0.0}
EXAMPLE1 = {
    "reference": {"amplitude": 0.5, "omega": 1.0},
    "controller": {"k1": 10.0, "k2": 10.0, "q1": 8.0, "q2": 8.0, "a1": 5.0, "a2": 2.0, "kappa1": 2.0,
                   "kappa2": 2.0, "rho1": 2.0, "rho2": 2.0, "rho_bar1": 1.0, "rho_bar2": 1.0, **ALPHA_BETA},
    "actuator": {**ACTUATOR_PARAMETERS, "t_fault": 10.0},
    "plant": {"x1_0": 0.5, "x2_0": 0.5, "z_0": 0.0},
}
PENDULUM = {
    "reference": {"amplitude": 1.0, "omega": 0.5},
    "controller": {"k1": 25.0, "k2": 25.0, "q1": 20.0, "q2": 20.0, "a1": 5.0, "a2": 2.0, "kappa1": 2.0,
                   "kappa2": 2.0, "rho1": 1.0, "rho2": 1.0, "rho_bar1": 2.0, "rho_bar2": 1.0, **ALPHA_BETA},
    "actuator": {**ACTUATOR_PARAMETERS, "t_fault": 5.0},
    "plant": {"M": 0.25, "L": 4.0, "B": 0.25, "g": 10.0, "x1_0": 0.6, "x2_0": 0.1, "z_0": 0.0},
}
FIXED_TIME, FINITE_TIME = 0, 1


def scenario(name: str, values: dict, plant_fmu: str, mode: int, description: str,
             t_fault: float | None = None) -> None:
    """Write one scenario folder."""
    controller = {**values["controller"], "mode": mode}
    actuator = {**values["actuator"], **({} if t_fault is None else {"t_fault": t_fault})}
    components = [
        ComponentSpec("reference", "Reference.fmu", REFERENCE, values["reference"]),
        ComponentSpec("controller", "FixedTimeController.fmu", CONTROLLER, controller),
        ComponentSpec("actuator", "Actuator.fmu", ACTUATOR, actuator),
        ComponentSpec("plant", plant_fmu, PLANT, values["plant"]),
    ]
    write_ssd(HERE / name, name, components, CONNECTIONS, 0.0, 30.0, 1e-3, description)


def main() -> None:
    """Write all scenarios of SPEC section 7."""
    scenario("example1", EXAMPLE1, "Example1Plant.fmu", FIXED_TIME,
             "Example 1 (eq. 85), fixed-time controller, actuator fault from t = 10 s")
    scenario("example1_finite_time", EXAMPLE1, "Example1Plant.fmu", FINITE_TIME,
             "Example 1, finite-time baseline controller [36], actuator fault from t = 10 s")
    scenario("example1_no_fault", EXAMPLE1, "Example1Plant.fmu", FIXED_TIME,
             "Example 1, fixed-time controller, fault never occurs (t_fault = 1e9 s)", t_fault=1e9)
    scenario("pendulum", PENDULUM, "PendulumPlant.fmu", FIXED_TIME,
             "Example 2 pendulum (eq. 99), fixed-time controller, actuator fault from t = 5 s")
    scenario("pendulum_finite_time", PENDULUM, "PendulumPlant.fmu", FINITE_TIME,
             "Example 2 pendulum, finite-time baseline controller [36], actuator fault from t = 5 s")


if __name__ == "__main__":
    main()
