# SPDX-License-Identifier: BSD-2-Clause
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

FMI 3.0 clocks (:mod:`orchestrator.clocks`): an FMU with periodic input clocks is instantiated with
event mode used, and both masters tick its clocks on schedule. A communication step that holds a
tick is cut there (the FMUs step to the tick, the values are exchanged at it as at any
communication point, then every instance whose clocks tick runs its event: fmi3EnterEventMode,
fmi3SetClock, fmi3UpdateDiscreteStates, fmi3EnterStepMode, and its clocked outputs are passed
on), so ticks land exactly where the master's step does not divide the interval; rows are still
recorded at the grid points only. A tick at t0 is made right after initialization. An FMU asking
for event mode after a step (``eventHandlingNeeded``) gets an event with no clock active. The compiled
executor (``orchestrator/native/core.c``) does the same in C, on the clocks as asked here.

Which one runs (:func:`orchestrator.validate.choose_master`): ``--master``, else the one the SSD's
algorithm annotation implies (libcosim's ``osp:FixedStepAlgorithm``: jacobi; OMSimulator's
``oms:FixedStepMaster``: gauss-seidel), else gauss-seidel.

* ``gauss-seidel`` (default): all FMUs step from t_k to t_k+1 with inputs held; then, at t_k+1,
  outputs are read and inputs set in the dependency order of the ModelStructure (``System.schedule``),
  so a direct-feedthrough output (the controller's v, the actuator's uf) at t_k+1 already uses the
  plant state at t_k+1: no artificial delay in a sampled controller.
* ``jacobi``: libcosim's fixed-step algorithm (0.11): every FMU sets the inputs transferred at the
  end of the previous step, steps, and its outputs are read; then all connections are transferred.
  Each connection therefore adds one step of delay. Initialization repeats N sweeps of
  (set, get, transfer) in initialization mode (N = number of FMUs), then set, exit, get, transfer.
  A clock's event at a communication point is part of computing the FMU's outputs there, so it
  sees the inputs set at the previous communication point, as the step before it did (no values
  are set between the step and the event); its clocked outputs are then read and transferred.
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
from dataclasses import replace
from types import FrameType
from typing import Any, NamedTuple

import numpy as np

from . import files
from .clocks import InputClock, due, pieces
from .errors import (
    Interrupted,
    LoopError,
    NonFiniteError,
    SimulationError,
    TimeLimitError,
    terminate,
)
from .fmi import CALLS, FAILED, Instance, InstanceBase, MessageLog, failed_call, interpreter_guard, trace
from .inputs import InputSeries
from .native import FUNCTIONS, NO_STATUS, Stepper
from .plan import MAX_TIME, NS_PER_S, Transfer, grid, make_plan, time_grid
from .results import NonFiniteError as NonFiniteRow
from .results import Recorder
from .system import ComponentModel, System

__all__ = ["GRACE", "LOOP_ITERATIONS", "LOOP_TOLERANCE", "MASTERS", "MAX_TIME", "NS_PER_S", "GaussSeidel",
           "InstanceFactory", "Jacobi", "Master",
           "grid", "open_instance", "time_grid", "tracing"]

GRACE = 2.0  # s a step may still take after the wall-clock limit or a second Ctrl-C before it is aborted
LOOP_TOLERANCE = 1e-10  # an algebraic loop has converged when no input on it moves by more (relative)
LOOP_ITERATIONS = 100  # sweeps of an algebraic loop at one communication point before it is a LoopError
BLOCK = 256  # steps the compiled executor makes between two looks at signals, the clock and progress


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
        self.flag = ctypes.c_int(0)  # 1 once there is a reason: the compiled executor stops at the next point
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
        self.flag.value = 1

    def _on_alarm(self, signum: int, frame: FrameType | None) -> None:
        if self.reason is None:
            self.reason = "timeout"
            self.flag.value = 1
            signal.setitimer(signal.ITIMER_REAL, GRACE)  # the step under way gets GRACE s to return
        else:
            self.aborted = True
            raise _Abort

    def requested(self) -> bool:
        """Whether the run must stop at this communication point."""
        if self.reason is None and time.monotonic() > self.deadline:
            self.reason = "timeout"
            self.flag.value = 1
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
    cs = comp.model.coSimulation
    return Instance.open(comp.name, comp.fmu, comp.model.guid, cs.modelIdentifier, workdir, messages, time,
                         shared=not cs.canBeInstantiatedOnlyOncePerProcess, event_mode=bool(comp.clocks))


InstanceFactory = Callable[[ComponentModel, str, MessageLog, float], InstanceBase]
# the result's columns -> the indices of those the output file holds (None: all) and its interval in
# ns (None: every row)
Layout = Callable[[Sequence[str]], tuple[list[int] | None, int | None]]


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
    long the run (``preview`` False: only its first and last rows). ``timeout``: wall-clock limit
    of the run in seconds. ``instances`` makes the instance of each component (default
    :func:`open_instance`; a fake in the fast unit tests).
    ``layout`` says which columns and rows the output file holds (only they are formatted).
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
                 loop_tolerance: float = LOOP_TOLERANCE, loop_iterations: int = LOOP_ITERATIONS,
                 compiled: bool = False, layout: Layout | None = None, preview: bool = True) -> None:
        self.system = system
        self.compiled = compiled
        self.loop_tolerance, self.loop_iterations = loop_tolerance, loop_iterations
        self.binary_copy = binary_copy  # the CSV is staged for another format: a float64 copy beside it
        self.layout = layout  # what the output file holds of each row (RunOutput.layout); None: all
        self.plan = make_plan(system, start_time, stop_time, step, self.name,
                              inputs.ports if inputs is not None else ())
        self._t0, self._h, self.n = self.plan.t0, self.plan.h, self.plan.n
        self.start_time = self.plan.start_time
        self.stop_time = stop_time
        self.columns = list(self.plan.columns)
        self.output = output
        self.progress = progress
        self.keep = keep
        self.preview = preview  # keep False: a preview for plotting (False: the first and last rows)
        self.timeout = timeout
        self.open_instance = instances
        self.inputs = inputs
        self._driven: list[Driven] = []
        self.instances: list[InstanceBase] = []
        self.recorder: Recorder | None = None
        self.messages = MessageLog()
        self.stopper: Stopper | None = None  # while run() runs: the stop requests
        self._clocked: list[tuple[InstanceBase, list[InputClock]]] = []  # instances with clocks (setup)
        self._all_clocks: list[InputClock] = []

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
            stopper = self.stopper = stack.enter_context(Stopper(self.timeout))
            self.setup(stack)
            recorder = self.recorder
            assert recorder is not None  # setup() creates it
            stack.callback(recorder.close)
            try:
                self.initialize()
                self._step_all(stopper, stack)
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

    def _stop_if_asked(self, t: float) -> None:
        """Raise the stop request (Ctrl-C, SIGTERM, the time limit) at ``t``, if there is one: checked
        between two components of the set-up and the initialization too, each of which may call a
        slow FMU (a scenario of 200 Python FMUs served Ctrl-C only after all were instantiated and
        initialized)."""
        if self.stopper is not None and self.stopper.requested():
            self.stopper.disarm()
            raise self.stopper.error(t)

    def _step_all(self, stopper: Stopper, stack: ExitStack) -> None:
        """Every step of the run: one at a time in Python, or blocks of up to ``BLOCK`` in C (the
        compiled executor); after each, a stop request ends the run and progress is reported at
        every 1 % of the steps."""
        n, k = self.n, 0
        stride = max(1, n // 100)
        poll = stopper.deadline != math.inf  # no timer: compare the clock at each point
        stepper = None
        if self.compiled:  # the clocks as asked in Initialization Mode
            index = {id(inst): i for i, inst in enumerate(self.instances)}
            asked = tuple((index[id(inst)], c) for inst, clocks in self._clocked for c in clocks)
            stepper = Stepper(replace(self.plan, clocks=asked), self.instances)
            stack.callback(stepper.close)
        while k < n:
            if stepper is None:
                self.step(k)
                k += 1
            else:
                k += self._block(stepper, k, min(n - k, BLOCK, stride - k % stride), stopper.flag)
            if stopper.reason is not None or (poll and stopper.requested()):
                stopper.disarm()
                raise stopper.error(self.time(k))
            if self.progress is not None and k % stride == 0:
                self.progress(k, n)

    def _block(self, stepper: Stepper, k: int, most: int, stop: ctypes.c_int) -> int:
        """At most ``most`` steps from t_k in C, their rows recorded; a failed call raises its
        SimulationError after the rows before it are recorded."""
        assert self.recorder is not None  # setup() creates it
        rows = self.recorder.space(most)
        driven = None
        if self._driven:
            assert self.inputs is not None  # _driven is laid out from it
            ends = self._t0 + self._h * np.arange(k + 1, k + 1 + len(rows), dtype=np.int64)
            if self._all_clocks:  # a row per piece of a step cut at the ticks, as the C code steps them
                ends = np.array([stop for end in ends.tolist()
                                 for stop in pieces(self._all_clocks, end - self._h, end, self._t0)],
                                dtype=np.int64)
            driven = np.ascontiguousarray(self.inputs.table(ends / NS_PER_S)[:, self._driven_columns])
        made = stepper.run(self.values, k, rows, driven, stop)
        self.recorder.commit(made)
        failure = stepper.failure
        if failure.status:
            inst = self.instances[failure.component]
            if failure.status < 0:  # no FMI status: fmi3UpdateDiscreteStates's verdict
                raise SimulationError(inst.name, FUNCTIONS[failure.function],
                                      NO_STATUS.get(failure.status, f"no FMI status ({failure.status})"),
                                      failure.time, self.messages.last.get(inst.name, ""))
            inst.fail(FUNCTIONS[failure.function], failure.status, failure.time)
        return made

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
        column = next((c for c in self.plan.output_order if not math.isfinite(row[c])), exc.column)
        port = self.system.port(self.columns[column])
        kind = "output" if column >= self.plan.first_output else "input"
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
            self._stop_if_asked(self.start_time)
        self._layout()
        components = self.system.components.values()
        self._clocked = [(inst, comp.clocks) for inst, comp in zip(self.instances, components, strict=True)
                         if comp.clocks]
        self._all_clocks = [c for _, clocks in self._clocked for c in clocks]
        file_columns, interval_ns = self.layout(self.columns) if self.layout is not None else (None, None)
        self.recorder = Recorder(self.columns, self.n + 1, self.output, keep=self.keep or self.output is None,
                                 binary_copy=self.binary_copy, file_columns=file_columns,
                                 interval_ns=interval_ns, preview=self.preview)

    def initialize(self) -> None:
        """FMI initialization; afterwards every FMU is in step mode and row t0 is recorded."""
        t0 = self.start_time
        stop = self.plan.stop
        tolerance = self.system.structure.experiment.tolerance  # OMSimulator's, when its file gives one
        for inst, part in zip(self.instances, self.plan.components, strict=True):
            start_values = part.starts
            inst.set_start_values(start_values, t0)
            inst.setup(t0, stop, tolerance)
            inst.set_start_values(start_values, t0)
            self._stop_if_asked(t0)
        self._ask_clocks(t0)
        self._drive(t0)
        self._initialize_impl(t0)
        assert self.recorder is not None  # setup() creates it
        self.recorder.append(self.values)

    def _ask_clocks(self, t0: float) -> None:
        """The interval and shift of each fixed clock that its FMU gives (in Initialization Mode,
        the parameters set): asked once, before the first tick."""
        asked = []
        for inst, declared in self._clocked:
            clocks = list(declared)  # the system's own stay as declared (a campaign reuses it)
            for j, clock in enumerate(clocks):
                if clock.interval_ns == 0:
                    try:
                        clocks[j] = clock.asked(*inst.clock_timing(t0, clock.vr))
                    except ValueError as exc:
                        raise SimulationError(inst.name, "fmi3GetIntervalDecimal", "an unusable interval", t0,
                                              str(exc)) from None
            asked.append((inst, clocks))
        self._clocked = asked
        self._all_clocks = [c for _, clocks in asked for c in clocks]

    def step(self, k: int) -> None:
        """Advance every FMU from t_k to t_k+1 and record row t_k+1; with clocks, the step is cut at
        every tick inside it and the ticks are made there."""
        start, end = self._t0 + self._h * k, self._t0 + self._h * (k + 1)
        if not self._all_clocks:  # the common case: one step, no look for ticks
            t, t_next = start / NS_PER_S, end / NS_PER_S
            self._step_impl(t, t_next - t, t_next)
        else:
            self._step_to_ticks(start, end)
        assert self.recorder is not None  # setup() creates it
        self.recorder.append(self.values)

    def _step_to_ticks(self, start: int, end: int) -> None:
        """From ``start`` to ``end`` (ns): a step cut at every tick inside, the ticks made there."""
        for stop in pieces(self._all_clocks, start, end, self._t0):
            t, t_next = start / NS_PER_S, stop / NS_PER_S
            self._step_impl(t, t_next - t, t_next)
            self._events(stop)
            start = stop

    def _events(self, t_ns: int, initial: bool = False) -> None:
        """The clock ticks at ``t_ns`` and the events the FMUs asked for: each such instance gets
        its event (:meth:`InstanceBase.tick`) with the inputs it holds (gauss-seidel: propagated at
        ``t_ns``; jacobi: those of the previous communication point), then its outputs are passed
        on (``_after_events``). ``initial``: right after initialization, where every clocked
        instance is in event mode."""
        t = t_ns / NS_PER_S
        ticked = []
        for inst, clocks in self._clocked:
            active = [c.vr for c in due(clocks, t_ns, self._t0)]
            if active or initial or inst.event_requested():
                inst.tick(t, active)
                ticked.append(inst)
        if ticked:
            self._after_events(ticked, t)

    def _after_events(self, ticked: list[InstanceBase], t: float) -> None:
        """After the events at ``t``: the clocked outputs reach the inputs they feed."""
        raise NotImplementedError

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
        """The value buffer as the plan lays it out, and the batched calls on views of it."""
        plan = self.plan
        self.values = np.array(plan.initial)
        self._cvalues = self._view(slice(0, len(plan.columns)))
        self._all_copy, self._all_scaled = self._transfers(plan.transfers)
        self._driven = []
        self._driven_columns = [j for part in plan.components for j in part.columns]
        for inst, part in zip(self.instances, plan.components, strict=True):
            inst.out_vr, inst.out_ptr = self._vrs(part.outputs.vrs), self._view(part.outputs.slice)
            inst.get_outputs = inst.exchange(False, part.outputs.ints)
            if part.inputs.vrs:
                inst.in_vr, inst.in_ptr = self._vrs(part.inputs.vrs), self._view(part.inputs.slice)
                inst.set_inputs = inst.exchange(True, part.inputs.ints)
            if part.driven.vrs:
                d = part.driven
                self._driven.append(Driven(inst, self._vrs(d.vrs), len(d.vrs), self._view(d.slice), d.slice,
                                           list(part.columns)))
        ops = []
        for call in plan.propagation:
            inst, b = self.instances[call.batch.component], call.batch
            function = inst.exchange(call.is_set, b.ints)
            copies, scaled = self._transfers(call.transfers)
            ops.append(Operation(call.is_set, inst, function, self._vrs(b.vrs), len(b.vrs),
                                 self._view(b.slice), copies, scaled))
        self._ops = ops
        self._segments = [(ops[s.first:s.end], np.array(s.inputs, dtype=np.intp) if s.loop else None,
                           list(s.components)) for s in plan.spans]

    @staticmethod
    def _transfers(transfers: Sequence[Transfer]) -> tuple[tuple[Copy, ...], tuple[Scaled, ...]]:
        """Connections as the loops apply them: plain copies, and those with a linear transformation."""
        return (tuple(Copy(t.dst, t.src) for t in transfers if t.plain),
                tuple(Scaled(t.dst, t.src, t.factor, t.offset) for t in transfers if not t.plain))

    @staticmethod
    def _vrs(vrs: Sequence[int]) -> ctypes.Array:
        return (c_uint * len(vrs))(*vrs)

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
                inst.fail(failed_call(fn, "fmi2SetReal" if is_set else "fmi2GetReal"), status, t)


class GaussSeidel(Master):
    """Default (unless the SSD names libcosim's algorithm): step all FMUs, then propagate outputs
    in dependency order at the new time."""

    name = "gauss-seidel"

    def _initialize_impl(self, t0: float) -> None:
        self._propagate(t0)
        for inst in self.instances:
            inst.exit_initialization(t0)
        self._propagate(t0)
        if self._clocked:
            self._events(self._t0, initial=True)

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            inst.step(t, h)
        self.values[0] = t_next
        self._drive(t_next)
        self._propagate(t_next)

    def _after_events(self, ticked: list[InstanceBase], t: float) -> None:
        self._propagate(t)


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
            self._stop_if_asked(t0)
        for inst in self.instances:
            inst.write_inputs(t0)
            inst.exit_initialization(t0)
            inst.read_outputs(t0)
        self._transfer_all()
        if self._clocked:
            self._events(self._t0, initial=True)

    def _step_impl(self, t: float, h: float, t_next: float) -> None:
        for inst in self.instances:
            inst.write_inputs(t)
            inst.step(t, h)
            inst.read_outputs(t)
        self.values[0] = t_next
        self._transfer_all()
        self._drive(t_next)

    def _after_events(self, ticked: list[InstanceBase], t: float) -> None:
        for inst in ticked:
            inst.read_outputs(t)
        self._transfer_all()


MASTERS: dict[str, type[Master]] = {"gauss-seidel": GaussSeidel, "jacobi": Jacobi}
