# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``FixedTimeController3``: the adaptive fixed-time (or finite-time) NN controller of the paper
for a plant of order n = 3; its variables, law and step are
:mod:`fmu_src.controller_core`'s (pythonfmu loads one class per script).
"""

from __future__ import annotations

from pythonfmu import Fmi2Slave

from fmu_src.controller_core import controller_fmu, declare_controller
from fmu_src.fmu_support import fmu_model


@fmu_model
@controller_fmu(3)
class FixedTimeController3(Fmi2Slave):
    """v = zeta_3 from the backstepping law of SPEC section 1, with states r and eta_hat_1..eta_hat_3."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        declare_controller(self, 3)
