# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``FixedTimeController``: the adaptive fixed-time (or finite-time) NN controller of the paper
for a plant of order n = 2 (the name the paper's scenarios use); its variables, law and step are
:mod:`fmu_src.controller_core`'s (pythonfmu loads one class per script).
"""

from __future__ import annotations

from pythonfmu import Fmi2Slave

from fmu_src.controller_core import controller_fmu, declare_controller
from fmu_src.fmu_support import fmu_model


@fmu_model
@controller_fmu(2)
class FixedTimeController(Fmi2Slave):
    """v = zeta_2 from the backstepping law of SPEC section 1, with states r and eta_hat_1..eta_hat_2."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        declare_controller(self, 2)
