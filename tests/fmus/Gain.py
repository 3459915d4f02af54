# SPDX-License-Identifier: BSD-2-Clause
"""Test FMU: y = k * u, direct feedthrough computed when read."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Gain(Fmi2Slave):
    """A static gain: the output follows the input at the same instant."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.k = 1.0
        self.u = 0.0
        self.register_variable(Real("k", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=lambda: self.k * self.u))

    def do_step(self, current_time, step_size):
        return True
