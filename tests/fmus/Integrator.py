# SPDX-License-Identifier: BSD-2-Clause
"""Test FMU: x' = u by explicit Euler over each step; x does not depend on u at the same instant.

``fail_at`` makes ``do_step`` return False (fmi2Discard) from that time on, to test failure handling.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Integrator(Fmi2Slave):
    """x_{k+1} = x_k + h * u_k: the exact oracle for the coupling tests."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x0 = 1.0
        self.x = 1.0
        self.u = 0.0
        self.fail_at = 1e300
        self.register_variable(Real("x0", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("fail_at", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        self.x = self.x0

    def do_step(self, current_time, step_size):
        if current_time >= self.fail_at:
            return False
        self.x += step_size * self.u
        return True
