"""The paper's two examples in one place (SPEC section 3): plant, initial state, reference,
actuator and controller gains. The scenario sources (``ssp/generate.py``), the monolithic
reference simulation and the tests read them from here.

Not bundled into the FMUs (their defaults are the model dataclasses' and Example 1's gains), so
this module may import the controller package absolutely.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

from controller.params import ControllerParameters

from .actuator import ActuatorParameters
from .plants import PendulumParameters, State, example1_rhs, pendulum_rhs
from .reference import ReferenceParameters

__all__ = ["EXAMPLE1", "EXAMPLE2", "EXAMPLES", "Example"]


@dataclass(frozen=True)
class Example:
    """One of the paper's examples, with the FMU that models its plant."""

    number: int
    name: str
    plant_fmu: str  # model name of the plant FMU
    plant_rhs: Callable[[float, Sequence[float], float], State] = field(repr=False)
    x0: State
    reference: ReferenceParameters
    actuator: ActuatorParameters
    controller: ControllerParameters
    plant: PendulumParameters | None = None  # physical parameters, where the plant has any
    stop_time: float = 30.0


EXAMPLE1 = Example(
    number=1,
    name="Example 1",
    plant_fmu="Example1Plant",
    plant_rhs=example1_rhs,
    x0=(0.5, 0.5, 0.0),
    reference=ReferenceParameters(amplitude=0.5, omega=1.0),
    actuator=ActuatorParameters(t_fault=10.0),
    controller=ControllerParameters(
        k=(10, 10), q=(8, 8), a=(5, 2), kappa=(2, 2), rho=(2, 2), rho_bar=(1, 1), alpha=1.5, beta=0.75,
        b_max=3.0,  # input gains 2 + sin(x1) and 2 + cos(x1 x2) <= 3 (paper's Assumption 3)
    ),
)

EXAMPLE2 = Example(
    number=2,
    name="Example 2 (pendulum)",
    plant_fmu="PendulumPlant",
    plant_rhs=partial(pendulum_rhs, p=PendulumParameters()),
    x0=(0.6, 0.1, 0.0),
    reference=ReferenceParameters(amplitude=1.0, omega=0.5),
    actuator=ActuatorParameters(t_fault=5.0),
    controller=ControllerParameters(
        k=(25, 25), q=(20, 20), a=(5, 2), kappa=(2, 2), rho=(1, 1), rho_bar=(2, 1), alpha=1.5, beta=0.75,
        b_max=1.0,  # input gains 1 (x1' = x2 + ...) and 1 / (M L) = 1
    ),
    plant=PendulumParameters(),
)

EXAMPLES: dict[int, Example] = {1: EXAMPLE1, 2: EXAMPLE2}
