# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``PendulumPlant``: the paper's Example 2 (eq. 99), a pendulum with unmodeled dynamics z
and the disturbances d1 sin t (on x1') and d2 cos t (on x2').

States advance in do_step with the input uf held over the step (the disturbances follow the
absolute time inside the step); outputs depend on no input directly.
"""

from __future__ import annotations

from dataclasses import fields

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, raise_problems
from fmu_src.models.native import pendulum_native
from fmu_src.models.plants import PendulumParameters, pendulum_problems, pendulum_rhs_for
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


@fmu_model
class PendulumPlant(Fmi2Slave):
    """x1' = x2 + z x1 + d1 sin t, x2' = uf/(M L) - (g/L + B/M) sin(x1 x2) + z x2 sin x1 + d2 cos t."""

    description = "Pendulum of the paper's Example 2 (eq. 99) with unmodeled dynamics z and disturbances"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        defaults = PendulumParameters()
        for field in fields(PendulumParameters):
            setattr(self, field.name, getattr(defaults, field.name))
        self.uf = 0.0
        self.x1_0 = 0.6
        self.x2_0 = 0.1
        self.z_0 = 0.0
        self._rhs = pendulum_rhs_for(defaults)  # with the parameters of exit_initialization_mode
        self._native = pendulum_native(defaults)
        declare(
            self, "uf", Fmi2Causality.input, "Control applied by the actuator, held over each step", unit="N"
        )
        declare_plant_outputs(self, "rad", "rad/s")
        declare(self, "M", PARAMETER, "Mass", unit="kg", minimum=0.0)
        declare(self, "L", PARAMETER, "Length", unit="m", minimum=0.0)
        declare(self, "B", PARAMETER, "Damping coefficient", unit="kg/s2", minimum=0.0)
        declare(self, "g", PARAMETER, "Gravitational acceleration", unit="m/s2")
        declare(self, "d1", PARAMETER, "Amplitude of the disturbance d1 sin(t) on x1'", unit="rad/s")
        declare(self, "d2", PARAMETER, "Amplitude of the disturbance d2 cos(t) on x2'", unit="rad/s2")
        declare(self, "x1_0", PARAMETER, "Initial angle x1", unit="rad")
        declare(self, "x2_0", PARAMETER, "Initial angular velocity x2", unit="rad/s")
        declare(self, "z_0", PARAMETER, "Initial value of z")
        declare_integrator(self)  # last: max_step, method, rtol, atol

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and start at the initial states."""
        params = PendulumParameters(**{f.name: getattr(self, f.name) for f in fields(PendulumParameters)})
        raise_problems(self.modelName, pendulum_problems(params) + plant_problems(self))
        self._rhs = pendulum_rhs_for(params)
        self._native = pendulum_native(params)
        start_plant(self)

    # the states now (the initial values until initialization has finished); the core's function
    # itself, no frame of the class's own at every read
    refresh_outputs = refresh_plant_outputs
    # in a built FMU the shim's step and refresh run in C, these methods on every other path
    compiled_calls = compiled_plant_calls

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Integrate the pendulum over the step with uf held."""
        return step_plant(self, self._rhs, self._native, current_time, step_size)
