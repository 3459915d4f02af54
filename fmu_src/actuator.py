# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``Actuator``: saturation (SPEC 10), input dead-zone and actuator fault between controller
and plant (SPEC 2).

``uf`` and ``u_dz`` are direct feedthrough: computed when read, from the inputs set at the
current communication point t (the absolute FMU time, as in the paper).
"""

from __future__ import annotations

import math
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, mark_stale, raise_problems
from fmu_src.models.actuator import ActuatorParameters, actuator_output, actuator_problems
from fmu_src.models.signals_native import Compiled, Refresh, Step, actuator_calls, param_values

PARAMETER = Fmi2Causality.parameter
INPUT = Fmi2Causality.input
OUTPUT = Fmi2Causality.output

# The FMU learns the time of a communication point as current_time + step_size, which can be an
# ulp away from the master's t0 + k h; a point this close to t_fault counts as t_fault.
FAULT_TIME_TOLERANCE = 1e-12


@fmu_model
class Actuator(Fmi2Slave):
    """uf = v_sat before t_fault; uf = K(t) u(v_sat) + L(t) from t_fault on; u is the dead-zone,
    v_sat = clip(v, -u_max, u_max)."""

    description = "Actuator fault (K(t), L(t)) and input dead-zone u(v) of the paper (eq. 2-6, 86-87)"

    @staticmethod
    def compiled_calls(slave: Fmi2Slave, step: Step, refresh: Refresh) -> Compiled | None:
        """do_step and refresh_outputs in C (fmu_src/models/_signals.c), where the FMU build compiled
        it: the same values with no interpreter frame per call (fmu_support's ``compiled_calls``)."""
        return actuator_calls(slave, step, refresh, FAULT_TIME_TOLERANCE)

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        defaults = ActuatorParameters()
        for name in ActuatorParameters.__dataclass_fields__:
            setattr(self, name, getattr(defaults, name))
        self.v = 0.0
        self.x1 = 0.0
        self.x2 = 0.0
        self.time = 0.0
        self.uf = self.u_dz = 0.0  # written by refresh_outputs
        self._params: ActuatorParameters | None = None  # frozen at exit_initialization_mode
        self._param_values: tuple[Any, ...] | None = None  # the compiled refresh's copy of _params
        declare(self, "v", INPUT, "Commanded control v from the controller")
        declare(self, "x1", INPUT, "Plant state x1 (enters the bias fault L(t))")
        declare(self, "x2", INPUT, "Plant state x2 (enters the bias fault L(t))")
        declare(
            self,
            "uf",
            OUTPUT,
            "Control applied to the plant: v_sat before t_fault, K(t) u(v_sat) + L(t) after "
            "(v_sat = v clipped to u_max)",
            depends_on=("v", "x1", "x2"),
        )
        declare(self, "u_dz", OUTPUT, "Dead-zone output u(v_sat)", depends_on=("v",))
        declare(self, "m_r", PARAMETER, "Dead-zone slope for v >= b_r", minimum=0.0)
        declare(self, "m_l", PARAMETER, "Dead-zone slope for v <= -b_l", minimum=0.0)
        declare(self, "b_r", PARAMETER, "Right dead-zone break point", minimum=0.0)
        declare(self, "b_l", PARAMETER, "Left dead-zone break point (at v = -b_l)", minimum=0.0)
        declare(
            self,
            "K_inf",
            PARAMETER,
            "Lasting effectiveness: K(t) = K_inf + K_amp exp(-K_rate t)",
            minimum=0.0,
        )
        declare(self, "K_amp", PARAMETER, "Decaying part of the effectiveness K(t)", minimum=0.0)
        declare(self, "K_rate", PARAMETER, "Decay rate of the effectiveness K(t)", unit="1/s", minimum=0.0)
        declare(self, "L_gain", PARAMETER, "Bias fault gain: L(t) = L_gain x2 cos(x1)^2 + L_bias")
        declare(self, "L_bias", PARAMETER, "Constant part of the bias fault L(t)")
        declare(self, "t_fault", PARAMETER, "Time at which the fault and the dead-zone start", unit="s")
        declare(  # last: the value references of the variables above are a contract
            self,
            "u_max",
            PARAMETER,
            "Saturation: v is clipped to [-u_max, u_max] before the dead-zone and the fault "
            "(default 1e300: no limit)",
            minimum=0.0,
        )

    def _parameters(self) -> ActuatorParameters:
        return ActuatorParameters(
            **{name: getattr(self, name) for name in ActuatorParameters.__dataclass_fields__}
        )

    def refresh_outputs(self) -> None:
        """uf and u_dz for the inputs set at the current communication point."""
        p = self._params or self._parameters()
        t = self.time
        if math.isfinite(p.t_fault) and abs(t - p.t_fault) <= FAULT_TIME_TOLERANCE * max(1.0, abs(p.t_fault)):
            t = p.t_fault  # (t_fault = inf: never faulty, and inf - inf is no time to snap to)
        self.uf, self.u_dz = actuator_output(t, self.v, self.x1, self.x2, p)

    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """Remember the start time: the outputs at the first communication point use it."""
        self.time = start_time
        mark_stale(self)

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and freeze them for the run."""
        params = self._parameters()
        raise_problems(self.modelName, actuator_problems(params))
        self._params = params
        self._param_values = param_values(params)
        mark_stale(self)

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Move to the next communication point (the actuator has no state)."""
        self.time = current_time + step_size  # the outputs are stale now (fmu_model marks them)
        return True
