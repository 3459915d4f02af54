# SPDX-License-Identifier: BSD-2-Clause
"""The paper's two examples in one place (SPEC section 3): plant, initial state, reference,
actuator and controller gains; and :data:`MANIPULATOR`, a third-order plant from the literature
under the same actuator (issue 35). The scenario sources (``ssp/generate.py``), the monolithic
reference simulation and the tests read them from here.

Not bundled into the FMUs (their defaults are the model dataclasses' and Example 1's gains), so
this module may import the controller package absolutely.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

from controller.params import SEMI_IMPLICIT, ControllerParameters

from .actuator import ActuatorParameters
from .manipulator import STATE_NAMES as MANIPULATOR_STATES
from .manipulator import ManipulatorParameters, input_gains, manipulator_rhs
from .plants import STATE_NAMES, PendulumParameters, State, example1_rhs, pendulum_rhs
from .reference import ReferenceParameters

__all__ = ["EXAMPLE1", "EXAMPLE2", "EXAMPLES", "MANIPULATOR", "Example"]


@dataclass(frozen=True)
class Example:
    """One of the paper's examples (or :data:`MANIPULATOR`), with the FMU that models its plant. The
    plant has three states (``states``: their names); the controller takes the first n = its order
    of them (the examples' third state z is unmeasured unmodeled dynamics)."""

    number: int
    name: str
    plant_fmu: str  # model name of the plant FMU
    plant_rhs: Callable[[float, Sequence[float], float], State] = field(repr=False)
    x0: State
    reference: ReferenceParameters
    actuator: ActuatorParameters
    controller: ControllerParameters
    plant: PendulumParameters | ManipulatorParameters | None = None  # physical parameters, if any
    stop_time: float = 30.0
    states: tuple[str, str, str] = STATE_NAMES


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

# Issue 35: the single-link manipulator driven by a DC motor (Dawson, Carroll and Schneider 1994), the
# order-3 controller sampled semi-implicitly at 1 ms (its explicit law at 1 ms diverges in the first
# step), the reference and fault of Example 1. Issue 45: one b_max caps every backstepping step at
# |z_i| / (b_max h), and with Example 1's gains (k = 10, q = 8, beta = 0.75) and b_max = 80 the law's
# feedback exceeded that cap at every sample of every run: the FMU was a linear controller
# v = -12.5 z_3. The semi-implicit cap binds where |z_i| < (q_i b_max h)^(1 / (2 - 2 beta)) (the q
# term) or |z_i| > 1 / (k_i b_max h) (the k term): beta = 0.9 shrinks the first region to
# (6 x 0.07)^5 = 0.013 (steps 1, 2) and (1 x 0.07)^5 = 2e-6 (step 3), k = 20, 20, 10 put the second
# beyond 0.7, 0.7 and 1.4, so the paper's law acts in most samples of every step
# (orchestrator/experiments/caps.py measures the share, docs/fixed-time-study/manipulator.md shows it).
# b_max = 1.75 g3 (g3 = 1 / L = 40): the masters that delay every connection (libcosim, Ecos, jacobi:
# z_(k+1) = z_k - (g3 / b_max) z_(k-1), stable for g3 / b_max < 1) stay stable with the law's own
# transient too; at b_max = 50 and 60 they diverged within 0.2 s, at b_max = 1 / L = 40 within 20 ms.
MANIPULATOR = Example(
    number=3,
    name="Manipulator (Dawson et al. 1994)",
    plant_fmu="ManipulatorPlant",
    plant_rhs=partial(manipulator_rhs, p=ManipulatorParameters()),
    x0=(0.5, 0.0, 0.0),
    reference=ReferenceParameters(amplitude=0.5, omega=1.0),
    actuator=ActuatorParameters(t_fault=10.0),
    controller=ControllerParameters(
        k=(20, 20, 10), q=(6, 6, 1), a=(5, 2, 2), kappa=(2, 2, 2), rho=(2, 2, 2), rho_bar=(1, 1, 1),
        alpha=1.5, beta=0.9, discretization=SEMI_IMPLICIT, sample_time=1e-3,
        b_max=1.75 * max(input_gains(ManipulatorParameters())),
    ),
    plant=ManipulatorParameters(),
    states=MANIPULATOR_STATES,
)
