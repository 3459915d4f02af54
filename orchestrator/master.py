"""Master algorithms: fixed communication step on the exact grid ``t_k = t0 + k*h``.

Time is an integer count of nanoseconds (as in libcosim) and converted to seconds once per
communication point, so the grid never drifts and ``t_k`` is the double nearest to ``t0 + k*h``.

Both masters share the lifecycle on ``Master``: ``setup`` (extract and instantiate every FMU,
prepare the value-reference and value arrays once) -> ``initialize`` (setupExperiment,
enterInitializationMode, start values, propagation of initial outputs, exitInitializationMode;
row t0) -> ``step`` (one communication step; one row) -> ``terminate``. Every FMU is terminated and
freed on every path through an ExitStack.

Values live in one float64 array ``values``: ``[time, inputs..., outputs...]``; each FMU's outputs
and inputs are contiguous slices of it, so one batched ``fmi2GetReal``/``fmi2SetReal`` per FMU
reads or writes it in place (ctypes arrays aliasing the NumPy buffer), and a connection is an index
gather ``values[inputs] = factor * values[sources] + offset``.

* ``gauss-seidel`` (default): all FMUs step from t_k to t_k+1 with inputs held; then, at t_k+1,
  outputs are read and inputs set in the dependency order of the ModelStructure (``System.schedule``),
  so a direct-feedthrough output (the controller's v, the actuator's uf) at t_k+1 already uses the
  plant state at t_k+1: no artificial delay in a sampled controller.
* ``jacobi``: libcosim's fixed-step algorithm (0.11): every FMU sets the inputs transferred at the
  end of the previous step, steps, and its outputs are read; then all connections are transferred.
  Each connection therefore adds one step of delay. Initialization repeats N sweeps of
  (set, get, transfer) in initialization mode (N = number of FMUs), then set, exit, get, transfer.
"""

from __future__ import annotations

import ctypes
import logging
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_uint, c_void_p

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from .errors import SimulationError
from .results import Recorder
from .system import PortRef, System

__all__ = ["MASTERS", "GaussSeidel", "Jacobi", "Master", "interpreter_guard", "time_grid"]

log = logging.getLogger(__name__)
NS_PER_S = 1_000_000_000


def time_grid(start: float, stop: float, step: float) -> np.ndarray:
    """Communication points t_k = t0 + k*h, k = 0..n, up to the last one not after ``stop``,
    computed in integer nanoseconds and rounded once (libcosim's time representation)."""
    t0, t1, h = (round(x * NS_PER_S) for x in (start, stop, step))
    if h <= 0:
        raise ValueError(f"the communication step must be positive and at least 1 ns (got {step!r} s)")
    if t1 < t0:
        raise ValueError(f"the stop time {stop!r} s is before the start time {start!r} s")
    n = (t1 - t0) // h
    return (t0 + h * np.arange(n + 1, dtype=np.int64)) / NS_PER_S


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


class _Instance:
    """One FMU instance with its raw FMI functions and the arrays prepared for batched calls."""

    def __init__(self, name: str, fmu: FMU2Slave) -> None:
        self.name = name
        self.fmu = fmu
        self.c = c_void_p(fmu.component)
        # The FMI functions of the library fmpy loaded, bound as PyDLL functions: called without
        # releasing the GIL, which a Python-based FMU would have to take back at once.
        lib = ctypes.PyDLL(fmu.dll._name, handle=fmu.dll._handle)
        self.do_step = lib.fmi2DoStep
        self.do_step.argtypes, self.do_step.restype = [c_void_p, c_double, c_double, c_int], c_int
        self.get_real, self.set_real = lib.fmi2GetReal, lib.fmi2SetReal
        for f in (self.get_real, self.set_real):
            f.argtypes, f.restype = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)], c_int
        self.initialized = False
        self.broken = False
        self.out_slice = slice(0, 0)
        self.out_vr = (c_uint * 0)()
        self.out_ptr = (c_double * 0)()
        self.in_slice = slice(0, 0)
        self.in_vr = (c_uint * 0)()
        self.in_ptr = (c_double * 0)()


class Master:
    """Base class: the lifecycle and everything both algorithms share.

    ``progress`` (if given) is called with the number of steps done, about every 1 % of the run.
    """

    name = ""

    def __init__(self, system: System, start_time: float, stop_time: float, step: float,
                 output: str | os.PathLike | None = None,
                 progress: Callable[[int, int], None] | None = None) -> None:
        self.system = system
        self.times = time_grid(start_time, stop_time, step).tolist()
        self.start_time = self.times[0]
        self.stop_time = stop_time
        self.output = output
        self.progress = progress
        self.instances: list[_Instance] = []
        self.recorder: Recorder | None = None
        self._messages: dict[str, str] = {}

    # -- public lifecycle -------------------------------------------------------------------
    def run(self) -> np.ndarray:
        """setup -> initialize -> step* -> terminate; returns the structured result array.

        On failure the rows computed so far are kept (in the CSV and in ``self.recorder``) and the
        SimulationError is raised after every FMU has been freed.
        """
        with ExitStack() as stack:
            self.setup(stack)
            stack.callback(self.recorder.close)
            try:
                self.initialize()
                n = len(self.times) - 1
                stride = max(1, n // 100)
                for k in range(n):
                    self.step(k)
                    if self.progress is not None and (k + 1) % stride == 0:
                        self.progress(k + 1, n)
                self.terminate()
            except SimulationError as exc:
                exc.result = self.recorder.result()
                raise
        return self.recorder.result()

    def setup(self, stack: ExitStack) -> None:
        """Extract and instantiate every FMU (freed by ``stack``) and lay out the value arrays."""
        workdir = tempfile.mkdtemp(prefix="orchestrate-")
        stack.callback(shutil.rmtree, workdir, ignore_errors=True)
        stack.enter_context(interpreter_guard())
        self._callbacks = self._make_callbacks()
        for comp in self.system.components.values():
            unzipdir = fmpy.extract(str(comp.fmu), unzipdir=os.path.join(workdir, comp.name))
            fmu = FMU2Slave(guid=comp.model.guid, unzipDirectory=unzipdir,
                            modelIdentifier=comp.model.coSimulation.modelIdentifier, instanceName=comp.name)
            try:
                fmu.instantiate(callbacks=self._callbacks)
            except Exception as exc:
                fmu.freeLibrary()
                raise SimulationError(comp.name, "fmi2Instantiate", "NULL", self.start_time,
                                      self._messages.get(comp.name, "")) from exc
            instance = _Instance(comp.name, fmu)
            stack.callback(self._release, instance)
            self.instances.append(instance)
        self._layout()
        self.recorder = Recorder(self.columns, len(self.times), self.output)

    def initialize(self) -> None:
        """FMI initialization; afterwards every FMU is in step mode and row t0 is recorded."""
        t0 = self.start_time
        stop = self.times[-1] if self.stop_time is None else float(self.stop_time)
        for inst in self.instances:
            self._apply_start_values(inst)
            self._call(inst, "fmi2SetupExperiment", t0, inst.fmu.setupExperiment, None, t0, stop)
            self._call(inst, "fmi2EnterInitializationMode", t0, inst.fmu.enterInitializationMode)
            self._apply_start_values(inst)
            inst.initialized = True
        self._initialize_impl(t0)
        self.recorder.append(self.values)

    def step(self, k: int) -> None:
        """Advance every FMU from t_k to t_k+1 and record row t_k+1."""
        t, t_next = self.times[k], self.times[k + 1]
        self._step_impl(t, t_next - t, t_next)
        self.recorder.append(self.values)

    def terminate(self) -> None:
        """fmi2Terminate on every FMU (they are freed by the ExitStack)."""
        t = float(self.values[0])
        for inst in self.instances:
            inst.initialized = False
            self._call(inst, "fmi2Terminate", t, inst.fmu.terminate)

    # -- to implement -------------------------------------------------------------------------
    def _initialize_impl(self, t0: float) -> None:
        raise NotImplementedError

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        raise NotImplementedError

    # -- shared machinery ---------------------------------------------------------------------
    def _layout(self) -> None:
        """Place time, inputs and outputs in ``values`` and prepare the batched call arrays."""
        system = self.system
        columns = ["time"]
        by_name = {inst.name: inst for inst in self.instances}
        # connected inputs in schedule order (each set operation a contiguous slice), then the rest
        input_order: list[PortRef] = []
        for comp in system.components.values():
            for op in system.schedule:
                if op.kind == "set" and op.component == comp.name:
                    input_order += [PortRef(op.component, i) for i in op.inputs]
        n_connected = len(input_order)
        for comp in system.components.values():
            input_order += [p for p in (PortRef(comp.name, i) for i in comp.inputs) if p not in system.links]
        columns += [str(p) for p in input_order]
        slot = {p: 1 + j for j, p in enumerate(input_order)}
        for comp in system.components.values():
            inst = by_name[comp.name]
            first = len(columns)
            columns += [str(PortRef(comp.name, o)) for o in comp.outputs]
            inst.out_slice = slice(first, len(columns))
            for o in comp.outputs:
                slot[PortRef(comp.name, o)] = len(slot) + 1
        self.columns = columns
        self.values = np.zeros(len(columns))
        for comp in system.components.values():
            variables = comp.variables
            for i in comp.inputs:
                start = comp.start_values.get(i, variables[i].start)
                self.values[slot[PortRef(comp.name, i)]] = float(start) if start is not None else 0.0
        self.values[0] = self.start_time
        self._cvalues = self._view(slice(0, len(columns)))
        # transfer of all connections at once (jacobi) and per set operation (gauss-seidel)
        self._all_copy, self._all_scaled = self._transfers(input_order[:n_connected], slot)
        for inst in self.instances:
            comp = system.components[inst.name]
            inst.out_vr = self._vrs(comp, comp.outputs)
            inst.out_ptr = self._view(inst.out_slice)
            mine = [j for j, p in enumerate(input_order[:n_connected]) if p.component == inst.name]
            if mine:
                inst.in_slice = slice(1 + mine[0], 2 + mine[-1])
                inst.in_vr = self._vrs(comp, [input_order[j].connector for j in mine])
                inst.in_ptr = self._view(inst.in_slice)
        self._ops = []
        for op in system.schedule:
            inst = by_name[op.component]
            if op.kind == "get":
                self._ops.append((False, inst, inst.get_real, inst.out_vr, len(inst.out_vr), inst.out_ptr,
                                  (), ()))
            else:
                ports = [PortRef(op.component, i) for i in op.inputs]
                dst = slice(slot[ports[0]], slot[ports[-1]] + 1)
                vrs = self._vrs(system.components[op.component], op.inputs)
                copy, scaled = self._transfers(ports, slot)
                self._ops.append((True, inst, inst.set_real, vrs, len(ports), self._view(dst), copy, scaled))

    def _transfers(self, ports: list[PortRef], slot: dict[PortRef, int]) -> tuple[tuple, tuple]:
        """Connections into ``ports`` as (input slot, output slot) pairs, and as (input slot,
        output slot, factor, offset) for those with a linear transformation."""
        links = [self.system.links[p] for p in ports]
        copy = tuple((slot[lk.end], slot[lk.start]) for lk in links if lk.factor == 1.0 and lk.offset == 0.0)
        scaled = tuple((slot[lk.end], slot[lk.start], lk.factor, lk.offset) for lk in links
                       if not (lk.factor == 1.0 and lk.offset == 0.0))
        return copy, scaled

    @staticmethod
    def _vrs(comp, names) -> ctypes.Array:
        variables = comp.variables
        return (c_uint * len(names))(*[variables[n].valueReference for n in names])

    def _view(self, part: slice) -> ctypes.Array:
        n = part.stop - part.start
        return (c_double * n).from_buffer(self.values, part.start * self.values.itemsize)

    def _transfer_all(self) -> None:
        v = self._cvalues
        for dst, src in self._all_copy:
            v[dst] = v[src]
        for dst, src, factor, offset in self._all_scaled:
            v[dst] = factor * v[src] + offset

    def _propagate(self, t: float) -> None:
        """Read outputs and set inputs in dependency order (gauss-seidel at a communication point)."""
        v = self._cvalues
        for is_set, inst, fn, vr, n, ptr, copy, scaled in self._ops:
            if is_set:
                for dst, src in copy:
                    v[dst] = v[src]
                for dst, src, factor, offset in scaled:
                    v[dst] = factor * v[src] + offset
                status = fn(inst.c, vr, n, ptr)
                if status > 1:
                    self._fail(inst, "fmi2SetReal", status, t)
            elif n:
                status = fn(inst.c, vr, n, ptr)
                if status > 1:
                    self._fail(inst, "fmi2GetReal", status, t)

    def _set_inputs(self, inst: _Instance, t: float) -> None:
        if len(inst.in_vr):
            status = inst.set_real(inst.c, inst.in_vr, len(inst.in_vr), inst.in_ptr)
            if status > 1:
                self._fail(inst, "fmi2SetReal", status, t)

    def _get_outputs(self, inst: _Instance, t: float) -> None:
        if len(inst.out_vr):
            status = inst.get_real(inst.c, inst.out_vr, len(inst.out_vr), inst.out_ptr)
            if status > 1:
                self._fail(inst, "fmi2GetReal", status, t)

    def _exit_initialization(self, inst: _Instance, t: float) -> None:
        self._call(inst, "fmi2ExitInitializationMode", t, inst.fmu.exitInitializationMode)

    def _apply_start_values(self, inst: _Instance) -> None:
        """Parameters and start values from the SSD, .ssv files and overrides, one call per type."""
        comp = self.system.components[inst.name]
        variables = comp.variables
        by_type: dict[str, tuple[list[int], list]] = {}
        for name, value in comp.start_values.items():
            v = variables[name]
            vrs, vals = by_type.setdefault(v.type, ([], []))
            vrs.append(v.valueReference)
            vals.append(value)
        setters = {"Real": inst.fmu.setReal, "Integer": inst.fmu.setInteger,
                   "Enumeration": inst.fmu.setInteger, "Boolean": inst.fmu.setBoolean,
                   "String": inst.fmu.setString}
        for type_, (vrs, vals) in by_type.items():
            self._call(inst, f"fmi2Set{'Integer' if type_ == 'Enumeration' else type_}", self.start_time,
                       setters[type_], vrs, vals)

    def _call(self, inst: _Instance, function: str, t: float, method, *args) -> None:
        """Call one of fmpy's checked wrappers; a failing status becomes a SimulationError."""
        try:
            method(*args)
        except FMICallException as exc:
            self._fail(inst, function, exc.status, t)

    def _fail(self, inst: _Instance, function: str, status: int, t: float) -> None:
        if status >= 3:
            inst.broken = True
        raise SimulationError(inst.name, function, status, t, self._messages.get(inst.name, ""))

    def _release(self, inst: _Instance) -> None:
        """Terminate (if still running and usable) and free one FMU; never raises.

        An instance that returned fmi2Fatal is left alone: FMI 2.0 allows no further call on it, and
        pythonfmu 0.7.0's fmi2FreeInstance after a Python exception corrupts the interpreter (the
        process crashed with SIGSEGV at its next garbage collection)."""
        if inst.broken:
            return
        try:
            if inst.initialized:
                inst.fmu.terminate()
        except Exception:  # noqa: BLE001 - cleanup must go on for the other FMUs
            log.warning("%s: fmi2Terminate failed during cleanup", inst.name)
        try:
            inst.fmu.freeInstance()
        except Exception:  # noqa: BLE001
            log.warning("%s: fmi2FreeInstance failed during cleanup", inst.name)

    def _make_callbacks(self) -> fmi2CallbackFunctions:
        """FMI callbacks whose logger keeps each instance's last message for error reports."""
        messages = self._messages

        def logger(env, instance_name, status, category, message):
            name = instance_name.decode("utf-8", "replace") if instance_name else "?"
            text = message.decode("utf-8", "replace").strip() if message else ""
            if status >= 1:
                messages[name] = text.splitlines()[-1] if text else text
                log.log(logging.WARNING if status == 1 else logging.ERROR, "%s: %s", name, text)
            else:
                log.debug("%s: %s", name, text)

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(fmpy.calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(fmpy.free)
        try:
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(callbacks))
        except (ImportError, OSError):
            log.debug("fmpy logger proxy unavailable; FMU messages are not formatted")
        return callbacks


class GaussSeidel(Master):
    """Default: step all FMUs, then propagate outputs in dependency order at the new time."""

    name = "gauss-seidel"

    def _initialize_impl(self, t0: float) -> None:
        self._propagate(t0)
        for inst in self.instances:
            self._exit_initialization(inst, t0)
        self._propagate(t0)

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            status = inst.do_step(inst.c, t, h, 1)
            if status > 1:
                self._fail(inst, "fmi2DoStep", status, t)
        self.values[0] = t_next
        self._propagate(t_next)


class Jacobi(Master):
    """libcosim's fixed-step algorithm: one step of delay on every connection."""

    name = "jacobi"

    def _initialize_impl(self, t0: float) -> None:
        for sweep in range(len(self.instances)):
            for inst in self.instances:
                if sweep:
                    self._set_inputs(inst, t0)
                self._get_outputs(inst, t0)
            self._transfer_all()
        for inst in self.instances:
            self._set_inputs(inst, t0)
            self._exit_initialization(inst, t0)
            self._get_outputs(inst, t0)
        self._transfer_all()

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            c = inst.c
            if inst.in_vr._length_:
                status = inst.set_real(c, inst.in_vr, inst.in_vr._length_, inst.in_ptr)
                if status > 1:
                    self._fail(inst, "fmi2SetReal", status, t)
            status = inst.do_step(c, t, h, 1)
            if status > 1:
                self._fail(inst, "fmi2DoStep", status, t)
            status = inst.get_real(c, inst.out_vr, inst.out_vr._length_, inst.out_ptr)
            if status > 1:
                self._fail(inst, "fmi2GetReal", status, t)
        self.values[0] = t_next
        self._transfer_all()


MASTERS: dict[str, type[Master]] = {"gauss-seidel": GaussSeidel, "jacobi": Jacobi}
