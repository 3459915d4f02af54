"""Shared behaviour of the project's pythonfmu slaves, bundled into every FMU.

pythonfmu 0.7 writes neither units nor output dependencies, keeps the very object returned by
``_get_fmu_state`` and snapshots only registered variables. This module adds what is missing.
It cannot be a base class: the pythonfmu loader finds the slave with the regex
``^class (\\w+)\\(\\s*Fmi2Slave\\s*\\)\\s*:`` on the script text, so every script declares
``class Name(Fmi2Slave):`` and applies the :func:`fmu_model` decorator instead.
"""

from __future__ import annotations

import copy
import logging
import re
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TypeVar
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status

__all__ = [
    "UNITS",
    "FmuParameterError",
    "declare",
    "fmu_model",
    "LOGGER_NAME",
    "raise_problems",
    "rename_indexed",
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
}

DEFAULT_EXPERIMENT = DefaultExperiment(start_time=0.0, stop_time=30.0, step_size=0.001)

# Instance attributes that belong to pythonfmu's machinery, not to the simulation state.
_NOT_STATE = frozenset({"vars", "log_queue", "instance_name", "resources", "visible", "guid", "_fmu_meta"})

# pythonfmu's binary forwards FMU log messages (even fmi2Fatal ones) to the importer only when
# logging is on (fmi2Instantiate loggingOn / fmi2SetDebugLogging). Every problem therefore also
# goes to this Python logger, which the host process sees (stderr by default, caplog in tests).
LOGGER_NAME = "fixed_time_cosim.fmu"
_log = logging.getLogger(LOGGER_NAME)

SlaveClass = TypeVar("SlaveClass", bound=type)


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


def declare(
    slave: Fmi2Slave,
    name: str,
    causality: Fmi2Causality,
    description: str,
    *,
    unit: str | None = None,
    depends_on: Iterable[str] | None = None,
    integer: bool = False,
    getter: Callable[[], Any] | None = None,
) -> None:
    """Register one variable with its description, unit and (for outputs) input dependencies.

    Parameters and inputs live in the slave attribute of the same name, which must exist.
    Parameters are ``fixed``: changed only before initialization. ``depends_on`` lists the input
    names an output depends on directly (empty: none); ``None`` keeps the FMI default (all).
    """
    if unit is not None and unit not in UNITS:
        raise ValueError(f"{type(slave).__name__}.{name}: unknown unit {unit!r}")
    variability = Fmi2Variability.fixed if causality == Fmi2Causality.parameter else None
    if integer:
        if causality == Fmi2Causality.output:
            variability = Fmi2Variability.discrete
        variable = Integer(
            name, causality=causality, description=description, variability=variability, getter=getter
        )
    else:
        variable = Real(
            name, causality=causality, description=description, variability=variability, getter=getter
        )
    slave.register_variable(variable)
    meta = slave.__dict__.setdefault("_fmu_meta", {})
    meta[name] = (unit, None if depends_on is None else tuple(depends_on))


def _extend_model_description(slave: Fmi2Slave, root: Element) -> Element:
    """Add UnitDefinitions, unit attributes and ModelStructure dependencies to pythonfmu's XML."""
    meta: dict[str, tuple[str | None, tuple[str, ...] | None]] = slave.__dict__.get("_fmu_meta", {})
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
        position = list(root).index(root.find("CoSimulation")) + 1
        root.insert(position, definitions)

    index = {}  # name -> 1-based index in ModelVariables
    causality = {}
    for i, node in enumerate(root.find("ModelVariables"), start=1):
        name = node.get("name")
        index[name] = i
        causality[name] = node.get("causality")
        unit = meta.get(name, (None, None))[0]
        if unit is not None:
            node.find("Real").set("unit", unit)

    outputs = root.find("ModelStructure/Outputs")
    if outputs is not None:
        names = {str(i): n for n, i in index.items()}
        parameters = [index[n] for n, c in causality.items() if c == "parameter"]
        initial = Element("InitialUnknowns")
        for unknown in outputs:
            name = names[unknown.get("index")]
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
                index=unknown.get("index"),
                dependencies=" ".join(map(str, sorted(inputs + parameters))),
            )
        if len(initial):
            structure = root.find("ModelStructure")
            structure.append(initial)
    return root


def _get_fmu_state(self: Fmi2Slave) -> dict[str, Any]:
    """A deep copy of every simulation attribute (pythonfmu keeps the returned object as is)."""
    return copy.deepcopy({k: v for k, v in vars(self).items() if k not in _NOT_STATE})


def _set_fmu_state(self: Fmi2Slave, state: dict[str, Any]) -> None:
    """Restore a snapshot; copies again so one snapshot can be restored many times."""
    vars(self).update(copy.deepcopy(state))


def fmu_model(cls: SlaveClass) -> SlaveClass:
    """Class decorator: DefaultExperiment, extended model description and full state snapshots."""
    base_to_xml = cls.to_xml

    def to_xml(self: Fmi2Slave, model_options: dict[str, str] | None = None) -> Element:
        return _extend_model_description(self, base_to_xml(self, model_options or {}))

    to_xml.__doc__ = base_to_xml.__doc__
    cls.to_xml = to_xml
    cls._get_fmu_state = _get_fmu_state
    cls._set_fmu_state = _set_fmu_state
    cls.default_experiment = DEFAULT_EXPERIMENT
    return cls


def rename_indexed(message: str, renames: dict[str, str]) -> str:
    """Turn library names such as ``k[1]`` or ``eta0[2]`` into FMU parameter names."""

    def replace(match: re.Match[str]) -> str:
        base, i = match.group(1), match.group(2)
        return renames.get(base, base + "{}").format(i)

    return re.sub(r"\b(\w+)\[(\d+)\]", replace, message)
