"""Master algorithms: fixed communication step on the exact grid ``t_k = t0 + k*h``.

Time is an integer count of nanoseconds (as in libcosim) and converted to seconds once per
communication point, so the grid never drifts and ``t_k`` is the double nearest to ``t0 + k*h``.

Both masters share the lifecycle on ``Master``: ``setup`` (extract and instantiate every FMU,
prepare the value-reference and value arrays once) -> ``initialize`` (setupExperiment,
enterInitializationMode, start values, propagation of initial outputs, exitInitializationMode;
row t0) -> ``step`` (one communication step; one row) -> ``terminate``. Every FMU is terminated and
freed on every path through an ExitStack (but one that returned fmi2Fatal: FMI allows no call).

Faults end the run with the rows before them kept: an FMU call that fails (SimulationError), a
value that is not finite (NonFiniteError: the rows are checked in blocks of 16, so the run stops
at most 16 steps later and names the step it appeared at), the wall-clock limit ``timeout``
(TimeLimitError), SIGINT or SIGTERM (Interrupted). In the main thread the signals and the limit
only set a flag that the loop reads at the next communication point, because an exception raised
inside a Python FMU's code would make it fail with fmi2Fatal; a step that does not return
within ``GRACE`` seconds after the limit (or after a second Ctrl-C) is aborted by raising into it.

Values live in one float64 array ``values``: ``[time, inputs..., outputs...]``; each FMU's outputs
and inputs are contiguous slices of it, so one batched ``fmi2GetReal``/``fmi2SetReal`` per FMU
reads or writes it in place (ctypes arrays aliasing the NumPy buffer), and a connection is an index
gather ``values[inputs] = factor * values[sources] + offset``. The FMI calls themselves (instances,
checked calls, statuses, cleanup) are :mod:`orchestrator.fmi`'s.

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
import fnmatch
import math
import os
import shutil
import signal
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from ctypes import c_double, c_uint
from types import FrameType
from typing import Any, NamedTuple

import numpy as np

from . import files
from .errors import Interrupted, LoopError, NonFiniteError, SimulationError, TimeLimitError, terminate
from .fmi import CALLS, FAILED, Instance, InstanceBase, MessageLog, interpreter_guard, trace
from .inputs import InputSeries
from .results import NonFiniteError as NonFiniteRow
from .results import Recorder
from .system import ComponentModel, PortRef, System

__all__ = ["GRACE", "LOOP_ITERATIONS", "LOOP_TOLERANCE", "MASTERS", "MAX_TIME", "NS_PER_S", "GaussSeidel",
           "InstanceFactory", "Jacobi", "Master",
           "grid", "open_instance", "time_grid", "tracing"]

NS_PER_S = 1_000_000_000
MAX_TIME = (2**63 - 1) / NS_PER_S / 2  # s: t0 + n*h stays within int64 nanoseconds (292 years / 2)
GRACE = 2.0  # s a step may still take after the wall-clock limit or a second Ctrl-C before it is aborted
LOOP_TOLERANCE = 1e-10  # an algebraic loop has converged when no input on it moves by more (relative)
LOOP_ITERATIONS = 100  # sweeps of an algebraic loop at one communication point before it is a LoopError


def grid(start: float, stop: float, step: float) -> tuple[int, int, int]:
    """The grid t_k = t0 + k*h, k = 0..n, up to the last point not after ``stop``: t0 and h in
    integer nanoseconds (libcosim's time representation) and n. ValueError when a time is not
    finite or beyond ``MAX_TIME``, the step is below 1 ns or the stop is before the start."""
    for name, x in (("start time", start), ("stop time", stop), ("communication step", step)):
        if not (math.isfinite(x) and abs(x) <= MAX_TIME):
            raise ValueError(f"the {name} {x:g} s is not a finite time within +-{MAX_TIME:.3g} s")
    t0, t1, h = (round(x * NS_PER_S) for x in (start, stop, step))
    if h <= 0:
        raise ValueError(f"the communication step must be positive and at least 1 ns (got {step!r} s)")
    if t1 < t0:
        raise ValueError(f"the stop time {stop!r} s is before the start time {start!r} s")
    return t0, h, (t1 - t0) // h


def time_grid(start: float, stop: float, step: float) -> np.ndarray:
    """Communication points t_k = t0 + k*h, k = 0..n (:func:`grid`), in seconds, each computed in
    integer nanoseconds and rounded once."""
    t0, h, n = grid(start, stop, step)
    return (t0 + h * np.arange(n + 1, dtype=np.int64)) / NS_PER_S


class _Abort(BaseException):
    """Raised by a signal handler into a step that does not return (a BaseException, so that
    ``except Exception`` in our code or an FMU's does not swallow it)."""


class Stopper:
    """Turns SIGINT, SIGTERM and the wall-clock limit ``timeout`` into a request (``reason``) that the
    master reads at the next communication point; a second signal, or the limit + GRACE, raises
    _Abort into the step under way. Signal handlers are installed only in the main thread and only
    over the defaults (an application that set its own keeps them); elsewhere the limit is checked
    at each communication point."""

    def __init__(self, timeout: float | None) -> None:
        self.timeout = timeout
        self.reason: int | str | None = None  # a signal number or "timeout"
        self.aborted = False
        self._previous: dict[int, Any] = {}
        self.deadline = math.inf

    def __enter__(self) -> Stopper:
        if self.timeout is not None:
            self.deadline = time.monotonic() + self.timeout
        if threading.current_thread() is not threading.main_thread():
            return self
        defaults = {signal.SIGINT: (signal.default_int_handler,), signal.SIGTERM: (signal.SIG_DFL, terminate)}
        for signum, default in defaults.items():
            if signal.getsignal(signum) in default:
                self._previous[signum] = signal.signal(signum, self._on_signal)
        if self.timeout is not None and signal.getsignal(signal.SIGALRM) is signal.SIG_DFL:
            self._previous[signal.SIGALRM] = signal.signal(signal.SIGALRM, self._on_alarm)
            signal.setitimer(signal.ITIMER_REAL, max(self.timeout, 1e-6))
            self.deadline = math.inf  # the timer does it
        return self

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        if self.reason is not None:
            self.aborted = True
            raise _Abort
        self.reason = signum

    def _on_alarm(self, signum: int, frame: FrameType | None) -> None:
        if self.reason is None:
            self.reason = "timeout"
            signal.setitimer(signal.ITIMER_REAL, GRACE)  # the step under way gets GRACE s to return
        else:
            self.aborted = True
            raise _Abort

    def requested(self) -> bool:
        """Whether the run must stop at this communication point."""
        if self.reason is None and time.monotonic() > self.deadline:
            self.reason = "timeout"
        return self.reason is not None

    def disarm(self) -> None:
        """No more alarm (the loop has stopped)."""
        if signal.SIGALRM in self._previous:
            signal.setitimer(signal.ITIMER_REAL, 0)

    def error(self, t: float, component: str = "") -> TimeLimitError | Interrupted:
        """The exception that ends the run: TimeLimitError or Interrupted."""
        if isinstance(self.reason, int):
            return Interrupted(signal.Signals(self.reason).name, self.reason, t)
        return TimeLimitError(self.timeout or 0.0, t, component, GRACE if component else 0.0)

    def __exit__(self, *exc: object) -> None:
        self.disarm()
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)


class Copy(NamedTuple):
    """A connection without transformation: ``values[dst] = values[src]``."""

    dst: int
    src: int


class Scaled(NamedTuple):
    """A connection with ``ssc:LinearTransformation``: ``values[dst] = factor * values[src] + offset``."""

    dst: int
    src: int
    factor: float
    offset: float


class Driven(NamedTuple):
    """The inputs of one instance that an input file drives: one batched fmi2SetReal of the
    ``values[where]`` slice, filled from the series' ``columns``."""

    instance: InstanceBase
    vrs: ctypes.Array
    n_values: int
    values: ctypes.Array
    where: slice
    columns: list[int]


class Operation(NamedTuple):
    """One step of the propagation at a communication point: read an FMU's outputs, or transfer
    connections into some of its inputs and write them, as one batched FMI call."""

    is_set: bool
    instance: InstanceBase
    function: Callable[..., int]  # the instance's fmi2SetReal or fmi2GetReal
    vrs: ctypes.Array
    n_values: int
    values: ctypes.Array  # view of the master's value buffer
    copies: tuple[Copy, ...]
    scaled: tuple[Scaled, ...]


def open_instance(comp: ComponentModel, workdir: str, messages: MessageLog, time: float) -> InstanceBase:
    """The real instance of ``comp``: its FMU extracted into ``workdir`` and instantiated."""
    return Instance.open(comp.name, comp.fmu, comp.model.guid, comp.model.coSimulation.modelIdentifier,
                         workdir, messages, time)


InstanceFactory = Callable[[ComponentModel, str, MessageLog, float], InstanceBase]


def tracing(patterns: Sequence[str], factory: InstanceFactory = open_instance) -> InstanceFactory:
    """``factory`` whose instances of the components matching ``patterns`` (shell patterns) log
    every FMI call (:func:`orchestrator.fmi.trace`, ``--fmi-log``)."""
    def open_traced(comp: ComponentModel, workdir: str, messages: MessageLog, time: float) -> InstanceBase:
        instance = factory(comp, workdir, messages, time)
        if any(fnmatch.fnmatchcase(comp.name, p) for p in patterns):
            CALLS.info("%s: fmi2Instantiate(%s) -> ok", comp.name, comp.fmu.name)
            trace(instance)
        return instance
    return open_traced


class Master:
    """Base class: the lifecycle and everything both algorithms share.

    The contract of a subclass (registered by name in :data:`MASTERS`):

    * ``name``: the name ``--master`` takes;
    * ``_initialize_impl(t0)``: called in initialization mode, after every instance's start values
      and ``setup``; it must leave every instance in step mode (``exit_initialization``) with
      ``values`` holding consistent outputs and inputs at t0 (the row the base class records);
    * ``_step_impl(t, h, t_next)``: advance every instance from ``t`` by ``h`` and leave ``values``
      as the row at ``t_next`` (``values[0] = t_next``); the base class records it.

    Both call only the instance interface of :class:`~orchestrator.fmi.InstanceBase` (``step``,
    ``read_outputs``, ``write_inputs``, :meth:`_propagate`, :meth:`_transfer_all`) and let a failed
    call raise its SimulationError: the base class owns the grid (``t_k = t0 + k h`` in integer
    nanoseconds), recording, the checks for non-finite values, the wall-clock limit and signals,
    and cleanup on every path.

    ``progress`` (if given) is called with the number of steps done, about every 1 % of the run.
    ``keep`` False (with an ``output``): rows are only streamed to the CSV and ``run`` returns a
    preview for plotting (:class:`~orchestrator.results.Recorder`), so memory stays flat however
    long the run. ``timeout``: wall-clock limit of the run in seconds. ``instances`` makes the
    instance of each component (default :func:`open_instance`; a fake in the fast unit tests).
    ``inputs`` drives unconnected inputs (:mod:`orchestrator.inputs`): set at t0 in initialization
    mode, then at each t_k+1 before its outputs are read (gauss-seidel) or after the step's transfer
    (jacobi, whose FMUs then use them in the next step, like every value it exchanges).
    """

    name = ""

    def __init__(self, system: System, start_time: float, stop_time: float, step: float,
                 output: str | os.PathLike | None = None,
                 progress: Callable[[int, int], None] | None = None, keep: bool = True,
                 timeout: float | None = None, instances: InstanceFactory = open_instance,
                 inputs: InputSeries | None = None, binary_copy: bool = False,
                 loop_tolerance: float = LOOP_TOLERANCE, loop_iterations: int = LOOP_ITERATIONS) -> None:
        self.system = system
        self.loop_tolerance, self.loop_iterations = loop_tolerance, loop_iterations
        self.binary_copy = binary_copy  # the CSV is staged for another format: a float64 copy beside it
        self._t0, self._h, self.n = grid(start_time, stop_time, step)
        self.start_time = self._t0 / NS_PER_S
        self.stop_time = stop_time
        self.output = output
        self.progress = progress
        self.keep = keep
        self.timeout = timeout
        self.open_instance = instances
        self.inputs = inputs
        self._driven: list[Driven] = []
        self.instances: list[InstanceBase] = []
        self.recorder: Recorder | None = None
        self.messages = MessageLog()

    @property
    def times(self) -> np.ndarray:
        """Every communication point (for inspection; the loop computes t_k as it goes)."""
        return (self._t0 + self._h * np.arange(self.n + 1, dtype=np.int64)) / NS_PER_S

    def time(self, k: int) -> float:
        """t_k in seconds."""
        return (self._t0 + self._h * k) / NS_PER_S

    # -- public lifecycle -------------------------------------------------------------------
    def run(self) -> np.ndarray:
        """setup -> initialize -> step* -> terminate; returns the structured result array.

        On failure, timeout or interruption the rows computed so far are kept (in the CSV and in
        ``self.recorder``) and the error (SimulationError, NonFiniteError, TimeLimitError,
        Interrupted; each with ``result`` and ``rows``) is raised after every FMU has been freed.
        """
        with ExitStack() as stack:
            stopper = stack.enter_context(Stopper(self.timeout))
            self.setup(stack)
            recorder = self.recorder
            assert recorder is not None  # setup() creates it
            stack.callback(recorder.close)
            try:
                self.initialize()
                n = self.n
                stride = max(1, n // 100)
                poll = stopper.deadline != math.inf  # no timer: compare the clock at each point
                for k in range(n):
                    self.step(k)
                    if stopper.reason is not None or (poll and stopper.requested()):
                        stopper.disarm()
                        raise stopper.error(self.time(k + 1))
                    if self.progress is not None and (k + 1) % stride == 0:
                        self.progress(k + 1, n)
                recorder.check()
                self.terminate()
            except NonFiniteRow as exc:
                stopper.disarm()
                raise self._kept(self._non_finite(exc)) from None
            except (SimulationError, _Abort) as exc:
                stopper.disarm()
                raise self._kept(self._cause(exc, stopper)) from None
            except (Interrupted, TimeLimitError) as exc:
                raise self._kept(exc) from None
        return recorder.result()

    def _kept(self, exc: SimulationError | Interrupted) -> SimulationError | Interrupted:
        """``exc`` with the rows kept: ``rows`` (their number) and ``result`` (as ``run`` returns)."""
        assert self.recorder is not None
        exc.rows = self.recorder.count
        exc.result = self.recorder.result()
        return exc

    def _cause(self, exc: SimulationError | _Abort, stopper: Stopper) -> SimulationError | Interrupted:
        """What to report for a failed call or an aborted step: the stop request that caused it, or
        a non-finite value among the rows not yet checked (it came first), or the failure itself."""
        assert self.recorder is not None
        component = getattr(exc, "component", "")
        t = getattr(exc, "time", self.time(self.recorder.count))
        if stopper.reason is not None:
            if isinstance(exc, SimulationError):
                for inst in self.instances:
                    if inst.name == component and stopper.aborted:
                        inst.broken = True  # the exception raised into it made it fail
            return stopper.error(t, component if stopper.aborted else "")
        try:
            self.recorder.check()
        except NonFiniteRow as row:
            return self._non_finite(row)
        assert isinstance(exc, SimulationError)  # _Abort is raised only after a stop request
        return exc

    def _non_finite(self, exc: NonFiniteRow) -> NonFiniteError:
        """The NonFiniteError naming the component, variable and time of a non-finite value: of
        the outputs of that row, the first read in propagation order (the values after it may only
        have passed it on through a direct feedthrough), else the column the recorder found."""
        assert self.recorder is not None
        row = self.recorder.data[exc.row - self.recorder._base]
        column = next((c for c in self._output_order if not math.isfinite(row[c])), exc.column)
        port = self.system.port(self.columns[column])
        kind = "output" if column >= self._first_output else "input"
        value = float(row[column])
        return NonFiniteError(port.component, port.connector, kind, value, self.time(exc.row))

    def setup(self, stack: ExitStack) -> None:
        """Extract and instantiate every FMU (freed by ``stack``) and lay out the value arrays."""
        workdir = str(files.temporary_folder("orchestrate-"))
        stack.callback(shutil.rmtree, workdir, ignore_errors=True)
        stack.enter_context(interpreter_guard())
        for comp in self.system.components.values():
            instance = self.open_instance(comp, workdir, self.messages, self.start_time)
            stack.callback(instance.release)
            self.instances.append(instance)
        self._layout()
        self.recorder = Recorder(self.columns, self.n + 1, self.output, keep=self.keep or self.output is None,
                                 binary_copy=self.binary_copy)

    def initialize(self) -> None:
        """FMI initialization; afterwards every FMU is in step mode and row t0 is recorded."""
        t0 = self.start_time
        stop = self.time(self.n) if self.stop_time is None else float(self.stop_time)
        for inst in self.instances:
            start_values = self._start_values(self.system.components[inst.name])
            inst.set_start_values(start_values, t0)
            inst.setup(t0, stop)
            inst.set_start_values(start_values, t0)
        self._drive(t0)
        self._initialize_impl(t0)
        assert self.recorder is not None  # setup() creates it
        self.recorder.append(self.values)

    def step(self, k: int) -> None:
        """Advance every FMU from t_k to t_k+1 and record row t_k+1."""
        t, t_next = (self._t0 + self._h * k) / NS_PER_S, (self._t0 + self._h * (k + 1)) / NS_PER_S
        self._step_impl(t, t_next - t, t_next)
        assert self.recorder is not None  # setup() creates it
        self.recorder.append(self.values)

    def terminate(self) -> None:
        """fmi2Terminate on every FMU (they are freed by the ExitStack)."""
        t = float(self.values[0])
        for inst in self.instances:
            inst.terminate(t)

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
        input_order, n_connected = self._input_order()
        columns += [str(p) for p in input_order]
        slot = {p: 1 + j for j, p in enumerate(input_order)}
        out_slice: dict[str, slice] = {}
        self._first_output = len(columns)
        for comp in system.components.values():
            first = len(columns)
            columns += [str(PortRef(comp.name, o)) for o in comp.outputs]
            out_slice[comp.name] = slice(first, len(columns))
            for o in comp.outputs:
                slot[PortRef(comp.name, o)] = len(slot) + 1
        self.columns = columns
        index = {name: j for j, name in enumerate(columns)}
        read = [op.component for op in system.schedule if op.kind == "get"]
        read += [name for name in system.components if name not in read]
        self._output_order = [index[str(PortRef(name, o))] for name in read
                              for o in system.components[name].outputs]
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
            inst.out_ptr = self._view(out_slice[inst.name])
            mine = [j for j, p in enumerate(input_order[:n_connected]) if p.component == inst.name]
            if mine:
                inst.in_vr = self._vrs(comp, [input_order[j].connector for j in mine])
                inst.in_ptr = self._view(slice(1 + mine[0], 2 + mine[-1]))
        self._layout_driven(input_order[n_connected:], slot)
        self._layout_ops(slot)

    def _input_order(self) -> tuple[list[PortRef], int]:
        """The inputs' places in ``values`` and how many are connected: connected inputs in schedule
        order (each set operation a contiguous slice), then per component the unconnected ones,
        those an input file drives first (each instance's a contiguous slice)."""
        system = self.system
        order: list[PortRef] = []
        for comp in system.components.values():
            for op in system.schedule:
                if op.kind == "set" and op.component == comp.name:
                    order += [PortRef(op.component, i) for i in op.inputs]
        n_connected = len(order)
        driven = set(self.inputs.ports) if self.inputs is not None else set()
        for comp in system.components.values():
            free = [p for p in (PortRef(comp.name, i) for i in comp.inputs) if p not in system.links]
            order += [p for p in free if p in driven] + [p for p in free if p not in driven]
        return order, n_connected

    def _layout_driven(self, unconnected: list[PortRef], slot: dict[PortRef, int]) -> None:
        """The batched fmi2SetReal of the inputs an input file drives, per instance."""
        if self.inputs is None:
            return
        driven = list(self.inputs.ports)
        for inst in self.instances:
            fed = [p for p in unconnected if p.component == inst.name and p in driven]
            if fed:
                comp = self.system.components[inst.name]
                where = slice(slot[fed[0]], slot[fed[0]] + len(fed))
                self._driven.append(Driven(inst, self._vrs(comp, [p.connector for p in fed]), len(fed),
                                           self._view(where), where, [driven.index(p) for p in fed]))

    def _layout_ops(self, slot: dict[PortRef, int]) -> None:
        """The propagation at a communication point (gauss-seidel) as batched calls, cut into
        segments: run once, or (an algebraic loop, ``System.iterated``) repeated until it converges."""
        system = self.system
        by_name = {inst.name: inst for inst in self.instances}
        self._ops: list[Operation] = []
        self._segments: list[tuple[list[Operation], np.ndarray | None, list[str]]] = []
        for op in system.schedule:
            inst = by_name[op.component]
            if op.kind == "get":
                self._ops.append(Operation(False, inst, inst.get_real, inst.out_vr, len(inst.out_vr),
                                           inst.out_ptr, (), ()))
            else:
                ports = [PortRef(op.component, i) for i in op.inputs]
                dst = slice(slot[ports[0]], slot[ports[-1]] + 1)
                vrs = self._vrs(system.components[op.component], op.inputs)
                copies, scaled = self._transfers(ports, slot)
                self._ops.append(Operation(True, inst, inst.set_real, vrs, len(ports), self._view(dst),
                                           copies, scaled))
        cut = 0
        for first, end in system.iterated:
            if first > cut:
                self._segments.append((self._ops[cut:first], None, []))
            loop = self._ops[first:end]
            inputs = np.array([c[0] for op in loop for c in (*op.copies, *op.scaled)], dtype=np.intp)
            names = list(dict.fromkeys(op.instance.name for op in loop))
            self._segments.append((loop, inputs, names))
            cut = end
        if cut < len(self._ops) or not self._segments:
            self._segments.append((self._ops[cut:], None, []))

    def _transfers(self, ports: list[PortRef],
                   slot: dict[PortRef, int]) -> tuple[tuple[Copy, ...], tuple[Scaled, ...]]:
        """The connections into ``ports``: plain copies, and those with a linear transformation."""
        links = [self.system.links[p] for p in ports]
        plain = [lk.factor == 1.0 and lk.offset == 0.0 for lk in links]
        copies = tuple(Copy(slot[lk.end], slot[lk.start]) for lk, p in zip(links, plain, strict=True) if p)
        scaled = tuple(Scaled(slot[lk.end], slot[lk.start], lk.factor, lk.offset)
                       for lk, p in zip(links, plain, strict=True) if not p)
        return copies, scaled

    @staticmethod
    def _vrs(comp: ComponentModel, names: Sequence[str]) -> ctypes.Array:
        variables = comp.variables
        return (c_uint * len(names))(*[variables[n].valueReference for n in names])

    @staticmethod
    def _start_values(comp: ComponentModel) -> dict[str, tuple[str, int, object]]:
        """Parameters and start values from the SSD, .ssv files and overrides: name -> (type, vr, value)."""
        variables = comp.variables
        return {name: (variables[name].type, variables[name].valueReference, value)
                for name, value in comp.start_values.items()}

    def _view(self, part: slice) -> ctypes.Array:
        n = part.stop - part.start
        return (c_double * n).from_buffer(self.values, part.start * self.values.itemsize)

    def _drive(self, t: float) -> None:
        """Set the inputs the input file drives to their values at ``t``."""
        if not self._driven:
            return
        assert self.inputs is not None  # _driven is laid out from it
        u = self.inputs.at(t)
        for inst, vr, n, ptr, where, columns in self._driven:
            self.values[where] = u[columns]
            status = inst.set_real(inst.c, vr, n, ptr)
            if status >= FAILED:
                inst.fail("fmi2SetReal", status, t)

    def _transfer_all(self) -> None:
        v = self._cvalues
        for dst, src in self._all_copy:
            v[dst] = v[src]
        for dst, src, factor, offset in self._all_scaled:
            v[dst] = factor * v[src] + offset

    def _propagate(self, t: float) -> None:
        """Read outputs and set inputs in dependency order (gauss-seidel at a communication point);
        an algebraic loop is swept until its inputs converge (fixed-point iteration)."""
        for ops, loop, names in self._segments:
            if loop is None:
                self._run_ops(ops, t)
            else:
                self._iterate(ops, loop, names, t)

    def _iterate(self, ops: list[Operation], inputs: np.ndarray, names: list[str], t: float) -> None:
        """Sweep the operations of an algebraic loop until no input on it moves by more than the
        tolerance (relative to 1 + its size) from one sweep to the next; LoopError after
        ``loop_iterations`` sweeps."""
        values = self.values
        before = values[inputs]
        residual = math.inf
        for _ in range(self.loop_iterations):
            self._run_ops(ops, t)
            after = values[inputs]
            residual = float(np.max(np.abs(after - before) / (1.0 + np.abs(after)), initial=0.0))
            if residual <= self.loop_tolerance or not math.isfinite(residual):
                return  # converged; or an FMU gave a value that is not finite, which the recorder names
            before = after
        raise LoopError(names, t, residual, self.loop_iterations, self.loop_tolerance)

    def _run_ops(self, ops: list[Operation], t: float) -> None:
        """The batched FMI calls of ``ops`` once, transferring connections before each set."""
        v = self._cvalues
        for is_set, inst, fn, vr, n, ptr, copies, scaled in ops:
            if is_set:
                for dst, src in copies:
                    v[dst] = v[src]
                for dst, src, factor, offset in scaled:
                    v[dst] = factor * v[src] + offset
            elif not n:
                continue
            status = fn(inst.c, vr, n, ptr)
            if status >= FAILED:
                inst.fail("fmi2SetReal" if is_set else "fmi2GetReal", status, t)


class GaussSeidel(Master):
    """Default: step all FMUs, then propagate outputs in dependency order at the new time."""

    name = "gauss-seidel"

    def _initialize_impl(self, t0: float) -> None:
        self._propagate(t0)
        for inst in self.instances:
            inst.exit_initialization(t0)
        self._propagate(t0)

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            inst.step(t, h)
        self.values[0] = t_next
        self._drive(t_next)
        self._propagate(t_next)


class Jacobi(Master):
    """libcosim's fixed-step algorithm: one step of delay on every connection."""

    name = "jacobi"

    def _initialize_impl(self, t0: float) -> None:
        for sweep in range(len(self.instances)):
            for inst in self.instances:
                if sweep:
                    inst.write_inputs(t0)
                inst.read_outputs(t0)
            self._transfer_all()
        for inst in self.instances:
            inst.write_inputs(t0)
            inst.exit_initialization(t0)
            inst.read_outputs(t0)
        self._transfer_all()

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            inst.write_inputs(t)
            inst.step(t, h)
            inst.read_outputs(t)
        self.values[0] = t_next
        self._transfer_all()
        self._drive(t_next)


MASTERS: dict[str, type[Master]] = {"gauss-seidel": GaussSeidel, "jacobi": Jacobi}
