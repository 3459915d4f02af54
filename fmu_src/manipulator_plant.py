# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``ManipulatorPlant``: a single-link robot manipulator driven by a brush DC motor (Dawson,
Carroll and Schneider 1994; :mod:`fmu_src.models.manipulator`), the third-order plant of the
``manipulator`` scenario: link angle x1 = q, velocity x2 = q', motor current x3 = I, input uf the
motor voltage.

States advance in do_step with the input uf held over the step; outputs are the states at the
communication point and depend on no input directly.
"""

from __future__ import annotations

from dataclasses import fields

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, raise_problems
from fmu_src.models.manipulator import ManipulatorParameters, manipulator_problems, manipulator_rhs_for
from fmu_src.models.native import manipulator_native
from fmu_src.plant_core import (
    compiled_plant_calls,
    declare_integrator,
    declare_plant_outputs,
    plant_problems,
    refresh_plant_outputs,
    start_plant,
    step_plant,
)

PARAMETER = Fmi2Causality.parameter
# name -> (description, unit) of the paper's constants, in ManipulatorParameters' order
CONSTANTS = {
    "J": ("Rotor inertia J", "kg.m2"),
    "m": ("Link mass m", "kg"),
    "L0": ("Link length L0", "m"),
    "M0": ("Load mass M0 (at the link's tip)", "kg"),
    "R0": ("Load radius R0", "m"),
    "B0": ("Viscous friction coefficient B0 at the joint", "N.m.s/rad"),
    "L": ("Armature inductance L", "H"),
    "R": ("Armature resistance R", "Ohm"),
    "K_tau": ("Torque constant K_tau", "N.m/A"),
    "K_B": ("Back-emf constant K_B", "V.s/rad"),
    "G": ("Gravitational acceleration G", "m/s2"),
}


@fmu_model
class ManipulatorPlant(Fmi2Slave):
    """M q'' + B q' + N sin q = I, L I' = uf - R I - K_B q' (Dawson et al. 1994)."""

    description = ("Single-link robot manipulator driven by a brush DC motor (Dawson, Carroll and Schneider "
                   "1994): link angle, velocity and motor current")

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        defaults = ManipulatorParameters()
        for field in fields(ManipulatorParameters):
            setattr(self, field.name, getattr(defaults, field.name))
        self.uf = 0.0
        self.x1_0 = 0.5
        self.x2_0 = 0.0
        self.x3_0 = 0.0
        self._rhs = manipulator_rhs_for(defaults)  # with the parameters of exit_initialization_mode
        self._native = manipulator_native(defaults)
        declare(self, "uf", Fmi2Causality.input, "Motor voltage applied by the actuator, held over each step",
                unit="V")
        declare_plant_outputs(self, "rad", "rad/s", ("x3", "Motor current I", "A"),
                              ("Link angle q (the output y)", "Link velocity q'"))
        for name, (description, unit) in CONSTANTS.items():
            declare(self, name, PARAMETER, description, unit=unit)
        declare(self, "x1_0", PARAMETER, "Initial link angle", unit="rad")
        declare(self, "x2_0", PARAMETER, "Initial link velocity", unit="rad/s")
        declare(self, "x3_0", PARAMETER, "Initial motor current", unit="A")
        declare_integrator(self)  # last: max_step, method, rtol, atol and the fail-fast bounds

    def _parameters(self) -> ManipulatorParameters:
        return ManipulatorParameters(**{f.name: getattr(self, f.name) for f in fields(ManipulatorParameters)})

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and start at the initial states."""
        params = self._parameters()
        raise_problems(self.modelName, manipulator_problems(params) + plant_problems(self))
        self._rhs = manipulator_rhs_for(params)
        self._native = manipulator_native(params)
        start_plant(self)

    # the states now (the initial values until initialization has finished); the core's function
    # itself, no frame of the class's own at every read
    refresh_outputs = refresh_plant_outputs
    # in a built FMU the shim's step and refresh run in C, these methods on every other path
    compiled_calls = compiled_plant_calls

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Integrate the manipulator over the step with uf held."""
        return step_plant(self, self._rhs, self._native, current_time, step_size)
