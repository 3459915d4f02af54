# SPDX-License-Identifier: BSD-2-Clause
"""Test FMU: y = amplitude * sin(omega * t), no inputs."""

import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Source(Fmi2Slave):
    """A sine source whose output is exact at every communication point."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.amplitude = 1.0
        self.omega = 1.0
        self.time = 0.0
        self.register_variable(Real("amplitude", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("omega", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.tunable))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    getter=lambda: self.amplitude * math.sin(self.omega * self.time)))

    def setup_experiment(self, start_time, stop_time, tolerance):
        self.time = start_time

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
