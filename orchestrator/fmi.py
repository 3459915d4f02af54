# SPDX-License-Identifier: BSD-2-Clause
"""FMI 2.0 and 3.0 co-simulation instances as the masters use them: extracted, instantiated, their
hot functions bound once, every failure turned into a :class:`~orchestrator.errors.SimulationError`.

fmpy loads the FMU and offers checked wrappers for the rare calls (setup, initialization mode,
start values, terminate). The calls made every communication step (``fmi2DoStep``,
``fmi2GetReal``, ``fmi2SetReal``) are rebound from the same library as ``ctypes.PyDLL`` functions
on prepared arrays: no per-call conversion, and the GIL is kept, which a Python-based FMU
(pythonfmu) would otherwise have to take back at once. Status codes keep fmpy's names
(``fmi2OK`` ... ``fmi2Pending``).

An FMI 3.0 FMU (``fmiVersion`` 3.x) is instantiated with fmpy's ``FMU3Slave`` (Co-Simulation,
no early return; event mode used when it has clocks, :mod:`orchestrator.clocks`) and offers the
same interface: the masters' ``get_real``, ``set_real`` and ``do_step`` call ``fmi3GetFloat64``,
``fmi3SetFloat64`` and ``fmi3DoStep`` (its output arguments read: ``eventHandlingNeeded`` is what
:meth:`Instance.event_requested` returns), parameters are set as Float64, Int32 or Boolean, and
failures name the FMI 3.0 function and status (``fmi3DoStep returned fmi3Discard``). An instance
in event mode is driven by :meth:`Instance.tick`.

An FMI 1.0 Co-Simulation FMU is instantiated with fmpy's ``FMU1Slave``: its functions carry the
model identifier as prefix (``<id>_fmiDoStep``), which the hot calls are bound to. FMI 1.0 has no
initialization mode: start values are set once after instantiation, ``setup`` is
``fmiInitializeSlave`` (after which only inputs may be set: the master's second pass of start
values is skipped), and ``exit_initialization`` does nothing.
"""

from __future__ import annotations

import copy
import ctypes
import logging
import os
import select
import signal
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from ctypes import POINTER, byref, c_bool, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path
from time import monotonic
from typing import NoReturn
from weakref import WeakValueDictionary, finalize

import fmpy
from fmpy.fmi1 import (
    FMICallException,
    FMU1Slave,
    fmi1CallbackAllocateMemoryTYPE,
    fmi1CallbackFreeMemoryTYPE,
    fmi1CallbackFunctions,
    fmi1CallbackLoggerTYPE,
)
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Discard,
    fmi2Fatal,
    fmi2Warning,
)
from fmpy.fmi3 import FMU3Slave, fmi3ValueReference
from lxml import etree

from .errors import ScenarioError, SimulationError
from .fmucache import release, unpack_fmu

__all__ = ["CALLS", "FAILED", "LOAD_TIMEOUT", "Instance", "InstanceBase", "MessageLog", "failed_call",
           "fmi_version", "interpreter_guard", "load_problem", "trace"]

log = logging.getLogger(__name__)

# A status at or above this is a failed call (fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending).
FAILED = fmi2Discard
UPDATES = 100  # fmi3UpdateDiscreteStates calls at one event before an FMU that never settles is an error
_SETTERS = {"Real": "setReal", "Integer": "setInteger", "Enumeration": "setInteger", "Boolean": "setBoolean",
            "String": "setString"}
_SETTERS3 = {"Float64": "setFloat64", "Int32": "setInt32", "Boolean": "setBoolean"}
# The FMI 3.0 function that does what the masters name by its FMI 2.0 name.
_FMI3_FUNCTIONS = {"fmi2DoStep": "fmi3DoStep", "fmi2GetReal": "fmi3GetFloat64",
                   "fmi2SetReal": "fmi3SetFloat64", "fmi2Instantiate": "fmi3InstantiateCoSimulation"}
_FMI3_STATUS = ("fmi3OK", "fmi3Warning", "fmi3Discard", "fmi3Error", "fmi3Fatal")
# The FMI 1.0 name of each function the masters name by its FMI 2.0 name.
_FMI1_FUNCTIONS = {"fmi2DoStep": "fmiDoStep", "fmi2GetReal": "fmiGetReal", "fmi2SetReal": "fmiSetReal",
                   "fmi2GetInteger": "fmiGetInteger", "fmi2SetInteger": "fmiSetInteger",
                   "fmi2Instantiate": "fmiInstantiateSlave", "fmi2SetupExperiment": "fmiInitializeSlave",
                   "fmi2Terminate": "fmiTerminateSlave"}
_FMI1_STATUS = ("fmiOK", "fmiWarning", "fmiDiscard", "fmiError", "fmiFatal", "fmiPending")


@contextmanager
def interpreter_guard() -> Iterator[None]:
    """Undo what FMUs written in Python do to this interpreter: pythonfmu puts each FMU's resources
    folder on sys.path and imports from it (even its bundled copy of pythonfmu), which would shadow
    our own modules after the run. Restores sys.path and forgets modules imported from those folders."""
    path, before = list(sys.path), set(sys.modules)
    try:
        yield
    finally:
        added = [p for p in sys.path if p and p not in path]
        sys.path[:] = path
        for name in set(sys.modules) - before:
            file = getattr(sys.modules[name], "__file__", None) or ""
            if any(file.startswith(p) for p in added):
                del sys.modules[name]


class MessageLog:
    """The FMI callbacks given to every instance: the logger keeps each instance's last warning or
    error (so a failure is reported on one line with the FMU's own explanation) and forwards every
    message to the Python logger ``orchestrator.fmi``."""

    def __init__(self) -> None:
        self.last: dict[str, str] = {}
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        self.callbacks1 = fmi1CallbackFunctions()  # FMI 1.0: the same logger, no variadic formatting
        self.callbacks1.logger = fmi1CallbackLoggerTYPE(self._log)
        self.callbacks1.allocateMemory = fmi1CallbackAllocateMemoryTYPE(fmpy.calloc)
        self.callbacks1.freeMemory = fmi1CallbackFreeMemoryTYPE(fmpy.free)
        try:
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(self.callbacks))
        except (ImportError, OSError):
            log.debug("fmpy logger proxy unavailable; FMU messages are not formatted")

    def logger3(self, name: str) -> Callable[[object, int, bytes, bytes], None]:
        """The FMI 3.0 logMessage callback of instance ``name`` (FMI 3.0 passes no instance name)."""
        encoded = name.encode()
        return lambda env, status, category, message: self._log(env, encoded, status, category, message)

    def _log(self, env, instance_name: bytes, status: int, category: bytes, message: bytes) -> None:
        name = instance_name.decode("utf-8", "replace") if instance_name else "?"
        text = message.decode("utf-8", "replace").strip() if message else ""
        if status >= fmi2Warning:
            self.last[name] = text.splitlines()[-1] if text else text
            log.log(logging.WARNING if status == fmi2Warning else logging.ERROR, "%s: %s", name, text)
        else:
            log.debug("%s: %s", name, text)


def failed_call(function: Callable[..., int] | None, default: str) -> str:
    """The FMI function a batched call that failed made last (:meth:`InstanceBase.exchange`:
    ``fmi2GetInteger`` when its integer part failed), else ``default``."""
    return str(getattr(function, "failed", default))


class InstanceBase:
    """What a master needs of an FMU instance, and the status handling written once.

    The hot functions ``do_step(c, t, h, 1)``, ``get_real(c, vr, n, values)`` and
    ``set_real(c, vr, n, values)`` return an FMI status (ctypes functions of the FMU's library
    for :class:`Instance`, any callables for a fake); the master lays out ``out_vr``/``out_ptr``
    and ``in_vr``/``in_ptr`` (ctypes arrays viewing its value buffer). A subclass provides the
    rare calls: ``set_start_values``, ``setup``, ``exit_initialization``, ``terminate`` and
    ``release``. Every failed call goes through :meth:`fail`.
    """

    do_step: Callable[..., int]
    get_real: Callable[..., int]
    set_real: Callable[..., int]
    get_integer: Callable[..., int] | None = None  # fmi2GetInteger (FMI 1.0, 2.0): integer connections
    set_integer: Callable[..., int] | None = None

    def __init__(self, name: str, messages: MessageLog) -> None:
        self.name = name
        self.messages = messages
        self.c: object = None
        self.initialized = False
        self.broken = False  # returned fmi2Fatal: no further call is allowed
        self.out_vr = (c_uint * 0)()
        self.out_ptr = (c_double * 0)()
        self.in_vr = (c_uint * 0)()
        self.in_ptr = (c_double * 0)()
        self.get_outputs: Callable[..., int] | None = None  # get_real, or exchange(False, n) (master)
        self.set_inputs: Callable[..., int] | None = None

    def fail(self, function: str, status: int, time: float) -> NoReturn:
        """Raise the SimulationError of a failed call (after fmi2Fatal the instance is left alone)."""
        if status >= fmi2Fatal:
            self.broken = True
        raise SimulationError(self.name, function, status, time, self.messages.last.get(self.name, ""))

    # -- hot calls on the prepared arrays -----------------------------------------------------
    def step(self, time: float, h: float) -> None:
        """fmi2DoStep from ``time`` over ``h``."""
        status = self.do_step(self.c, time, h, 1)
        if status >= FAILED:
            self.fail("fmi2DoStep", status, time)

    def read_outputs(self, time: float) -> None:
        """fmi2GetReal of every output into ``out_ptr``."""
        if len(self.out_vr):
            status = (self.get_outputs or self.get_real)(self.c, self.out_vr, len(self.out_vr), self.out_ptr)
            if status >= FAILED:
                self.fail(failed_call(self.get_outputs, "fmi2GetReal"), status, time)

    def write_inputs(self, time: float) -> None:
        """fmi2SetReal of every connected input from ``in_ptr``."""
        if len(self.in_vr):
            status = (self.set_inputs or self.set_real)(self.c, self.in_vr, len(self.in_vr), self.in_ptr)
            if status >= FAILED:
                self.fail(failed_call(self.set_inputs, "fmi2SetReal"), status, time)

    def exchange(self, is_set: bool, ints: int) -> Callable[..., int]:
        """The batched call ``(c, vr, n, values)`` of a batch whose last ``ints`` values are Integer
        or Enumeration variables: ``set_real``/``get_real`` on the others, then
        ``fmi2SetInteger``/``fmi2GetInteger`` on those, through an int buffer (exact: a 32-bit int
        is exact in float64); the plain real call when ``ints`` is 0."""
        real = self.set_real if is_set else self.get_real
        if not ints:
            return real
        integer = self.set_integer if is_set else self.get_integer
        if integer is None:
            raise ScenarioError(f"component '{self.name}': its instance exchanges no Integer values")
        buffer = (c_int * ints)()

        names = ("fmi2SetReal", "fmi2SetInteger") if is_set else ("fmi2GetReal", "fmi2GetInteger")

        def call(c: object, vr: ctypes.Array, n: int, values: ctypes.Array) -> int:
            k = n - ints
            call.failed = names[0]  # type: ignore[attr-defined]  # read by failed_call
            status = real(c, vr, k, values) if k else 0
            if status >= FAILED:
                return status
            call.failed = names[1]  # type: ignore[attr-defined]
            tail = ctypes.cast(ctypes.addressof(vr) + k * ctypes.sizeof(c_uint), POINTER(c_uint))
            if is_set:
                buffer[:] = [int(x) for x in values[k:n]]
                return max(status, integer(c, tail, ints, buffer))
            got = integer(c, tail, ints, buffer)
            values[k:n] = [float(x) for x in buffer]
            return max(status, got)
        return call

    def native(self) -> tuple[int, int] | None:
        """The FMU's library handle (``dlopen``) and instance pointer, for the compiled executor to
        call its FMI 2.0 or 3.0 functions itself; None when it cannot (a fake, FMI 1.0)."""
        return None

    # -- the rare calls, provided by a subclass ------------------------------------------------
    def set_start_values(self, values: Mapping[str, tuple[str, int, object]], time: float) -> None:
        """Set parameters and start values ``name -> (type, value reference, value)``."""
        raise NotImplementedError

    def setup(self, start: float, stop: float, tolerance: float | None = None) -> None:
        """fmi2SetupExperiment (``tolerance``: the relative tolerance of the FMU's own solver, None:
        undefined) then fmi2EnterInitializationMode."""
        raise NotImplementedError

    def exit_initialization(self, time: float) -> None:
        """fmi2ExitInitializationMode."""
        raise NotImplementedError

    def terminate(self, time: float) -> None:
        """fmi2Terminate."""
        raise NotImplementedError

    def release(self) -> None:
        """Terminate (if still running and usable) and free the instance; never raises."""
        raise NotImplementedError

    def tick(self, time: float, clocks: Sequence[int]) -> None:
        """An event at ``time``: the input clocks ``clocks`` (value references) active."""
        raise NotImplementedError

    def clock_timing(self, time: float, vr: int) -> tuple[float, float]:
        """The interval and shift (s) of the fixed input clock ``vr``, asked in Initialization Mode
        (fmi3GetIntervalDecimal, fmi3GetShiftDecimal)."""
        raise NotImplementedError

    def event_requested(self) -> bool:
        """Whether the last step asked for event mode (FMI 3.0 ``eventHandlingNeeded``)."""
        return False


class Instance(InstanceBase):
    """One FMU instance: fmpy's slave and its hot functions bound once from the FMU's library."""

    def __init__(self, name: str, fmu: FMU1Slave | FMU2Slave | FMU3Slave, messages: MessageLog) -> None:
        super().__init__(name, messages)
        self.fmu = fmu
        self.fmi3 = isinstance(fmu, FMU3Slave)
        self.fmi1 = isinstance(fmu, FMU1Slave)
        self.event_mode = False  # FMI 3.0 instantiated with eventModeUsed (set by open)
        self.in_event_mode = False  # from exitInitializationMode (event mode used) to the first tick
        self.c = c_void_p(fmu.component)
        lib = _library(fmu)
        if self.fmi3:
            self._bind_fmi3(lib)
        elif self.fmi1:
            prefix = f"{fmu.modelIdentifier}_fmi"
            step, get, set_, get_i, set_i = (getattr(lib, f"{prefix}{f}") for f in (
                "DoStep", "GetReal", "SetReal", "GetInteger", "SetInteger"))
            step.argtypes, step.restype = [c_void_p, c_double, c_double, ctypes.c_char], c_int
            for f in (get, set_):
                f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)], c_int
            for f in (get_i, set_i):
                f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int)], c_int
            self.get_real, self.set_real, self.get_integer, self.set_integer = get, set_, get_i, set_i
            self.do_step = lambda c, t, h, new: step(c, t, h, b"\x01" if new else b"\x00")
        else:
            self.do_step = lib.fmi2DoStep
            self.do_step.argtypes, self.do_step.restype = [c_void_p, c_double, c_double, c_int], c_int
            self.get_real, self.set_real = lib.fmi2GetReal, lib.fmi2SetReal
            for f in (lib.fmi2GetReal, lib.fmi2SetReal):
                f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)], c_int
            self.get_integer, self.set_integer = lib.fmi2GetInteger, lib.fmi2SetInteger
            for f in (lib.fmi2GetInteger, lib.fmi2SetInteger):
                f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_int)], c_int

    def _bind_fmi3(self, lib: ctypes.PyDLL) -> None:
        """The masters' FMI 2.0-shaped hot calls on fmi3GetFloat64, fmi3SetFloat64 and fmi3DoStep."""
        get, set_, step = lib.fmi3GetFloat64, lib.fmi3SetFloat64, lib.fmi3DoStep
        for f in (get, set_):
            f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double), c_size_t], c_int
        flag = POINTER(c_bool)
        step.argtypes = [c_void_p, c_double, c_double, c_bool, flag, flag, flag, POINTER(c_double)]
        step.restype = c_int
        self._step_flags = (c_bool(), c_bool(), c_bool(), c_double())  # written by every fmi3DoStep
        event, terminate, early, last = (byref(x) for x in self._step_flags)
        self.get_real = lambda c, vr, n, values: get(c, vr, n, values, n)
        self.set_real = lambda c, vr, n, values: set_(c, vr, n, values, n)
        self.do_step = lambda c, t, h, no_set: step(c, t, h, no_set, event, terminate, early, last)

    def native(self) -> tuple[int, int] | None:
        """fmpy's library handle and the instance (FMI 1.0: None, its functions carry a prefix)."""
        c = self.c
        if self.fmi1 or not isinstance(c, c_void_p) or not c.value:
            return None
        return int(self.fmu.dll._handle), int(c.value)

    @classmethod
    def open(cls, name: str, fmu_path: str | os.PathLike, guid: str, model_identifier: str, workdir: str,
             messages: MessageLog, time: float, shared: bool = True, event_mode: bool = False) -> Instance:
        """Unpack ``fmu_path`` (:func:`orchestrator.fmucache.unpack_fmu`: its cache entry, shared by
        every instance of the FMU unless ``shared`` is False, or a folder in ``workdir``) and
        instantiate it (fmi2Instantiate, or fmi3InstantiateCoSimulation for an FMI 3.0 FMU, with
        ``eventModeUsed`` = ``event_mode``: an FMU with clocks)."""
        try:
            unzipdir = unpack_fmu(fmu_path, os.path.join(workdir, name), shared)
        except OSError:
            raise  # the temporary folder: full or unwritable (not the scenario's fault)
        except Exception as exc:  # fmpy raises bare Exceptions; zipfile, zlib their own
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise ScenarioError(f"component '{name}': FMU '{os.path.basename(fmu_path)}' cannot be "
                                f"unpacked: {detail}") from exc
        try:
            instance = cls._instantiate(name, unzipdir, guid, model_identifier, messages, time,
                                        os.path.basename(fmu_path), event_mode)
        except BaseException:
            release(unzipdir)
            raise
        return instance

    @classmethod
    def _instantiate(cls, name: str, unzipdir: str, guid: str, model_identifier: str, messages: MessageLog,
                     time: float, fmu_name: str, event_mode: bool = False) -> Instance:
        """Load the unpacked FMU's library and instantiate it; a library the loader refuses (a missing
        symbol, a newer glibc or libstdc++, another architecture, no shared object) is one
        ScenarioError naming the FMU, the file and the loader's reason."""
        version = fmi_version(unzipdir)
        fmi3 = version.startswith("3.")
        kind = FMU3Slave if fmi3 else FMU1Slave if version.startswith("1.") else FMU2Slave
        cwd = os.getcwd()
        try:
            fmu = _slave(kind, guid, unzipdir, model_identifier, name, library_path(unzipdir, version,
                                                                                    model_identifier))
        except Exception as exc:  # fmpy wraps the loader's OSError (or a missing function's) in Exception
            library = library_path(unzipdir, version, model_identifier)
            raise ScenarioError(f"component '{name}': FMU '{fmu_name}': cannot load "
                                f"{_load_reason(exc, unzipdir, library)}") from None
        finally:
            os.chdir(cwd)  # fmpy changes into the binaries folder and, when the load fails, stays there
        try:
            if isinstance(fmu, FMU3Slave):
                fmu.instantiate(logMessage=messages.logger3(name), eventModeUsed=event_mode)
            elif isinstance(fmu, FMU1Slave):
                fmu.instantiate(functions=messages.callbacks1)
            else:
                fmu.instantiate(callbacks=messages.callbacks)
        except Exception as exc:
            fmu.freeLibrary()
            function = (_FMI3_FUNCTIONS if fmi3 else _FMI1_FUNCTIONS if kind is FMU1Slave else {}).get(
                "fmi2Instantiate", "fmi2Instantiate")
            raise SimulationError(name, function, "NULL", time, messages.last.get(name, "")) from exc
        instance = cls(name, fmu, messages)
        instance.event_mode = event_mode
        return instance

    # -- checked calls ------------------------------------------------------------------------
    def call(self, function: str, time: float, method: Callable[..., object], *args: object) -> None:
        """Call one of fmpy's checked wrappers; a failing status becomes a SimulationError."""
        try:
            method(*args)
        except FMICallException as exc:
            self.fail(function, exc.status, time)

    def fail(self, function: str, status: int, time: float) -> NoReturn:
        """Raise the SimulationError of a failed call (after fmi2Fatal the instance is left alone).
        An FMI 3.0 instance names the FMI 3.0 function and status."""
        if status >= fmi2Fatal:
            self.broken = True
        shown: int | str = status
        if self.fmi3 or self.fmi1:
            function = (_FMI3_FUNCTIONS if self.fmi3 else _FMI1_FUNCTIONS).get(function, function)
            names = _FMI3_STATUS if self.fmi3 else _FMI1_STATUS
            shown = names[status] if 0 <= status < len(names) else f"status {status}"
        raise SimulationError(self.name, function, shown, time, self.messages.last.get(self.name, ""))

    def set_start_values(self, values: Mapping[str, tuple[str, int, object]], time: float) -> None:
        """Set parameters and start values ``name -> (type, value reference, value)``, one call per type
        (FMI 1.0: once, before fmiInitializeSlave)."""
        if self.fmi1 and self.initialized:
            return
        by_type: dict[str, tuple[list[int], list[object]]] = {}
        for type_, vr, value in values.values():
            vrs, vals = by_type.setdefault(type_, ([], []))
            vrs.append(vr)
            vals.append(value)
        prefix, setters = ("fmi3", _SETTERS3) if self.fmi3 else ("fmi" if self.fmi1 else "fmi2", _SETTERS)
        for type_, (vrs, vals) in by_type.items():
            setter = setters[type_]  # the system refuses other types before a run
            self.call(f"{prefix}S{setter[1:]}", time, getattr(self.fmu, setter), vrs, vals)

    def setup(self, start: float, stop: float, tolerance: float | None = None) -> None:
        """fmi2SetupExperiment then fmi2EnterInitializationMode (FMI 3.0: fmi3EnterInitializationMode;
        FMI 1.0, which has no tolerance: fmiInitializeSlave)."""
        if isinstance(self.fmu, FMU3Slave):
            enter = self.fmu.enterInitializationMode
            self.call("fmi3EnterInitializationMode", start, enter, tolerance, start, stop)
        elif isinstance(self.fmu, FMU1Slave):
            self.call("fmiInitializeSlave", start, self.fmu.initialize, start, stop)
        else:
            self.call("fmi2SetupExperiment", start, self.fmu.setupExperiment, tolerance, start, stop)
            self.call("fmi2EnterInitializationMode", start, self.fmu.enterInitializationMode)
        self.initialized = True

    def exit_initialization(self, time: float) -> None:
        if self.fmi1:
            return  # FMI 1.0: fmiInitializeSlave (setup) left it ready to step
        prefix = "fmi3" if self.fmi3 else "fmi2"
        self.call(f"{prefix}ExitInitializationMode", time, self.fmu.exitInitializationMode)
        self.in_event_mode = self.event_mode

    def clock_timing(self, time: float, vr: int) -> tuple[float, float]:
        assert isinstance(self.fmu, FMU3Slave)  # System refuses clocks on other FMUs
        vrs = (fmi3ValueReference * 1)(vr)
        interval, qualifier, shift = (c_double * 1)(), (c_int * 1)(), (c_double * 1)()
        self.call("fmi3GetIntervalDecimal", time, self.fmu.getIntervalDecimal, vrs, interval, qualifier)
        self.call("fmi3GetShiftDecimal", time, self.fmu.getShiftDecimal, vrs, shift)
        return interval[0], shift[0]

    def tick(self, time: float, clocks: Sequence[int]) -> None:
        """FMI 3.0 Co-Simulation with event mode at ``time``: fmi3EnterEventMode (unless still in it
        after initialization), fmi3SetClock of ``clocks`` active, fmi3UpdateDiscreteStates until
        no more updates are needed (at most ``UPDATES`` times: an FMU that never settles is a
        SimulationError), fmi3EnterStepMode. Inputs set before it hold; outputs read after it are
        the clocked partition's."""
        assert isinstance(self.fmu, FMU3Slave)  # System refuses clocks on other FMUs
        if not self.in_event_mode:
            self.call("fmi3EnterEventMode", time, self.fmu.enterEventMode)
        self.in_event_mode = True
        if clocks:
            self.call("fmi3SetClock", time, self.fmu.setClock, list(clocks), [True] * len(clocks))
        for _ in range(UPDATES):
            try:
                again, terminate, *_ = self.fmu.updateDiscreteStates()
            except FMICallException as exc:
                self.fail("fmi3UpdateDiscreteStates", exc.status, time)
            if terminate:
                raise SimulationError(self.name, "fmi3UpdateDiscreteStates", "terminateSimulation", time,
                                      self.messages.last.get(self.name, ""))
            if not again:
                break
        else:
            raise SimulationError(self.name, "fmi3UpdateDiscreteStates", f"discreteStatesNeedUpdate after "
                                  f"{UPDATES} calls", time, self.messages.last.get(self.name, ""))
        self.call("fmi3EnterStepMode", time, self.fmu.enterStepMode)
        self.in_event_mode = False

    def event_requested(self) -> bool:
        return self.fmi3 and bool(self._step_flags[0].value)

    def terminate(self, time: float) -> None:
        self.initialized = False
        function = "fmi3Terminate" if self.fmi3 else "fmiTerminateSlave" if self.fmi1 else "fmi2Terminate"
        self.call(function, time, self.fmu.terminate)

    def release(self) -> None:
        """Terminate (if still running and usable) and free the instance; never raises.

        An instance that returned fmi2Fatal is left alone: FMI 2.0 allows no further call on it, and
        pythonfmu 0.7.0's fmi2FreeInstance after a Python exception corrupts the interpreter (the
        process crashed with SIGSEGV at its next garbage collection)."""
        if self.broken:
            return
        try:
            if self.initialized:
                self.fmu.terminate()
        except Exception:  # noqa: BLE001 - cleanup must go on for the other FMUs
            log.warning("%s: fmi2Terminate failed during cleanup", self.name)
        try:
            self.fmu.freeInstance()  # FMI 1.0: fmiFreeSlaveInstance, and the library is unloaded
        except Exception:  # noqa: BLE001
            log.warning("%s: fmi2FreeInstance failed during cleanup", self.name)
        release(self.fmu.unzipDirectory)


# (fmpy's slave class, library) -> a slave of it made by fmpy and never instantiated, while a slave
# copied from it lives (each keeps it): see _slave
_TEMPLATES: WeakValueDictionary[tuple[type, str], FMU1Slave | FMU2Slave | FMU3Slave] = WeakValueDictionary()


def _slave(kind: type[FMU1Slave | FMU2Slave | FMU3Slave], guid: str, unzipdir: str, model_identifier: str,
           name: str, library: str) -> FMU1Slave | FMU2Slave | FMU3Slave:
    """fmpy's slave ``name`` of the unpacked FMU, not instantiated yet. fmpy binds all of the
    library's FMI functions for every slave it makes (50 ctypes functions, each described with
    ``inspect``): the slaves of one library are copies of the first instead, sharing its bindings
    (16 copies of example1: 64 slaves, 3.5 MB; issue 46). The library stays loaded while a copy
    lives: the first slave holds a reference of its own, and each copy one that its
    ``freeInstance`` gives back, as fmpy's own slaves do."""
    key = (kind, os.path.abspath(library))
    template = _TEMPLATES.get(key)
    if template is None or template.guid != guid:
        fmu = kind(guid=guid, unzipDirectory=unzipdir, modelIdentifier=model_identifier, instanceName=name)
        template = copy.copy(fmu)
        ctypes.CDLL(fmu.dll._name)  # the template's reference to the library, given back when it goes
        finalize(template, fmpy.freeLibrary, fmu.dll._handle)
        _TEMPLATES[key] = template
    else:
        fmu = copy.copy(template)
        fmu.instanceName = name
        ctypes.CDLL(fmu.dll._name)  # this slave's reference, given back by its freeInstance
    fmu._ftc_template = template  # lives while a slave of it does
    return fmu


def _library(fmu: FMU1Slave | FMU2Slave | FMU3Slave) -> ctypes.PyDLL:
    """The FMU's library, for its hot functions: one ctypes library per template (:func:`_slave`),
    so that the instances of one FMU share its functions and their argtypes (ctypes makes a class
    per library object and an object per function: 23 KB per copy of example1). The template
    keeps the library loaded for as long as the functions can be called: a library unloaded and
    loaded again may come back at another address under the same handle."""
    template = getattr(fmu, "_ftc_template", None)
    lib = getattr(template, "_ftc_library", None)
    if lib is None or lib._handle != fmu.dll._handle:
        lib = ctypes.PyDLL(fmu.dll._name, handle=fmu.dll._handle)
        if template is not None:
            template._ftc_library = lib
    return lib


CALLS = logging.getLogger("orchestrator.fmi.calls")
LOAD_TIMEOUT = 10.0  # seconds a trial load (validate) may take before it is called hung


def library_path(unzipdir: str | os.PathLike, version: str, model_identifier: str) -> str:
    """The shared library of an unpacked FMU that a run loads on this platform (as fmpy finds it)."""
    folder = fmpy.platform_tuple if version.startswith("3.") else fmpy.platform
    return os.path.join(unzipdir, "binaries", folder, model_identifier + fmpy.sharedLibraryExtension)


def _load_reason(exc: BaseException | str, unzipdir: str | os.PathLike, library: str) -> str:
    """``<library>: <the loader's own words>`` on one line, the paths inside the FMU relative to it."""
    if isinstance(exc, BaseException):
        cause = exc.__context__ if isinstance(exc.__context__, OSError | AttributeError) else exc
        exc = str(cause)
    text = " ".join(exc.split())
    for prefix in (os.path.abspath(unzipdir), str(unzipdir)):
        text = text.replace(os.path.join(prefix, ""), "")
    name = os.path.relpath(library, unzipdir)
    return text if text.startswith(f"{name}:") else f"{name}: {text}"


def _functions(version: str, model_identifier: str) -> tuple[str, ...]:
    """The functions every step of a run calls, as the library must export them."""
    if version.startswith("1."):
        return tuple(f"{model_identifier}_{_FMI1_FUNCTIONS[f]}" for f in
                     ("fmi2Instantiate", "fmi2DoStep", "fmi2GetReal", "fmi2SetReal"))
    names = ("fmi2Instantiate", "fmi2DoStep", "fmi2GetReal", "fmi2SetReal")
    return tuple(_FMI3_FUNCTIONS[f] for f in names) if version.startswith("3.") else names


def load_problem(unzipdir: str | os.PathLike, version: str, model_identifier: str) -> str:
    """Why a run could not load the unpacked FMU's library ('' when it can): its path in the FMU,
    then the loader's reason (an undefined symbol, ``GLIBCXX_3.4.32' not found``, wrong ELF class,
    invalid ELF header) or the FMI functions it does not export. The trial load happens in a
    forked child, so neither the library's constructors nor a crash or hang in them touch this
    process (a child that dies or takes longer than LOAD_TIMEOUT is the reason); where fork is
    missing (Windows), it happens in this process, as a run's would."""
    library = library_path(unzipdir, version, model_identifier)
    if not os.path.isfile(library):
        return _load_reason("no such file", unzipdir, library)
    functions = _functions(version, model_identifier)
    if not hasattr(os, "fork"):
        return _try_load(library, functions, unzipdir)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: load, write the reason, leave without any Python clean-up
        try:
            os.close(read)
            os.write(write, _try_load(library, functions, unzipdir).encode()[:4000])
        finally:
            os._exit(0)
    os.close(write)
    try:
        return _wait_for(pid, read)
    finally:
        os.close(read)


def _wait_for(pid: int, read: int) -> str:
    """What the child of :func:`load_problem` reported; it is killed after LOAD_TIMEOUT."""
    deadline = monotonic() + LOAD_TIMEOUT
    chunks: list[bytes] = []
    while True:
        ready, _, _ = select.select([read], [], [], max(0.0, deadline - monotonic()))
        if not ready:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return f"loading it did not return within {LOAD_TIMEOUT:g} s"
        chunk = os.read(read, 4096)
        if not chunk:
            break
        chunks.append(chunk)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        return f"loading it crashed the process ({signal.Signals(os.WTERMSIG(status)).name})"
    return b"".join(chunks).decode(errors="replace")


def _try_load(library: str, functions: tuple[str, ...], unzipdir: str | os.PathLike) -> str:
    try:
        dll = ctypes.CDLL(library)
    except OSError as exc:
        return _load_reason(str(exc), unzipdir, library)
    missing = [f for f in functions if not hasattr(dll, f)]
    return _load_reason(f"exports no {', '.join(missing)}", unzipdir, library) if missing else ""


def _status(status: int) -> str:
    names = SimulationError.STATUS_NAMES
    return names[status] if 0 <= status < len(names) else str(status)


def trace(instance: InstanceBase) -> InstanceBase:
    """Log every FMI call ``instance`` makes from now on to the logger ``orchestrator.fmi.calls``
    (level INFO), one line each: ``plant: fmi2DoStep(t=0.001, h=0.001) -> fmi2OK``, with the value
    references and values of fmi2GetReal/fmi2SetReal. Returns the instance."""
    name = instance.name
    do_step, get_real, set_real = instance.do_step, instance.get_real, instance.set_real

    def traced_step(c: object, t: float, h: float, new_step: int) -> int:
        status = do_step(c, t, h, new_step)
        CALLS.info("%s: fmi2DoStep(t=%r, h=%r) -> %s", name, t, h, _status(status))
        return status

    def traced_get(c: object, vr: ctypes.Array, n: int, values: ctypes.Array) -> int:
        status = get_real(c, vr, n, values)
        CALLS.info("%s: fmi2GetReal(vr=%s) -> %s %s", name, list(vr[:n]), list(values[:n]), _status(status))
        return status

    def traced_set(c: object, vr: ctypes.Array, n: int, values: ctypes.Array) -> int:
        status = set_real(c, vr, n, values)
        CALLS.info("%s: fmi2SetReal(vr=%s, values=%s) -> %s", name, list(vr[:n]), list(values[:n]),
                   _status(status))
        return status

    instance.do_step, instance.get_real, instance.set_real = traced_step, traced_get, traced_set
    for method, function in (("set_start_values", "fmi2Set* (start values)"),
                             ("setup", "fmi2SetupExperiment + fmi2EnterInitializationMode"),
                             ("exit_initialization", "fmi2ExitInitializationMode"),
                             ("terminate", "fmi2Terminate")):
        setattr(instance, method, _logged(name, function, getattr(instance, method)))
    return instance


def _logged(name: str, function: str, method: Callable[..., None]) -> Callable[..., None]:
    def call(*args: object) -> None:
        try:
            method(*args)
        except SimulationError as exc:
            CALLS.info("%s: %s%s -> %s", name, function, _args(args), exc.status)
            raise
        CALLS.info("%s: %s%s -> fmi2OK", name, function, _args(args))
    return call


def _args(args: tuple[object, ...]) -> str:
    shown = [repr({k: v[2] for k, v in a.items()}) if isinstance(a, Mapping) else repr(a) for a in args]
    return f"({', '.join(shown)})"


def fmi_version(unzipdir: str | os.PathLike) -> str:
    """The ``fmiVersion`` of an extracted FMU, read from the root of its modelDescription.xml alone
    (no entities resolved, no network)."""
    with open(Path(unzipdir, "modelDescription.xml"), "rb") as xml:  # closed after the first element
        for _, element in etree.iterparse(xml, events=("start",), resolve_entities=False, no_network=True):
            return str(element.get("fmiVersion", ""))
    return ""
