# SPDX-License-Identifier: BSD-2-Clause
"""The Reference and Actuator FMUs' step and output refresh compiled (``_signals.c`` beside this
module): the same bits as their Python methods, with no interpreter frame per call.

Each of the two models is a few lines of arithmetic, yet cost about 12 000 instructions per
communication step in the interpreter. Their FMU classes hand the shim the functions of this module
through ``compiled_calls`` (:func:`fmu_src.fmu_support._direct_binding`): the shim then calls
``functools.partial(_signals.<function>, binding)``, where ``binding`` is a tuple made once per
slave here (its ``__dict__``, the Python methods to fall back on, the keys). The C side keeps no
state: every value stays in the slave's ``__dict__``, which state snapshots copy. Wherever the
Python code would raise or the values are not plain floats, the C function calls the Python method
instead, so every message and exception stays its own.

The FMU build compiles ``_signals.c`` into the Reference and Actuator FMUs; in the source tree,
where nothing is compiled, :data:`COMPILED` is False and the FMU classes keep their Python methods.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import astuple
from functools import partial
from typing import Any

try:
    from . import _signals  # type: ignore[attr-defined]  # compiled by the FMU build
except ImportError:
    if __name__.startswith("_ftc_"):  # bundled in an FMU (fmu_src/toolchain/build.py names the package so)
        raise  # a built FMU carries it: without it the build is broken, not slower
    _signals = None  # the source tree: the Python methods run

__all__ = ["COMPILED", "actuator_calls", "param_values", "reference_calls"]

COMPILED = _signals is not None

Step = Callable[[float, float], bool]
Refresh = Callable[[], None]
# What a compiled_calls hook hands fmu_support: the step and refresh as Python callables, and the
# extension's capsule of their C entries (controller/direct_calls.h) with the binding they take.
Compiled = tuple[Step, Refresh, Any, tuple[Any, ...]]
# The dict key under which an FMU keeps param_values() of its frozen parameters.
VALUES_KEY = "_param_values"


def param_values(params: Any) -> tuple[Any, ...] | None:
    """(params, the fields of that frozen dataclass in order), kept beside ``_params`` at
    exit_initialization_mode: the compiled refresh reads the fields from this tuple (no attribute
    lookups per call) while ``params`` is still the slave's ``_params``. None (the compiled refresh
    then calls the Python one) where a field is not a float."""
    values = astuple(params)
    return (params, *values) if all(type(value) is float for value in values) else None


def _binding(
    slave: Any, step: Step, refresh: Refresh, names: tuple[str, ...], *extra: Any
) -> tuple[Any, ...]:
    """The tuple _signals.c reads (see there): the slave's ``__dict__``, the two Python methods, the
    interned keys, then ``extra``."""
    keys = tuple(sys.intern(name) for name in ("time", "_params", VALUES_KEY, *names))
    return (slave.__dict__, step, refresh, *keys, *extra)


def reference_calls(slave: Any, step: Step, refresh: Refresh) -> Compiled | None:
    """The Reference FMU's compiled do_step and refresh_outputs (:data:`Compiled`), or None where
    not compiled."""
    if _signals is None:
        return None
    binding = _binding(slave, step, refresh, ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot"))
    return (partial(_signals.step_slave, binding), partial(_signals.reference_refresh, binding),
            _signals.reference_direct_calls, binding)


def actuator_calls(
    slave: Any, step: Step, refresh: Refresh, fault_time_tolerance: float
) -> Compiled | None:
    """The Actuator FMU's compiled do_step and refresh_outputs (:data:`Compiled`), or None where
    not compiled; the refresh snaps the time to t_fault within ``fault_time_tolerance`` as the
    Python one does."""
    if _signals is None:
        return None
    binding = _binding(slave, step, refresh, ("v", "x1", "x2", "uf", "u_dz"), float(fault_time_tolerance))
    return (partial(_signals.step_slave, binding), partial(_signals.actuator_refresh, binding),
            _signals.actuator_direct_calls, binding)
