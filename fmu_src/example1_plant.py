"""FMU ``Example1Plant``: the paper's Example 1 (eq. 85) with unmodeled dynamics z.

States advance in do_step with the input uf held over the step; outputs are the states at the
communication point and depend on no input directly.
"""

from __future__ import annotations

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, raise_problems
from fmu_src.models.plants import State, example1_rhs, integration_problems
from fmu_src.plant_core import DEFAULT_MAX_STEP, declare_plant_outputs, step_plant

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
        self.max_step = DEFAULT_MAX_STEP
        self.state: State | None = None
        declare(self, "uf", Fmi2Causality.input, "Control applied by the actuator, held over each step")
        declare_plant_outputs(self, None, None)
        declare(self, "x1_0", PARAMETER, "Initial value of x1")
        declare(self, "x2_0", PARAMETER, "Initial value of x2")
        declare(self, "z_0", PARAMETER, "Initial value of z")
        declare(
            self,
            "max_step",
            PARAMETER,
            "Largest RK4 sub-step inside a communication step (accuracy)",
            unit="s",
        )

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and start at the initial states."""
        initial = {"x1_0": self.x1_0, "x2_0": self.x2_0, "z_0": self.z_0}
        raise_problems(self.modelName, integration_problems(initial, self.max_step))
        self.state = (self.x1_0, self.x2_0, self.z_0)

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Integrate the plant over the step with uf held."""
        return step_plant(self, example1_rhs, current_time, step_size)
