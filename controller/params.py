# SPDX-License-Identifier: BSD-2-Clause
"""Design parameters of the adaptive fixed-time controller (SPEC section 1), validated once."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from enum import IntEnum
from typing import Any, TypeVar

__all__ = [
    "DEFAULT_CENTERS",
    "Problem",
    "EXPLICIT",
    "FINITE_TIME",
    "FIXED_TIME",
    "ControllerParameters",
    "Discretization",
    "Mode",
    "ParameterError",
    "SEMI_IMPLICIT",
]


class Mode(IntEnum):
    """Which law: the paper's fixed-time one, or its finite-time comparison method [36] (no k term).

    The value is the controller FMU's Integer parameter ``mode``; ``str()`` gives the label
    ("fixed-time") used in tables and on the command line.
    """

    FIXED_TIME = 0
    FINITE_TIME = 1

    @property
    def label(self) -> str:
        """The label: "fixed-time" or "finite-time"."""
        return self.name.lower().replace("_", "-")

    def __str__(self) -> str:
        return self.label

    @classmethod
    def parse(cls, value: object) -> Mode:
        """A Mode from itself, its integer value or its label; ValueError naming the choices."""
        return _parse_choice(cls, "mode", value)


class Discretization(IntEnum):
    """How the sampled controller evaluates the law (the controller FMU's Integer ``discretization``).

    ``EXPLICIT`` (0): the paper's law at the sample, held (the reproduction). ``SEMI_IMPLICIT`` (1):
    each step's feedback magnitude phi(|z|) = k|z|^(2 alpha-1) + q|z|^(2 beta-1) + eta_hat w |z| is
    evaluated at the sample, its sign implicitly at the next one (Acary and Brogliato 2010), which
    gives min(phi(|z|), |z| / (b_max sample_time)): the law itself wherever one sample of it cannot
    drive z through zero, the one-sample deadbeat correction inside that boundary layer.
    """

    EXPLICIT = 0
    SEMI_IMPLICIT = 1

    @property
    def label(self) -> str:
        """The label: "explicit" or "semi-implicit"."""
        return self.name.lower().replace("_", "-")

    def __str__(self) -> str:
        return self.label

    @classmethod
    def parse(cls, value: object) -> Discretization:
        """A Discretization from itself, its integer value or its label; ValueError naming the choices."""
        return _parse_choice(cls, "discretization", value)


def _parse_choice(cls: type[_Choice], name: str, value: object) -> _Choice:
    """A member of ``cls`` from itself, its integer value or its label; ValueError naming the choices."""
    if isinstance(value, str):
        for member in cls:
            if value.strip().lower() in (member.label, member.name.lower(), str(member.value)):
                return member
    elif isinstance(value, int) and not isinstance(value, bool) and value in tuple(cls):
        return cls(value)
    raise ValueError(_choices(cls, value).render(lambda _, __: name))


def _choices(cls: type[_Choice], value: object) -> Problem:
    """The problem of a value that is none of ``cls``'s members."""
    choices = " or ".join(f"{m.value} ({m.label})" for m in cls)
    name = "mode" if cls is Mode else "discretization"
    return Problem(name, None, f"{{name}} must be {choices} (got {value!r})")


_Choice = TypeVar("_Choice", Mode, Discretization)

FIXED_TIME = Mode.FIXED_TIME
FINITE_TIME = Mode.FINITE_TIME
EXPLICIT = Discretization.EXPLICIT
SEMI_IMPLICIT = Discretization.SEMI_IMPLICIT

DEFAULT_CENTERS = (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5)


@dataclass(frozen=True)
class Problem:
    """One violated constraint: the parameter (a field of :class:`ControllerParameters`), the entry
    of a per-step tuple (1-based; None: the whole value), and what is wrong, ``{name}`` standing for
    the parameter's name. A caller with other names (the controller FMU's ``k1``, ``tau`` ...)
    renders it with its own."""

    parameter: str
    index: int | None
    text: str

    def render(self, name: Callable[[str, int | None], str] | None = None) -> str:
        """The message, the parameter named by ``name(parameter, index)`` (default ``k[1]``)."""
        shown = (name or _library_name)(self.parameter, self.index)
        return self.text.replace("{name}", shown)


def _library_name(parameter: str, index: int | None) -> str:
    return parameter if index is None else f"{parameter}[{index}]"


class ParameterError(ValueError):
    """A design parameter violates the constraints of SPEC section 1; ``problems`` lists each
    (:class:`Problem`), the message joins them."""

    def __init__(self, problems: Sequence[Problem]) -> None:
        super().__init__("; ".join(p.render() for p in problems))
        self.problems = tuple(problems)


def _positive(name: str, value: float, index: int | None = None) -> Problem | None:
    if not (math.isfinite(value) and value > 0.0):
        return Problem(name, index, f"{{name}} must satisfy {{name}} > 0 (got {value!r})")
    return None


# The per-step tuples (length n) and the scalar reals of ControllerParameters.
_PER_STEP = ("k", "q", "a", "kappa", "rho", "rho_bar")
_REALS = ("alpha", "beta", "a_bar", "gamma_gain", "gamma_power", "d_r", "r0", "width", "sample_time", "b_max")


@dataclass(frozen=True)
class ControllerParameters:
    """Gains of the backstepping law for a plant of order n = len(q).

    Per-step gains are tuples of length n (index i-1 belongs to step i). In finite-time mode
    the fast gains ``k`` are not used (the law of the paper's comparison method [36]).
    ``discretization``, ``sample_time`` (s) and ``b_max`` (the bound b_M of the plant's input
    gains, the paper's Assumption 3) select how a sampled controller evaluates the law
    (:class:`Discretization`); the last two are used, and checked, only when it is semi-implicit.
    ``nn_term`` False switches the NN term eta_hat_i z_i P_i^T P_i / (2 a_i^2) out of every zeta_i
    (an ablation, issue 37; the estimates still adapt, eq. 38, and act nowhere); True is the
    paper's law, bit for bit.
    """

    k: tuple[float, ...]
    q: tuple[float, ...]
    a: tuple[float, ...]
    kappa: tuple[float, ...]
    rho: tuple[float, ...]
    rho_bar: tuple[float, ...]
    alpha: float = 1.5
    beta: float = 0.75
    mode: Mode = FIXED_TIME
    a_bar: float = 1.0
    gamma_gain: float = 2.5
    gamma_power: float = 4.0
    d_r: float = 0.625
    r0: float = 0.0
    eta0: tuple[float, ...] | None = None
    centers: tuple[float, ...] = DEFAULT_CENTERS
    width: float = 2.0
    discretization: Discretization = EXPLICIT
    sample_time: float = 1e-3
    b_max: float = 1.0
    nn_term: bool = True

    def __post_init__(self) -> None:
        self._coerce()
        problems = self._parse_choices()
        problems += self._shape_problems()
        problems += self._exponent_problems()
        problems += self._sign_problems()
        if not self.centers or not all(math.isfinite(c) for c in self.centers):
            problems.append(Problem("centers", None, "{name} must be a non-empty list of finite numbers"))
        if problems:
            raise ParameterError(problems)

    def _coerce(self) -> None:
        """Tuples of floats and floats from whatever sequences and numbers the caller gave."""
        for name in _PER_STEP + ("centers",):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        eta0 = self.eta0 if self.eta0 is not None else (0.0,) * len(self.q)
        object.__setattr__(self, "eta0", tuple(float(v) for v in eta0))
        for name in _REALS:
            object.__setattr__(self, name, float(getattr(self, name)))

    def _parse_choices(self) -> list[Problem]:
        """``mode``, ``discretization`` and ``nn_term`` as their types; a problem for each that is none."""
        problems: list[Problem] = []
        try:
            object.__setattr__(self, "mode", Mode.parse(self.mode))
        except ValueError:
            problems.append(_choices(Mode, self.mode))
        try:
            object.__setattr__(self, "discretization", Discretization.parse(self.discretization))
        except ValueError:
            problems.append(_choices(Discretization, self.discretization))
        if isinstance(self.nn_term, (bool, int)) and self.nn_term in (0, 1):
            object.__setattr__(self, "nn_term", bool(self.nn_term))
        else:
            problems.append(Problem("nn_term", None,
                                    f"{{name}} must be 1 (on) or 0 (off) (got {self.nn_term!r})"))
        return problems

    def _shape_problems(self) -> list[Problem]:
        """At least one step, and n entries in every per-step tuple."""
        problems: list[Problem] = []
        n = len(self.q)
        if n < 1:
            problems.append(Problem("q", None, "{name} must have at least one entry (plant order n >= 1)"))
        for name in _PER_STEP + ("eta0",):
            if len(getattr(self, name)) != n:
                problems.append(Problem(name, None, f"{{name}} must have n = {n} entries "
                                                    f"(got {len(getattr(self, name))})"))
        return problems

    def _exponent_problems(self) -> list[Problem]:
        """The exponents' ranges: alpha > 1, 0.5 < beta < 1."""
        problems: list[Problem] = []
        if not (self.alpha > 1.0 and math.isfinite(self.alpha)):
            problems.append(Problem("alpha", None,
                                    f"{{name}} must satisfy {{name}} > 1 (got {self.alpha!r})"))
        if not 0.5 < self.beta < 1.0:
            problems.append(Problem("beta", None,
                                    f"{{name}} must satisfy 0.5 < {{name}} < 1 (got {self.beta!r})"))
        return problems

    def _sign_problems(self) -> list[Problem]:
        """Gains that must be positive (only those the mode and discretization use), the rest >= 0."""
        found = self._positive_problems()
        assert self.eta0 is not None  # filled by _coerce
        at_least_zero: list[tuple[str, int | None, float]] = [
            (name, None, getattr(self, name)) for name in ("gamma_gain", "d_r", "gamma_power", "r0")]
        at_least_zero += [("eta0", i, v) for i, v in enumerate(self.eta0, 1)]
        return found + [Problem(name, i, f"{{name}} must satisfy {{name}} >= 0 (got {value!r})")
                        for name, i, value in at_least_zero if not (math.isfinite(value) and value >= 0.0)]

    def _positive_problems(self) -> list[Problem]:
        """The gains that must be > 0: ``k`` only in fixed-time mode, ``sample_time`` and ``b_max``
        only when semi-implicit."""
        gains: tuple[str, ...] = ("q", "a", "kappa", "rho", "rho_bar")
        if self.mode == FIXED_TIME:
            gains = ("k",) + gains
        found = [_positive(name, value, i) for name in gains
                 for i, value in enumerate(getattr(self, name), start=1)]
        used = ("a_bar", "width") + (("sample_time", "b_max") if self.discretization == SEMI_IMPLICIT else ())
        found += [_positive(name, getattr(self, name)) for name in used]
        return [p for p in found if p is not None]

    @property
    def n(self) -> int:
        """Plant order: the number of backstepping steps."""
        return len(self.q)

    @property
    def k_effective(self) -> tuple[float, ...]:
        """The fast gains the law applies: ``k`` in fixed-time mode, zeros in finite-time mode."""
        return self.k if self.mode == FIXED_TIME else (0.0,) * self.n

    def with_changes(self, **changes: Any) -> ControllerParameters:
        """A validated copy with some fields replaced."""
        return replace(self, **changes)
