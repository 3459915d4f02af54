"""FMI 2.0 co-simulation instances as the masters use them: extracted, instantiated, their hot
functions bound once, every failure turned into a :class:`~orchestrator.errors.SimulationError`.

fmpy loads the FMU and offers checked wrappers for the rare calls (setup, initialization mode,
start values, terminate). The calls made every communication step (``fmi2DoStep``,
``fmi2GetReal``, ``fmi2SetReal``) are rebound from the same library as ``ctypes.PyDLL`` functions
on prepared arrays: no per-call conversion, and the GIL is kept, which a Python-based FMU
(pythonfmu) would otherwise have to take back at once. Status codes keep fmpy's names
(``fmi2OK`` ... ``fmi2Pending``).
"""

from __future__ import annotations

import ctypes
import logging
import os
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_uint, c_void_p

import fmpy
from fmpy.fmi1 import FMICallException
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

from .errors import ScenarioError, SimulationError

__all__ = ["FAILED", "Instance", "MessageLog", "interpreter_guard"]

log = logging.getLogger(__name__)

# A status at or above this is a failed call (fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending).
FAILED = fmi2Discard
_SETTERS = {"Real": "setReal", "Integer": "setInteger", "Enumeration": "setInteger", "Boolean": "setBoolean",
            "String": "setString"}


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
        try:
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(self.callbacks))
        except (ImportError, OSError):
            log.debug("fmpy logger proxy unavailable; FMU messages are not formatted")

    def _log(self, env, instance_name: bytes, status: int, category: bytes, message: bytes) -> None:
        name = instance_name.decode("utf-8", "replace") if instance_name else "?"
        text = message.decode("utf-8", "replace").strip() if message else ""
        if status >= fmi2Warning:
            self.last[name] = text.splitlines()[-1] if text else text
            log.log(logging.WARNING if status == fmi2Warning else logging.ERROR, "%s: %s", name, text)
        else:
            log.debug("%s: %s", name, text)


class Instance:
    """One FMU instance: fmpy's slave, its hot functions bound once, and the arrays of its batched
    output read (``out_vr`` -> ``out_ptr``) and input write (``in_vr`` <- ``in_ptr``) that a master
    lays out (ctypes arrays viewing the master's value buffer)."""

    def __init__(self, name: str, fmu: FMU2Slave, messages: MessageLog) -> None:
        self.name = name
        self.fmu = fmu
        self.messages = messages
        self.c = c_void_p(fmu.component)
        lib = ctypes.PyDLL(fmu.dll._name, handle=fmu.dll._handle)
        self.do_step = lib.fmi2DoStep
        self.do_step.argtypes, self.do_step.restype = [c_void_p, c_double, c_double, c_int], c_int
        self.get_real, self.set_real = lib.fmi2GetReal, lib.fmi2SetReal
        for f in (self.get_real, self.set_real):
            f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)], c_int
        self.initialized = False
        self.broken = False  # returned fmi2Fatal: no further call is allowed
        self.out_vr = (c_uint * 0)()
        self.out_ptr = (c_double * 0)()
        self.in_vr = (c_uint * 0)()
        self.in_ptr = (c_double * 0)()

    @classmethod
    def open(cls, name: str, fmu_path: str | os.PathLike, guid: str, model_identifier: str, workdir: str,
             messages: MessageLog, time: float) -> Instance:
        """Extract ``fmu_path`` into ``workdir/name`` and instantiate it (fmi2Instantiate)."""
        try:
            unzipdir = fmpy.extract(str(fmu_path), unzipdir=os.path.join(workdir, name))
        except OSError:
            raise  # the temporary folder: full or unwritable (not the scenario's fault)
        except Exception as exc:  # fmpy raises bare Exceptions; zipfile, zlib their own
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise ScenarioError(f"component '{name}': FMU '{os.path.basename(fmu_path)}' cannot be "
                                f"unpacked: {detail}") from exc
        fmu = FMU2Slave(guid=guid, unzipDirectory=unzipdir, modelIdentifier=model_identifier,
                        instanceName=name)
        try:
            fmu.instantiate(callbacks=messages.callbacks)
        except Exception as exc:
            fmu.freeLibrary()
            raise SimulationError(name, "fmi2Instantiate", "NULL", time, messages.last.get(name, "")) from exc
        return cls(name, fmu, messages)

    # -- checked calls ------------------------------------------------------------------------
    def call(self, function: str, time: float, method: Callable[..., object], *args: object) -> None:
        """Call one of fmpy's checked wrappers; a failing status becomes a SimulationError."""
        try:
            method(*args)
        except FMICallException as exc:
            self.fail(function, exc.status, time)

    def fail(self, function: str, status: int, time: float) -> None:
        """Raise the SimulationError of a failed call (after fmi2Fatal the instance is left alone)."""
        if status >= fmi2Fatal:
            self.broken = True
        raise SimulationError(self.name, function, status, time, self.messages.last.get(self.name, ""))

    def set_start_values(self, values: Mapping[str, tuple[str, int, object]], time: float) -> None:
        """Set parameters and start values ``name -> (type, value reference, value)``, one call per type."""
        by_type: dict[str, tuple[list[int], list[object]]] = {}
        for type_, vr, value in values.values():
            vrs, vals = by_type.setdefault(type_, ([], []))
            vrs.append(vr)
            vals.append(value)
        for type_, (vrs, vals) in by_type.items():
            setter = _SETTERS[type_]
            self.call(f"fmi2S{setter[1:]}", time, getattr(self.fmu, setter), vrs, vals)

    def setup(self, start: float, stop: float) -> None:
        """fmi2SetupExperiment then fmi2EnterInitializationMode."""
        self.call("fmi2SetupExperiment", start, self.fmu.setupExperiment, None, start, stop)
        self.call("fmi2EnterInitializationMode", start, self.fmu.enterInitializationMode)
        self.initialized = True

    def exit_initialization(self, time: float) -> None:
        self.call("fmi2ExitInitializationMode", time, self.fmu.exitInitializationMode)

    def terminate(self, time: float) -> None:
        self.initialized = False
        self.call("fmi2Terminate", time, self.fmu.terminate)

    # -- hot calls on the prepared arrays -----------------------------------------------------
    def read_outputs(self, time: float) -> None:
        if len(self.out_vr):
            status = self.get_real(self.c, self.out_vr, len(self.out_vr), self.out_ptr)
            if status >= FAILED:
                self.fail("fmi2GetReal", status, time)

    def write_inputs(self, time: float) -> None:
        if len(self.in_vr):
            status = self.set_real(self.c, self.in_vr, len(self.in_vr), self.in_ptr)
            if status >= FAILED:
                self.fail("fmi2SetReal", status, time)

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
            self.fmu.freeInstance()
        except Exception:  # noqa: BLE001
            log.warning("%s: fmi2FreeInstance failed during cleanup", self.name)
