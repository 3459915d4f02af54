"""FMU ``FixedTimeController``: the adaptive fixed-time (or finite-time) NN controller of the
paper for a plant of order n = 2, wrapping :class:`controller.order2.Order2Controller` (the
library's :class:`~controller.stepping.AdaptiveController` specialised to n = 2, equal to it).

``v``, ``z1``, ``z2`` and ``zeta1`` are direct feedthrough: computed when read, for the inputs
set at the current communication point (once per input set and state). The states r and
eta_hat advance in do_step with the inputs held over the step (RK4, ``substeps`` sub-steps); the
law evaluated for the outputs is the first RK4 stage.
"""

from __future__ import annotations

import math
from typing import cast

from pythonfmu import Fmi2Causality, Fmi2Slave
from pythonfmu.enums import Fmi2Status

from controller.order2 import Order2Controller, Stage
from controller.params import DEFAULT_CENTERS, ControllerParameters, Discretization, Mode, ParameterError
from fmu_src.fmu_support import declare, fmu_model, mark_stale, raise_problems, report

PARAMETER = Fmi2Causality.parameter
INPUT = Fmi2Causality.input
OUTPUT = Fmi2Causality.output

INPUTS = ("x1", "x2", "yd", "yd_dot", "yd_ddot")
# Example 1 gains (SPEC section 3): name -> default, per backstepping step i = 1, 2.
GAINS = {"k": 10.0, "q": 8.0, "kappa": 2.0, "rho": 2.0, "rho_bar": 1.0}
GAIN_DESCRIPTIONS = {
    "k": "Fast (fixed-time) gain k_{i} of step {i}",
    "q": "Gain q_{i} of the sig(z)^(2 beta - 1) term of step {i}",
    "a": "NN weight design constant a_{i} of step {i}",
    "kappa": "Adaptation gain kappa_{i} of eta_hat_{i}",
    "rho": "Leakage rho_{i} of eta_hat_{i}",
    "rho_bar": "Leakage rho_bar_{i} of eta_hat_{i}",
}


# The parameters of ControllerParameters this FMU names otherwise (its per-step gains are k1, k2 ...).
RENAMED = {"width": "tau", "centers": "mu1..mu7"}


def _fmu_name(parameter: str, index: int | None) -> str:
    """This FMU's name of a parameter of ControllerParameters: ``k[1]`` is ``k1``, ``eta0[2]``
    ``eta2_0``, ``width`` ``tau`` (the library's problems are rendered with it, no text parsed)."""
    if index is None:
        return RENAMED.get(parameter, parameter)
    return f"eta{index}_0" if parameter == "eta0" else f"{parameter}{index}"


@fmu_model
class FixedTimeController(Fmi2Slave):
    """v = zeta_2 from the backstepping law of SPEC section 1, with states r, eta1_hat, eta2_hat."""

    description = "Adaptive fixed-time NN backstepping controller (order 2) with actuator-fault compensation"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for name in INPUTS:
            setattr(self, name, 0.0)
        for name, default in GAINS.items():
            setattr(self, f"{name}1", default)
            setattr(self, f"{name}2", default)
        self.a1, self.a2 = 5.0, 2.0
        self.alpha = 1.5
        self.beta = 0.75
        self.mode = 0
        self.a_bar = 1.0
        self.gamma_gain = 2.5
        self.gamma_power = 4.0
        self.d_r = 0.625
        self.r0 = 0.0
        self.eta1_0 = 0.0
        self.eta2_0 = 0.0
        for j, center in enumerate(DEFAULT_CENTERS, start=1):
            setattr(self, f"mu{j}", center)
        self.tau = 2.0
        self.substeps = 1
        self.discretization = 0
        self.sample_time = 1e-3
        self.b_max = 1.0
        self._warned_step = False  # the step != sample_time warning, logged once
        # Outputs, written by refresh_outputs.
        self.v = self.z1 = self.z2 = self.zeta1 = self.eta1_hat = self.eta2_hat = self.r = 0.0
        self._controller: Order2Controller | None = None  # built at exit_initialization_mode
        self._stage: Stage | None = None  # the law behind the outputs (current unless stale)

        descriptions = {
            "x1": "Plant state x1 (the output y)",
            "x2": "Plant state x2",
            "yd": "Reference yd",
            "yd_dot": "Reference derivative yd'",
            "yd_ddot": "Reference second derivative yd''",
        }
        for name in INPUTS:
            declare(self, name, INPUT, descriptions[name])
        declare(self, "v", OUTPUT, "Control v = zeta_2 (to the actuator)", depends_on=INPUTS)
        declare(self, "z1", OUTPUT, "Tracking error z1 = x1 - yd", depends_on=("x1", "yd"))
        declare(self, "z2", OUTPUT, "Error z2 = x2 - zeta1", depends_on=INPUTS)
        declare(self, "zeta1", OUTPUT, "Virtual control zeta1", depends_on=("x1", "yd", "yd_dot"))
        declare(self, "eta1_hat", OUTPUT, "Adaptive estimate eta_hat_1", depends_on=())
        declare(self, "eta2_hat", OUTPUT, "Adaptive estimate eta_hat_2", depends_on=())
        declare(self, "r", OUTPUT, "Dynamic signal r of the unmodeled dynamics", depends_on=())
        for name in ("k", "q", "a", "kappa", "rho", "rho_bar"):
            for i in (1, 2):
                declare(self, f"{name}{i}", PARAMETER, GAIN_DESCRIPTIONS[name].format(i=i), minimum=0.0)
        declare(
            self, "alpha", PARAMETER, "Exponent alpha > 1 of the fast term sig(z)^(2 alpha - 1)", minimum=1.0
        )
        declare(
            self,
            "beta",
            PARAMETER,
            "Exponent 0.5 < beta < 1 of the term sig(z)^(2 beta - 1)",
            minimum=0.5,
            maximum=1.0,
        )
        declare(
            self,
            "mode",
            PARAMETER,
            "Control law: 0 = fixed-time, 1 = finite-time (k = 0)",
            integer=True,
            minimum=0,
            maximum=1,
        )
        declare(self, "a_bar", PARAMETER, "Decay rate a_bar of the dynamic signal r", unit="1/s", minimum=0.0)
        declare(
            self,
            "gamma_gain",
            PARAMETER,
            "Gain of x1^gamma_power in r' (unmodeled dynamics bound)",
            minimum=0.0,
        )
        declare(self, "gamma_power", PARAMETER, "Power of x1 in r'", minimum=0.0)
        declare(self, "d_r", PARAMETER, "Constant term d_r in r'", minimum=0.0)
        declare(self, "r0", PARAMETER, "Initial value of r", minimum=0.0)
        declare(self, "eta1_0", PARAMETER, "Initial value of eta_hat_1", minimum=0.0)
        declare(self, "eta2_0", PARAMETER, "Initial value of eta_hat_2", minimum=0.0)
        for j in range(1, len(DEFAULT_CENTERS) + 1):
            declare(self, f"mu{j}", PARAMETER, f"Center of RBF neuron {j} (mu_{j} * ones)")
        declare(self, "tau", PARAMETER, "Width tau of the Gaussian RBF neurons", minimum=0.0)
        declare(
            self,
            "substeps",
            PARAMETER,
            "RK4 sub-steps per communication step for r and eta_hat",
            integer=True,
            minimum=1,
        )
        # Added last (issue 11), so the value references above stay where they were.
        declare(self, "discretization", PARAMETER, "Sampled law: 0 = explicit (the paper's law held), "
                "1 = semi-implicit (min(phi(|z|), |z| / (b_max sample_time)) per step: no chattering)",
                integer=True, minimum=0, maximum=1)
        declare(self, "sample_time", PARAMETER, "Sample time h of the semi-implicit law (the communication "
                "step)", unit="s", minimum=0.0)
        declare(self, "b_max", PARAMETER, "Upper bound b_M of the plant's input gains g_i (paper's "
                "Assumption 3), used by the semi-implicit law", minimum=0.0)

    def _parameters(self) -> ControllerParameters:
        """The library's validated parameters; raises naming the FMU parameters."""
        problems = []
        if self.substeps < 1:
            problems.append(f"substeps must satisfy substeps >= 1 (got {self.substeps!r})")
        try:
            params = ControllerParameters(
                **{
                    name: (getattr(self, f"{name}1"), getattr(self, f"{name}2")) for name in GAIN_DESCRIPTIONS
                },
                alpha=self.alpha,
                beta=self.beta,
                mode=cast(Mode, self.mode),  # an int; ControllerParameters parses and checks it
                a_bar=self.a_bar,
                gamma_gain=self.gamma_gain,
                gamma_power=self.gamma_power,
                d_r=self.d_r,
                r0=self.r0,
                eta0=(self.eta1_0, self.eta2_0),
                centers=tuple(getattr(self, f"mu{j}") for j in range(1, len(DEFAULT_CENTERS) + 1)),
                width=self.tau,
                discretization=cast(Discretization, self.discretization),  # likewise
                sample_time=self.sample_time,
                b_max=self.b_max,
            )
        except ParameterError as error:
            problems.extend(p.render(_fmu_name) for p in error.problems)
        raise_problems(self.modelName, problems)
        return params

    def refresh_outputs(self) -> None:
        """The law for the inputs set now and the current states (in initialization mode: the
        parameters set so far, validated)."""
        c = self._controller
        if c is None:
            c = Order2Controller(self._parameters(), self.substeps)
        self._stage = stage = c.stage(self.x1, self.x2, self.yd, self.yd_dot, self.yd_ddot)
        law = stage[0]
        self.v, self.z1, self.z2, self.zeta1 = law[0], law[1], law[2], law[3]
        self.r, self.eta1_hat, self.eta2_hat = c.r, c.eta1, c.eta2

    def exit_initialization_mode(self) -> None:
        """Validate the parameters (raises, naming them) and start at r0, eta0."""
        self._controller = Order2Controller(self._parameters(), self.substeps)
        mark_stale(self)

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Integrate r and eta_hat over the step with the inputs held.

        Returns False (fmi2Discard, with a logged reason, state unchanged) if the states stop
        being finite.
        """
        c = self._controller
        assert c is not None, "doStep before exitInitializationMode"
        if c.params.discretization and not self._warned_step and not math.isclose(
                step_size, c.params.sample_time, rel_tol=1e-9):
            self._warned_step = True
            report(self, f"communication step {step_size!r} s at t = {current_time!r} differs from "
                   f"sample_time = {c.params.sample_time!r} s that the semi-implicit law assumes "
                   "(logged once)", Fmi2Status.warning)
        # The law behind the outputs is the first RK4 stage, unless something changed since.
        first = None if self._fmu_stale else self._stage
        before = (c.r, c.eta1, c.eta2)
        c.advance(self.x1, self.x2, self.yd, self.yd_dot, self.yd_ddot, step_size, first)
        mark_stale(self)
        if not (math.isfinite(c.r) and math.isfinite(c.eta1) and math.isfinite(c.eta2)):
            report(
                self,
                f"non-finite state {c.state} at t = {current_time + step_size!r} with inputs "
                f"x = {(self.x1, self.x2)}, yd = {(self.yd, self.yd_dot, self.yd_ddot)}; "
                "step rejected (fmi2Discard)",
            )
            c.r, c.eta1, c.eta2 = before
            return False
        return True
