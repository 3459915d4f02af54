# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``FixedTimeController4``: the adaptive fixed-time (or finite-time) NN controller of the paper
for a plant of order n = 4; its variables, law and step are
:mod:`fmu_src.controller_core`'s (pythonfmu loads one class per script).
"""

from __future__ import annotations

from pythonfmu import Fmi2Slave

from fmu_src.controller_core import controller_fmu, declare_controller
from fmu_src.fmu_support import fmu_model


@fmu_model
@controller_fmu(4)
class FixedTimeController4(Fmi2Slave):
    """v = zeta_4 from the backstepping law of SPEC section 1, with states r and eta_hat_1..eta_hat_4."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        declare_controller(self, 4)
