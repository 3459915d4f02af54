# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``Example1Plant``: the paper's Example 1 (eq. 85) with unmodeled dynamics z.

States advance in do_step with the input uf held over the step; outputs are the states at the
communication point and depend on no input directly.
"""

from __future__ import annotations

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, raise_problems
from fmu_src.models.native import EXAMPLE1
from fmu_src.models.plants import example1_rhs
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
class Example1Plant(Fmi2Slave):
    """x1' = (2 + sin x1) x2 + ..., x2' = (2 + cos(x1 x2)) uf + ..., z' = -z - x1^2 + 0.5."""

    description = "Example 1 plant of the paper (eq. 85): second order with unmodeled dynamics z"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.uf = 0.0
        self.x1_0 = 0.5
        self.x2_0 = 0.5
        self.z_0 = 0.0
        self._native = EXAMPLE1  # the compiled step's plant (plant_core.compiled_plant_calls reads it)
        declare(self, "uf", Fmi2Causality.input, "Control applied by the actuator, held over each step")
        declare_plant_outputs(self, None, None)
        declare(self, "x1_0", PARAMETER, "Initial value of x1")
        declare(self, "x2_0", PARAMETER, "Initial value of x2")
        declare(self, "z_0", PARAMETER, "Initial value of z")
        declare_integrator(self)  # last: max_step, method, rtol, atol

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and start at the initial states."""
        raise_problems(self.modelName, plant_problems(self))
        start_plant(self)

    # the states now (the initial values until initialization has finished); the core's function
    # itself, no frame of the class's own at every read
    refresh_outputs = refresh_plant_outputs
    # in a built FMU the shim's step and refresh run in C, these methods on every other path
    compiled_calls = compiled_plant_calls

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Integrate the plant over the step with uf held."""
        return step_plant(self, example1_rhs, self._native, current_time, step_size)
