# SPDX-License-Identifier: BSD-2-Clause
"""Shared behaviour of the project's pythonfmu slaves, bundled into every FMU.

pythonfmu 0.7 writes neither units nor output dependencies, keeps the very object returned by
``_get_fmu_state`` and snapshots only registered variables. This module adds what is missing.
It cannot be a base class: the pythonfmu loader finds the slave with the regex
``^class (\\w+)\\(\\s*Fmi2Slave\\s*\\)\\s*:`` on the script text, so every script declares
``class Name(Fmi2Slave):`` and applies the :func:`fmu_model` decorator instead.

It also replaces pythonfmu's ``get_real``/``set_real`` (and the Integer pair), which call one
getter or setter lambda per variable: a slave keeps every variable in the attribute of the same
name, value references map straight to those names, and outputs computed from inputs and states
are refreshed once, by the slave's ``refresh_outputs()``, when one is read after anything changed
(see :func:`declare`).

The FMU's C shim (``fmu_src/toolchain/shim/cosimulation.c``) makes the calls of every communication step
(``fmi2DoStep``, ``fmi2GetReal``/``fmi2SetReal`` of inputs and outputs) on these same attributes
itself, past pythonfmu's per-call machinery: :func:`fmu_model` offers it the slave's binding
(see :func:`_direct_binding`).
"""

from __future__ import annotations

import copy
import logging
import sys
import threading
import weakref
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

if TYPE_CHECKING:  # the model description is written at build time: a running FMU never loads xml
    from xml.etree.ElementTree import Element

__all__ = [
    "UNITS",
    "FmuParameterError",
    "assigned",
    "declare",
    "fmu_model",
    "LOGGER_NAME",
    "mark_stale",
    "raise_problems",
    "report",
]

# Unit name -> SI base-unit exponents (FMI 2.0 BaseUnit attributes).
UNITS: dict[str, dict[str, int]] = {
    "s": {"s": 1},
    "1/s": {"s": -1},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "m": {"m": 1},
    "kg": {"kg": 1},
    "m/s2": {"m": 1, "s": -2},
    "kg/s2": {"kg": 1, "s": -2},
    "N": {"kg": 1, "m": 1, "s": -2},
    # the manipulator's link and motor (issue 35)
    "A": {"A": 1},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "H": {"kg": 1, "m": 2, "s": -2, "A": -2},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "kg.m2": {"kg": 1, "m": 2},
    "N.m/A": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "V.s/rad": {"kg": 1, "m": 2, "s": -2, "A": -1, "rad": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
}

DEFAULT_EXPERIMENT = DefaultExperiment(start_time=0.0, stop_time=30.0, step_size=0.001)

# Instance attributes that belong to pythonfmu's machinery, not to the simulation state.
_NOT_STATE = frozenset(
    {"vars", "log_queue", "instance_name", "resources", "visible", "guid", "_fmu_meta", "_fmu_io",
     "_fmu_ranges"}
)

# pythonfmu's binary forwards FMU log messages (even fmi2Fatal ones) to the importer only when
# logging is on (fmi2Instantiate loggingOn / fmi2SetDebugLogging). Every problem therefore also
# goes to this Python logger, which the host process sees (stderr by default, caplog in tests).
LOGGER_NAME = "fixed_time_cosim.fmu"
_log = logging.getLogger(LOGGER_NAME)

SlaveClass = TypeVar("SlaveClass", bound=type[Fmi2Slave])


class FmuParameterError(ValueError):
    """A parameter of an FMU violates its allowed range; the message names the parameter."""


def report(slave: Fmi2Slave, message: str, status: Fmi2Status = Fmi2Status.error) -> None:
    """Send a message to the importer's FMI logger (when logging is on) and to the Python logger."""
    slave.log(message, status)
    level = logging.WARNING if status <= Fmi2Status.warning else logging.ERROR
    _log.log(level, "%s (%s): %s", slave.instance_name, slave.modelName, message)


def raise_problems(model: str, problems: Sequence[str]) -> None:
    """Raise one :class:`FmuParameterError` listing every problem, prefixed with the model name.

    Raised from ``exit_initialization_mode``: pythonfmu turns it into fmi2Fatal and passes the
    exception text (with the parameter names) to the importer's FMI logger when logging is on;
    it is also logged to the Python logger :data:`LOGGER_NAME`.
    """
    if problems:
        message = f"{model}: invalid parameters: " + "; ".join(problems)
        _log.error("%s", message)
        raise FmuParameterError(message)


class _ValueReferences:
    """Value reference -> attribute name, per type and per use (``_fmu_io`` of a slave)."""

    __slots__ = (
        "computed", "feedthrough", "integer", "integer_parameters", "real", "real_inputs", "real_parameters"
    )

    def __init__(self) -> None:
        self.real: dict[int, str] = {}  # every Real variable (read)
        self.real_inputs: dict[int, str] = {}  # Real inputs (set every step)
        self.real_parameters: dict[int, str] = {}  # Real parameters (set before initialization)
        self.integer: dict[int, str] = {}
        self.integer_parameters: dict[int, str] = {}
        self.computed: set[int] = set()  # outputs that refresh_outputs() computes
        self.feedthrough = False  # some output depends directly on an input


def declare(
    slave: Fmi2Slave,
    name: str,
    causality: Fmi2Causality,
    description: str,
    *,
    unit: str | None = None,
    depends_on: Iterable[str] | None = None,
    integer: bool = False,
    minimum: float | None = None,
    maximum: float | None = None,
) -> None:
    """Register one variable with its description, unit and (for outputs) input dependencies.

    Every variable lives in the slave attribute of the same name. Parameters and inputs must
    exist when declared; outputs are written by the slave's ``refresh_outputs()``, which
    ``fmi2GetReal`` calls before reading an output whenever an input, a parameter or the state
    has changed since (``fmi2SetReal``, ``do_step`` and initialization mark the outputs stale).
    Parameters are ``fixed``: changed only before initialization. ``depends_on`` lists the input
    names an output depends on directly (empty: none); ``None`` keeps the FMI default (all).
    ``minimum``/``maximum`` go to the variable's ``min``/``max``: the closed range the model's own
    check accepts (an open bound such as ``beta < 1`` is written as ``max="1"`` and still refused
    by the check), so importers can show and enforce it before a run.
    """
    if unit is not None and unit not in UNITS:
        raise ValueError(f"{type(slave).__name__}.{name}: unknown unit {unit!r}")
    depends = None if depends_on is None else tuple(depends_on)
    variability = Fmi2Variability.fixed if causality == Fmi2Causality.parameter else None
    if integer:
        if causality == Fmi2Causality.output:
            variability = Fmi2Variability.discrete
        variable = Integer(name, causality=causality, description=description, variability=variability)
    else:
        variable = Real(name, causality=causality, description=description, variability=variability)
    slave.register_variable(variable)
    io = slave.__dict__.setdefault("_fmu_io", _ValueReferences())
    slave.__dict__.setdefault("_fmu_stale", True)
    slave.__dict__.setdefault("_fmu_assigned", frozenset())
    vr = variable.value_reference
    if integer:
        io.integer[vr] = name
    else:
        io.real[vr] = name
    if causality == Fmi2Causality.parameter:
        (io.integer_parameters if integer else io.real_parameters)[vr] = name
    elif causality == Fmi2Causality.input and not integer:
        io.real_inputs[vr] = name
    elif causality == Fmi2Causality.output:
        io.computed.add(vr)
        io.feedthrough = io.feedthrough or depends is None or bool(depends)
    meta = slave.__dict__.setdefault("_fmu_meta", {})
    meta[name] = (unit, depends)
    if minimum is not None or maximum is not None:
        slave.__dict__.setdefault("_fmu_ranges", {})[name] = (minimum, maximum)


def assigned(slave: Fmi2Slave) -> frozenset[str]:
    """Names of the parameters the importer has set (fmi2SetReal/fmi2SetInteger) so far."""
    return slave.__dict__.get("_fmu_assigned", frozenset())


def _not_of_type(vrs: Iterable[int], known: dict[int, str], kind: str) -> TypeError:
    bad = next((vr for vr in vrs if vr not in known), None)
    return TypeError(f"Variable with valueReference={bad} is not {kind}!")


def _get_real(self: Fmi2Slave, vrs: list[int]) -> list[float]:
    """fmi2GetReal: outputs refreshed once if stale, then one dict lookup per variable."""
    d = self.__dict__
    io = d["_fmu_io"]
    if d["_fmu_stale"] and not io.computed.isdisjoint(vrs):
        self.refresh_outputs()
        d["_fmu_stale"] = False
    names = io.real
    try:
        return [d[names[vr]] for vr in vrs]
    except KeyError:
        raise _not_of_type(vrs, names, "of type Real") from None


def _set_real(self: Fmi2Slave, vrs: list[int], values: list[float]) -> None:
    """fmi2SetReal: inputs and parameters straight into their attributes; the outputs become stale
    (after an input only if some output depends on an input directly)."""
    d = self.__dict__
    io = d["_fmu_io"]
    inputs = io.real_inputs
    stale = io.feedthrough
    for vr, value in zip(vrs, values, strict=True):
        name = inputs.get(vr)
        if name is None:
            name = io.real_parameters.get(vr)
            if name is None:
                raise _not_of_type([vr], {}, "a Real input or parameter")
            d["_fmu_assigned"] = d["_fmu_assigned"] | {name}
            stale = True
        d[name] = value
    if stale:
        d["_fmu_stale"] = True


def _get_integer(self: Fmi2Slave, vrs: list[int]) -> list[int]:
    """fmi2GetInteger: the attributes of Integer variables."""
    d = self.__dict__
    names = d["_fmu_io"].integer
    try:
        return [int(d[names[vr]]) for vr in vrs]
    except KeyError:
        raise _not_of_type(vrs, names, "of type Integer") from None


def _set_integer(self: Fmi2Slave, vrs: list[int], values: list[int]) -> None:
    """fmi2SetInteger: Integer parameters (the only Integer variables that can be set)."""
    d = self.__dict__
    names = d["_fmu_io"].integer_parameters
    for vr, value in zip(vrs, values, strict=True):
        name = names.get(vr)
        if name is None:
            raise _not_of_type([vr], {}, "an Integer parameter")
        d[name] = value
        d["_fmu_assigned"] = d["_fmu_assigned"] | {name}
    d["_fmu_stale"] = True


def mark_stale(slave: Fmi2Slave) -> None:
    """The state or time has changed: recompute the outputs at their next read."""
    slave.__dict__["_fmu_stale"] = True


def _child(parent: Element, path: str) -> Element:
    """The element at ``path`` under ``parent``, which pythonfmu's XML always has."""
    child = parent.find(path)
    if child is None:
        raise ValueError(f"pythonfmu's modelDescription has no {path} under <{parent.tag}>")
    return child


def _extend_model_description(slave: Fmi2Slave, root: Element) -> Element:
    """Add UnitDefinitions, unit and min/max attributes and ModelStructure dependencies to
    pythonfmu's XML."""
    from xml.etree.ElementTree import Element, SubElement

    meta: dict[str, tuple[str | None, tuple[str, ...] | None]] = slave.__dict__.get("_fmu_meta", {})
    ranges: dict[str, tuple[float | None, float | None]] = slave.__dict__.get("_fmu_ranges", {})
    used_units = sorted({unit for unit, _ in meta.values() if unit is not None})
    if used_units:
        definitions = Element("UnitDefinitions")
        for unit in used_units:
            SubElement(
                SubElement(definitions, "Unit", name=unit),
                "BaseUnit",
                {k: str(v) for k, v in UNITS[unit].items()},
            )
        # Schema order: CoSimulation, UnitDefinitions, TypeDefinitions, LogCategories, ...
        position = list(root).index(_child(root, "CoSimulation")) + 1
        root.insert(position, definitions)

    index: dict[str, int] = {}  # name -> 1-based index in ModelVariables
    causality: dict[str, str | None] = {}
    for i, node in enumerate(_child(root, "ModelVariables"), start=1):
        name = node.get("name", "")
        index[name] = i
        causality[name] = node.get("causality")
        variable_unit = meta.get(name, (None, None))[0]
        if variable_unit is not None:
            _child(node, "Real").set("unit", variable_unit)
        low, high = ranges.get(name, (None, None))
        real = node.find("Real")
        typed = real if real is not None else _child(node, "Integer")
        for attribute, bound in (("min", low), ("max", high)):
            if bound is not None:
                typed.set(attribute, repr(int(bound)) if typed.tag == "Integer" else repr(float(bound)))

    outputs = root.find("ModelStructure/Outputs")
    if outputs is not None:
        names = {str(i): n for n, i in index.items()}
        parameters = [index[n] for n, c in causality.items() if c == "parameter"]
        initial = Element("InitialUnknowns")
        for unknown in outputs:
            name = names[unknown.get("index", "")]
            depends = meta.get(name, (None, None))[1]
            if depends is None:
                continue
            for dependency in depends:
                if causality.get(dependency) != "input":
                    raise ValueError(f"{name} depends on {dependency!r}, which is not an input")
            inputs = sorted(index[d] for d in depends)
            unknown.set("dependencies", " ".join(map(str, inputs)))
            # At initialization an output may also depend on every (exact) parameter.
            SubElement(
                initial,
                "Unknown",
                index=unknown.get("index", ""),
                dependencies=" ".join(map(str, sorted(inputs + parameters))),
            )
        if len(initial):
            _child(root, "ModelStructure").append(initial)
    return root


def _get_fmu_state(self: Fmi2Slave) -> dict[str, Any]:
    """A deep copy of every simulation attribute (pythonfmu keeps the returned object as is)."""
    return copy.deepcopy({k: v for k, v in vars(self).items() if k not in _NOT_STATE})


def _set_fmu_state(self: Fmi2Slave, state: dict[str, Any]) -> None:
    """Restore a snapshot; copies again so one snapshot can be restored many times."""
    vars(self).update(copy.deepcopy(state))
    mark_stale(self)


# The binding handed to the shim; bump with the shim's DIRECT_PROTOCOL when the tuple changes.
DIRECT_PROTOCOL = 3
_KIND_INPUT, _KIND_OUTPUT = 1, 2


def _direct_binding(slave: Fmi2Slave, do_step: Any) -> tuple[Any, ...]:
    """What the shim's direct calls need (see ``cosimulation.c``): (protocol, the
    slave's ``__dict__``, ``do_step`` bound to the slave, its ``refresh_outputs`` bound, the log
    queue pythonfmu forwards, value reference -> name, value reference -> kind (bytes: 1 Real input,
    2 Real output, 0 any other), whether an output depends directly on an input, the keys of the
    stale flag and of a kept exception, then the C entries of the two calls (a capsule, see
    ``controller/direct_calls.h``) and the binding they take, or None and None).

    The shim calls the two bound methods itself, with no Python wrapper between (a frame less per
    call, four FMUs twice a step): after ``do_step`` it sets the stale flag, whatever happened, and
    keeps an exception it raised under the second key, where the class's ``do_step`` as pythonfmu
    calls it raises that very exception (:func:`fmu_model`), so that pythonfmu reports it as
    usual; a true result is fmi2OK, a false one fmi2Discard. After ``refresh_outputs`` it clears
    the stale flag.

    A class that sets ``compiled_calls`` (a function of the slave and its two bound methods) hands
    the shim what that returns instead, unless None: two callables in C (the model's extension)
    that do what the two methods do on the usual path, with no interpreter frame, and call them
    otherwise (initialization, a rejected step, an error), so that every message stays theirs;
    and the capsule of their C entries with their binding, which the shim calls first, with no
    Python call at all (no argument tuple, no float objects for the time and step), leaving every
    path but the usual one to the two callables."""
    d = slave.__dict__
    io: _ValueReferences = d["_fmu_io"]
    step, refresh = do_step.__get__(slave), slave.refresh_outputs
    compiled = getattr(type(slave), "compiled_calls", None)
    calls = compiled(slave, step, refresh) if compiled is not None else None
    capsule = model_binding = None
    if calls is not None:
        step, refresh, capsule, model_binding = calls
    size = max(io.real, default=-1) + 1
    names: list[str | None] = [None] * size
    kinds = bytearray(size)
    for vr, name in io.real_inputs.items():
        names[vr], kinds[vr] = sys.intern(name), _KIND_INPUT
    for vr in io.computed:
        if vr in io.real:
            names[vr], kinds[vr] = sys.intern(io.real[vr]), _KIND_OUTPUT
    return (DIRECT_PROTOCOL, d, step, refresh, slave.log_queue, tuple(names),
            bytes(kinds), io.feedthrough, sys.intern("_fmu_stale"), sys.intern("_fmu_raised"), capsule,
            model_binding)


def _claim(model: str, instance_name: str) -> tuple[Any, ...] | None:
    """The shim's ``sys._ftc_fmu_claim``: the binding of the slave constructed last in this thread,
    if it is an instance ``instance_name`` of ``model`` (pythonfmu has just constructed it in
    fmi2Instantiate or fmi2Reset), else None (the shim then forwards every call to pythonfmu)."""
    ref = _constructed().pop(threading.get_ident(), None)
    slave = ref() if ref is not None else None
    if slave is None or type(slave).__name__ != model or slave.instance_name != instance_name:
        return None
    return slave._fmu_direct_binding()


def _constructed() -> dict[int, weakref.ReferenceType[Fmi2Slave]]:
    """Thread id -> the slave constructed last in that thread, shared by every FMU in the process
    (each bundles its own copy of this module): kept in ``sys``, with the first copy's claim."""
    registry: dict[int, weakref.ReferenceType[Fmi2Slave]] = sys.__dict__.setdefault("_ftc_fmu_slaves", {})
    sys.__dict__.setdefault("_ftc_fmu_claim", _claim)
    return registry


def fmu_model(cls: SlaveClass) -> SlaveClass:
    """Class decorator: DefaultExperiment, extended model description, full state snapshots and
    attribute-based get/set (the class defines ``refresh_outputs()``, see :func:`declare`); the
    outputs are marked stale after every ``do_step`` (the class's own need not)."""
    if not callable(getattr(cls, "refresh_outputs", None)):
        raise TypeError(f"{cls.__name__} must define refresh_outputs()")
    base_to_xml = cls.to_xml

    def to_xml(self: Fmi2Slave, model_options: dict[str, str] | None = None) -> Element:
        return _extend_model_description(self, base_to_xml(self, model_options or {}))

    to_xml.__doc__ = base_to_xml.__doc__
    cls.to_xml = to_xml
    cls._get_fmu_state = _get_fmu_state
    cls._set_fmu_state = _set_fmu_state
    cls.get_real = _get_real
    cls.set_real = _set_real
    cls.get_integer = _get_integer
    cls.set_integer = _set_integer
    cls.default_experiment = DEFAULT_EXPERIMENT

    base_init, own_do_step = cls.__init__, cls.do_step

    def init(self: Fmi2Slave, **kwargs: Any) -> None:
        base_init(self, **kwargs)
        _constructed()[threading.get_ident()] = weakref.ref(self)

    def do_step(self: Fmi2Slave, current_time: float, step_size: float) -> bool:
        raised = self.__dict__.pop("_fmu_raised", None)
        if raised is not None:  # the shim's direct call raised it: pythonfmu reports it now
            raise raised
        try:
            return own_do_step(self, current_time, step_size)
        finally:
            self.__dict__["_fmu_stale"] = True  # as the direct call's step: the class's do_step need not

    def direct_binding(self: Fmi2Slave) -> tuple[Any, ...]:
        return _direct_binding(self, own_do_step)

    init.__doc__, do_step.__doc__ = base_init.__doc__, own_do_step.__doc__
    cls.__init__ = init
    cls.do_step = do_step
    cls._fmu_direct_binding = direct_binding
    return cls
