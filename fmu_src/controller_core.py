# SPDX-License-Identifier: BSD-2-Clause
"""What every controller FMU shares, for a plant of order n = 1..4: its variables, their defaults and
checks, the law behind the outputs and the step. Functions, not a base class (see
:mod:`fmu_src.fmu_support`); one script per order declares ``class FixedTimeController<n>(Fmi2Slave)``
(``FixedTimeController`` for n = 2, the name the scenarios use) and calls these.

The law is :func:`controller.native.law_for`'s: compiled (``controller/_law.c``) in a built FMU,
the Python reference in the source tree, the same bits. Outputs v, z_i and zeta_i are direct
feedthrough: computed when read, for the inputs set at the current communication point (once per
input set and state). The states r and eta_hat advance in do_step with the inputs held over the
step (RK4, ``substeps`` sub-steps); the law evaluated for the outputs is the first RK4 stage.

The variables of order n, in this order (value references are a contract; n = 2 is the FMU of
before issue 35, variable for variable): inputs x1..xn, yd, yd_dot, ..., (the n-th derivative);
outputs v, z1..zn, zeta1..zeta(n-1), eta1_hat..etan_hat, r; parameters k1..kn, q1..qn, a1..an,
kappa1..kappan, rho1..rhon, rho_bar1..rho_barn, alpha, beta, mode, a_bar, gamma_gain, gamma_power,
d_r, r0, eta1_0..etan_0, mu1..mu7, tau, substeps, discretization, sample_time, b_max, nn_term.
"""

from __future__ import annotations

import math
import sys
from abc import update_abstractmethods
from collections.abc import Callable
from functools import partial
from math import isfinite
from operator import itemgetter
from typing import Any, TypeVar, cast

from pythonfmu import Fmi2Causality, Fmi2Slave
from pythonfmu.enums import Fmi2Status

from controller.native import MAX_ORDER, CompiledLaw, law_for, slave_functions
from controller.params import DEFAULT_CENTERS, ControllerParameters, Discretization, Mode, ParameterError

from .fmu_support import declare, mark_stale, raise_problems, report

__all__ = [
    "GAIN_DESCRIPTIONS",
    "compiled_controller_calls",
    "controller_fmu",
    "ORDERS",
    "controller_model",
    "declare_controller",
    "input_names",
    "output_names",
    "refresh_controller_outputs",
    "start_controller",
    "step_controller",
]

PARAMETER = Fmi2Causality.parameter
INPUT = Fmi2Causality.input
OUTPUT = Fmi2Causality.output

ORDERS = tuple(range(1, MAX_ORDER + 1))  # plant orders with a controller FMU
# Example 1's gains (SPEC section 3): name -> default for every step (a: a1 = 5, a_i = 2 from step 2
# on; SPEC 11: steps beyond 2 repeat step 2's values, the paper gives gains for n = 2 only).
GAINS = {"k": 10.0, "q": 8.0, "kappa": 2.0, "rho": 2.0, "rho_bar": 1.0}
# The law's open bounds (beta < 1, alpha > 1, q > 0 ...) as the closed min/max FMI declares: the
# nearest doubles inside, so an importer's range check refuses what the law refuses (beta = 1.0
# passed validate and failed in the FMU at t = 0, issue 36).
ABOVE_ZERO = math.nextafter(0.0, 1.0)
POSITIVE_GAINS = ("q", "a", "kappa", "rho", "rho_bar")  # k may be 0: the finite-time law (mode 1)
GAIN_DESCRIPTIONS = {
    "k": "Fast (fixed-time) gain k_{i} of step {i}",
    "q": "Gain q_{i} of the sig(z)^(2 beta - 1) term of step {i}",
    "a": "NN weight design constant a_{i} of step {i}",
    "kappa": "Adaptation gain kappa_{i} of eta_hat_{i}",
    "rho": "Leakage rho_{i} of eta_hat_{i}",
    "rho_bar": "Leakage rho_bar_{i} of eta_hat_{i}",
}
DERIVATIVES = ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")
DERIVATIVE_WORDS = ("", "", "second ", "third ", "fourth ")


SlaveClass = TypeVar("SlaveClass", bound=type[Fmi2Slave])


def controller_fmu(n: int) -> Callable[[SlaveClass], SlaveClass]:
    """Class decorator making ``class FixedTimeController<n>(Fmi2Slave)`` the controller FMU of order n:
    its description and the core's functions as ``refresh_outputs``, ``exit_initialization_mode`` and
    ``do_step`` (no frame of the class's own per call: the hot path of every step). The class defines
    ``__init__`` itself (calling :func:`declare_controller`): with one set by the decorator, pythonfmu
    0.7.0's binary frees the script's module after instantiating the slave (the host then crashes at
    exit). Apply :func:`~fmu_src.fmu_support.fmu_model` on top."""

    def make(cls: SlaveClass) -> SlaveClass:
        cls.description = (f"Adaptive fixed-time NN backstepping controller (order {n}) with actuator-fault "
                           "compensation")
        cls.refresh_outputs = refresh_controller_outputs
        cls.exit_initialization_mode = start_controller
        cls.do_step = step_controller
        cls.compiled_calls = compiled_controller_calls
        update_abstractmethods(cls)  # the class was abstract until do_step was set
        return cls

    return make


def controller_model(n: int) -> str:
    """The model name of the controller FMU for plant order ``n``; ValueError (one line) outside 1..4."""
    if n not in ORDERS:
        raise ValueError(f"there is a controller FMU for plant orders n = 1..{MAX_ORDER} (got n = {n}); "
                         "for other orders use the library (controller.stepping.AdaptiveController)")
    return "FixedTimeController" if n == 2 else f"FixedTimeController{n}"


def input_names(n: int) -> tuple[str, ...]:
    """x1..xn, then yd and its derivatives up to order n."""
    return (*(f"x{i}" for i in range(1, n + 1)), *DERIVATIVES[: n + 1])


def output_names(n: int) -> tuple[str, ...]:
    """v, z1..zn, zeta1..zeta(n-1), eta1_hat..etan_hat, r."""
    return ("v", *(f"z{i}" for i in range(1, n + 1)), *(f"zeta{i}" for i in range(1, n)),
            *(f"eta{i}_hat" for i in range(1, n + 1)), "r")


def _derivative_description(j: int) -> str:
    if j == 0:
        return "Reference yd"
    return f"Reference {DERIVATIVE_WORDS[j]}derivative yd{chr(39) * j}"


def declare_controller(slave: Fmi2Slave, n: int) -> None:
    """Register the variables of order ``n`` (module docstring) with their defaults."""
    _defaults(slave, n)
    _declare_inputs_and_outputs(slave, n)
    _declare_parameters(slave, n)


def _defaults(slave: Fmi2Slave, n: int) -> None:
    """Every variable's start value and the slave's own attributes."""
    inputs = input_names(n)
    for name in inputs:
        setattr(slave, name, 0.0)
    steps = range(1, n + 1)
    for name, default in GAINS.items():
        for i in steps:
            setattr(slave, f"{name}{i}", default)
    for i in steps:
        setattr(slave, f"a{i}", 5.0 if i == 1 else 2.0)
    slave.alpha = 1.5
    slave.beta = 0.75
    slave.mode = 0
    slave.a_bar = 1.0
    slave.gamma_gain = 2.5
    slave.gamma_power = 4.0
    slave.d_r = 0.625
    slave.r0 = 0.0
    for i in steps:
        setattr(slave, f"eta{i}_0", 0.0)
    for j, center in enumerate(DEFAULT_CENTERS, start=1):
        setattr(slave, f"mu{j}", center)
    slave.tau = 2.0
    slave.substeps = 1
    slave.discretization = 0
    slave.sample_time = 1e-3
    slave.b_max = 1.0
    slave.nn_term = 1
    slave._order = n
    slave._step_unchecked = False  # semi-implicit, and no step-size warning logged yet
    for name in output_names(n):  # written by refresh_controller_outputs
        setattr(slave, name, 0.0)
    slave._law = None  # built at exit_initialization_mode
    slave._state = ()  # (r, eta_hat_1..eta_hat_n)
    slave._stage = None  # the law behind the outputs (current unless stale)
    slave._inputs = itemgetter(*inputs)
    # the outputs in the order refresh_outputs has them: the state's r, eta_hat_i, then the law's v, z_i,
    # zeta_i (the first 2n values of its result)
    slave._outputs = ("r", *(f"eta{i}_hat" for i in range(1, n + 1)), *output_names(n)[: 2 * n])


def _declare_inputs_and_outputs(slave: Fmi2Slave, n: int) -> None:
    inputs = input_names(n)
    steps = range(1, n + 1)
    for i in steps:
        declare(slave, f"x{i}", INPUT, f"Plant state x{i}" + (" (the output y)" if i == 1 else ""))
    for j in range(n + 1):
        declare(slave, DERIVATIVES[j], INPUT, _derivative_description(j))
    declare(slave, "v", OUTPUT, f"Control v = zeta_{n} (to the actuator)", depends_on=inputs)
    declare(slave, "z1", OUTPUT, "Tracking error z1 = x1 - yd", depends_on=("x1", "yd"))
    for i in range(2, n + 1):
        depends = inputs if i == n else (*inputs[:i], *DERIVATIVES[:i])
        declare(slave, f"z{i}", OUTPUT, f"Error z{i} = x{i} - zeta{i - 1}", depends_on=depends)
    for i in range(1, n):
        declare(slave, f"zeta{i}", OUTPUT, f"Virtual control zeta{i}",
                depends_on=(*inputs[:i], *DERIVATIVES[: i + 1]))
    for i in steps:
        declare(slave, f"eta{i}_hat", OUTPUT, f"Adaptive estimate eta_hat_{i}", depends_on=())
    declare(slave, "r", OUTPUT, "Dynamic signal r of the unmodeled dynamics", depends_on=())


def _declare_parameters(slave: Fmi2Slave, n: int) -> None:
    steps = range(1, n + 1)
    for name in GAIN_DESCRIPTIONS:
        for i in steps:
            declare(slave, f"{name}{i}", PARAMETER, GAIN_DESCRIPTIONS[name].format(i=i),
                    minimum=ABOVE_ZERO if name in POSITIVE_GAINS else 0.0)
    declare(slave, "alpha", PARAMETER, "Exponent alpha > 1 of the fast term sig(z)^(2 alpha - 1)",
            minimum=math.nextafter(1.0, 2.0))
    declare(slave, "beta", PARAMETER, "Exponent 0.5 < beta < 1 of the term sig(z)^(2 beta - 1)",
            minimum=math.nextafter(0.5, 1.0), maximum=math.nextafter(1.0, 0.0))
    declare(slave, "mode", PARAMETER, "Control law: 0 = fixed-time, 1 = finite-time (k = 0)", integer=True,
            minimum=0, maximum=1)
    declare(slave, "a_bar", PARAMETER, "Decay rate a_bar of the dynamic signal r", unit="1/s",
            minimum=ABOVE_ZERO)
    declare(slave, "gamma_gain", PARAMETER, "Gain of x1^gamma_power in r' (unmodeled dynamics bound)",
            minimum=0.0)
    declare(slave, "gamma_power", PARAMETER, "Power of x1 in r'", minimum=0.0)
    declare(slave, "d_r", PARAMETER, "Constant term d_r in r'", minimum=0.0)
    declare(slave, "r0", PARAMETER, "Initial value of r", minimum=0.0)
    for i in steps:
        declare(slave, f"eta{i}_0", PARAMETER, f"Initial value of eta_hat_{i}", minimum=0.0)
    for j in range(1, len(DEFAULT_CENTERS) + 1):
        declare(slave, f"mu{j}", PARAMETER, f"Center of RBF neuron {j} (mu_{j} * ones)")
    declare(slave, "tau", PARAMETER, "Width tau of the Gaussian RBF neurons", minimum=ABOVE_ZERO)
    declare(slave, "substeps", PARAMETER, "RK4 sub-steps per communication step for r and eta_hat",
            integer=True, minimum=1)
    # Added last (issue 11), so the value references above stay where they were.
    declare(slave, "discretization", PARAMETER, "Sampled law: 0 = explicit (the paper's law held), "
            "1 = semi-implicit (min(phi(|z|), |z| / (b_max sample_time)) per step: no chattering)",
            integer=True, minimum=0, maximum=1)
    declare(slave, "sample_time", PARAMETER, "Sample time h of the semi-implicit law (the communication "
            "step)", unit="s", minimum=0.0)
    declare(slave, "b_max", PARAMETER, "Upper bound b_M of the plant's input gains g_i (paper's "
            "Assumption 3), used by the semi-implicit law", minimum=0.0)
    # Added last (issue 37), likewise.
    declare(slave, "nn_term", PARAMETER, "NN term eta_hat_i z_i P_i^T P_i / (2 a_i^2) in every zeta_i: "
            "1 = on (the paper's law), 0 = off (the ablation; eta_hat still adapts)", integer=True, minimum=0,
            maximum=1)


# The parameters of ControllerParameters these FMUs name otherwise (their per-step gains are k1, k2 ...).
RENAMED = {"width": "tau", "centers": "mu1..mu7"}


def _fmu_name(parameter: str, index: int | None) -> str:
    """The FMU's name of a parameter of ControllerParameters: ``k[1]`` is ``k1``, ``eta0[2]``
    ``eta2_0``, ``width`` ``tau`` (the library's problems are rendered with it, no text parsed)."""
    if index is None:
        return RENAMED.get(parameter, parameter)
    return f"eta{index}_0" if parameter == "eta0" else f"{parameter}{index}"


def _parameters(slave: Fmi2Slave) -> ControllerParameters:
    """The library's validated parameters; raises naming the FMU parameters."""
    n = slave._order
    problems = []
    if slave.substeps < 1:
        problems.append(f"substeps must satisfy substeps >= 1 (got {slave.substeps!r})")
    steps = range(1, n + 1)
    try:
        params = ControllerParameters(
            **{name: tuple(getattr(slave, f"{name}{i}") for i in steps) for name in GAIN_DESCRIPTIONS},
            alpha=slave.alpha,
            beta=slave.beta,
            mode=cast(Mode, slave.mode),  # an int; ControllerParameters parses and checks it
            a_bar=slave.a_bar,
            gamma_gain=slave.gamma_gain,
            gamma_power=slave.gamma_power,
            d_r=slave.d_r,
            r0=slave.r0,
            eta0=tuple(getattr(slave, f"eta{i}_0") for i in steps),
            centers=tuple(getattr(slave, f"mu{j}") for j in range(1, len(DEFAULT_CENTERS) + 1)),
            width=slave.tau,
            discretization=cast(Discretization, slave.discretization),  # likewise
            sample_time=slave.sample_time,
            b_max=slave.b_max,
            nn_term=cast(bool, slave.nn_term),  # an int; ControllerParameters checks it
        )
    except ParameterError as error:
        problems.extend(p.render(_fmu_name) for p in error.problems)
    raise_problems(slave.modelName, problems)
    return params


def _initial_state(params: ControllerParameters) -> tuple[float, ...]:
    assert params.eta0 is not None  # ControllerParameters fills it
    return (params.r0, *params.eta0)


def refresh_controller_outputs(slave: Fmi2Slave) -> None:
    """The law for the inputs set now and the current states (in initialization mode: the
    parameters set so far, validated, and the initial states r0, eta0)."""
    d = slave.__dict__
    law, state = d["_law"], d["_state"]
    if law is None:  # initialization mode
        params = _parameters(slave)
        state = _initial_state(params)
        law = law_for(params, slave.substeps)
    d["_stage"] = stage = law.evaluate(state, d["_inputs"](d))
    d.update(zip(d["_outputs"], state + stage, strict=False))  # r, eta_hat_i; v, z_i, zeta_i (then unused)


def start_controller(slave: Fmi2Slave) -> None:
    """Validate the parameters (raises, naming them) and start at r0, eta0."""
    d = slave.__dict__
    params = _parameters(slave)
    d["_law"] = law_for(params, slave.substeps)
    d["_state"] = _initial_state(params)
    d["_params"] = params
    d["_step_unchecked"] = bool(params.discretization)
    mark_stale(slave)


def step_controller(slave: Fmi2Slave, current_time: float, step_size: float) -> bool:
    """Integrate r and eta_hat over the step with the inputs held.

    Returns False (fmi2Discard, with a logged reason, state unchanged) if the states stop being
    finite.
    """
    d = slave.__dict__
    law = d["_law"]
    assert law is not None, "doStep before exitInitializationMode"
    if d["_step_unchecked"] and step_size != d["_params"].sample_time:  # equal: nothing to check
        _check_step(slave, current_time, step_size)
    # The law behind the outputs is the first RK4 stage, unless something changed since.
    inputs = d["_inputs"](d)
    state = law.advance(step_size, None if d["_fmu_stale"] else d["_stage"], d["_state"], inputs)
    d["_fmu_stale"] = True  # mark_stale
    if not isfinite(sum(state)) and not all(map(isfinite, state)):  # a finite sum: every state finite
        n = d["_order"]
        report(
            slave,
            f"non-finite state {list(state)} at t = {current_time + step_size!r} with inputs "
            f"x = {inputs[:n]}, yd = {inputs[n:]}; step rejected (fmi2Discard)",
        )
        return False
    d["_state"] = state  # its outputs r, eta_hat_i at the next refresh_outputs (the state is stale)
    return True


# The keys _law.step_slave and _law.refresh_slave read besides the variables (see _law.c): the slave's
# law, state, stage, stale flag, step-size check and parameters, and the CompiledLaw's constants (then the
# class CompiledLaw: another law, or none yet, goes to the Python functions).
_BINDING_KEYS = ("_law", "_state", "_stage", "_fmu_stale", "_step_unchecked", "_params", "sample_time",
                 "constants", "substeps")


def compiled_controller_calls(slave: Fmi2Slave, step: Callable[[float, float], bool],
                              refresh: Callable[[], None]) -> tuple[Any, ...] | None:
    """The FMU's step and output refresh in C (``_law.step_slave``, ``_law.refresh_slave``), what the
    shim calls (``compiled_calls`` of :func:`~fmu_src.fmu_support._direct_binding`): the usual path of
    :func:`step_controller` and :func:`refresh_controller_outputs` with no interpreter frame, the
    same values written; ``step`` and ``refresh`` otherwise. Then ``_law.direct_calls`` and the
    binding: the same two as C entries the shim calls with no Python call between
    (``controller/direct_calls.h``). None where the law is not compiled."""
    functions = slave_functions()
    if functions is None:
        return None
    step_slave, refresh_slave, direct_calls = functions
    n = slave._order
    binding = (slave.__dict__, step, refresh, tuple(map(sys.intern, input_names(n))),
               tuple(map(sys.intern, slave._outputs)), *map(sys.intern, _BINDING_KEYS), CompiledLaw)
    return partial(step_slave, binding), partial(refresh_slave, binding), direct_calls, binding


def _check_step(slave: Fmi2Slave, current_time: float, step_size: float) -> None:
    """Warn once when the communication step differs from the semi-implicit law's sample time."""
    params = slave._params
    if not math.isclose(step_size, params.sample_time, rel_tol=1e-9):
        slave._step_unchecked = False  # logged once
        report(slave, f"communication step {step_size!r} s at t = {current_time!r} differs from "
               f"sample_time = {params.sample_time!r} s that the semi-implicit law assumes "
               "(logged once)", Fmi2Status.warning)
