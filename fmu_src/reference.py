# SPDX-License-Identifier: BSD-2-Clause
"""FMU ``Reference``: yd = amplitude sin(omega t + phase) + offset with its first four derivatives
(a controller for a plant of order n takes yd and n of them).

The outputs are the values at the current communication point t (no state besides time).
"""

from __future__ import annotations

from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave

from fmu_src.fmu_support import declare, fmu_model, mark_stale, raise_problems
from fmu_src.models.reference import ReferenceParameters, reference_derivatives, reference_problems
from fmu_src.models.signals_native import Compiled, Refresh, Step, param_values, reference_calls

PARAMETER = Fmi2Causality.parameter
OUTPUT = Fmi2Causality.output


@fmu_model
class Reference(Fmi2Slave):
    """Sinusoidal reference signal yd and its derivatives up to the fourth."""

    description = "Reference signal yd = amplitude*sin(omega*t + phase) + offset and derivatives"

    @staticmethod
    def compiled_calls(slave: Fmi2Slave, step: Step, refresh: Refresh) -> Compiled | None:
        """do_step and refresh_outputs in C (fmu_src/models/_signals.c), where the FMU build compiled
        it: the same values with no interpreter frame per call (fmu_support's ``compiled_calls``)."""
        return reference_calls(slave, step, refresh)

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.amplitude = 0.5
        self.omega = 1.0
        self.phase = 0.0
        self.offset = 0.0
        self.time = 0.0
        self.yd = self.yd_dot = self.yd_ddot = self.yd_dddot = self.yd_ddddot = 0.0  # by refresh_outputs
        self._params: ReferenceParameters | None = None  # frozen at exit_initialization_mode
        self._param_values: tuple[Any, ...] | None = None  # the compiled refresh's copy of _params
        declare(self, "yd", OUTPUT, "Reference yd(t)", depends_on=())
        declare(self, "yd_dot", OUTPUT, "First derivative yd'(t)", depends_on=())
        declare(self, "yd_ddot", OUTPUT, "Second derivative yd''(t)", depends_on=())
        declare(self, "amplitude", PARAMETER, "Amplitude of the sine")
        declare(self, "omega", PARAMETER, "Angular frequency", unit="rad/s")
        declare(self, "phase", PARAMETER, "Phase at t = 0", unit="rad")
        declare(self, "offset", PARAMETER, "Constant offset added to the sine")
        # Added last (issue 35: plants of order 3 and 4), so the value references above stay where they were.
        declare(self, "yd_dddot", OUTPUT, "Third derivative yd'''(t)", depends_on=())
        declare(self, "yd_ddddot", OUTPUT, "Fourth derivative yd''''(t)", depends_on=())

    def _parameters(self) -> ReferenceParameters:
        return ReferenceParameters(self.amplitude, self.omega, self.phase, self.offset)

    def refresh_outputs(self) -> None:
        """yd and its four derivatives at the current communication point."""
        (self.yd, self.yd_dot, self.yd_ddot, self.yd_dddot,
         self.yd_ddddot) = reference_derivatives(self.time, self._params or self._parameters())

    def setup_experiment(
        self, start_time: float, stop_time: float | None = None, tolerance: float | None = None
    ) -> None:
        """Remember the start time: the outputs at the first communication point use it."""
        self.time = start_time
        mark_stale(self)

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and freeze them for the run."""
        params = self._parameters()
        raise_problems(self.modelName, reference_problems(params))
        self._params = params
        self._param_values = param_values(params)
        mark_stale(self)

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Move to the next communication point."""
        self.time = current_time + step_size  # the outputs are stale now (fmu_model marks them)
        return True
