# SPDX-License-Identifier: BSD-2-Clause
"""Test FMU that fails on purpose at its ``k``-th ``do_step`` (1-based), for the fault tests.

``y`` counts the steps taken (no input needed: its value in row j is j, an exact oracle).
``mode``: 0 healthy, 1 ``do_step`` raises, 2 ``y`` becomes NaN, 3 ``y`` becomes +inf,
4 ``do_step`` returns False (fmi2Discard), 5 ``do_step`` never returns, 6 reading ``y`` raises
(fmi2GetReal fails). ``trace``: a file that gets one line per lifecycle call (terminate, free), to
check that the importer terminated and freed the instance.
"""

import math
import time

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String


class Faulty(Fmi2Slave):
    """A step counter with one fault at step k."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.mode = 0
        self.k = 1
        self.trace = ""
        self.u = 0.0
        self.steps = 0
        self.value = 0.0
        self.register_variable(Integer("mode", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(Integer("k", causality=Fmi2Causality.parameter,
                                       variability=Fmi2Variability.fixed))
        self.register_variable(String("trace", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=self._y))

    def _y(self):
        if self.mode == 6 and self.steps >= self.k:
            raise RuntimeError(f"cannot compute y after step {self.steps}")
        return self.value

    def _note(self, what):
        if self.trace:
            with open(self.trace, "a") as f:
                f.write(what + "\n")

    def do_step(self, current_time, step_size):
        self.steps += 1
        if self.steps == self.k:
            if self.mode == 1:
                raise RuntimeError(f"step {self.steps} failed on purpose")
            if self.mode == 4:
                return False
            if self.mode == 5:
                while True:
                    time.sleep(0.01)
        self.value = float(self.steps)
        if self.steps >= self.k and self.mode == 2:
            self.value = math.nan
        if self.steps >= self.k and self.mode == 3:
            self.value = math.inf
        return True

    def terminate(self):
        self._note("terminate")

    def __del__(self):
        self._note("free")
