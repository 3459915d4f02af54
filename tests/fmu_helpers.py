# SPDX-License-Identifier: BSD-2-Clause
"""Helpers for the FMU tests: drive one FMU directly through fmpy's FMI 2.0 API (exact input
values and step times, state get/set). The FMUs come from the session fixture ``fmus``."""

from __future__ import annotations

import ctypes
import importlib.util
import math
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from types import FrameType, ModuleType
from typing import Any

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from scipy.integrate import solve_ivp

from fmu_src.toolchain.build import EXTENSIONS, FMU_SCRIPTS, REPO_ROOT, compile_extension
from fmu_src.toolchain.runtime import ensure_runtime

MODELS = tuple(FMU_SCRIPTS)
# fmpy.extract alone leaves each FMU (about 80 MB with its runtimes) in TMPDIR for ever: the tests
# extract each FMU once per process into this folder, which is removed when the process exits.
_UNZIP_ROOT = tempfile.TemporaryDirectory(prefix="ftc-tests-")
_extracted: dict[Path, str] = {}


def unzipped(path: Path) -> str:
    """The FMU at ``path`` extracted once per test process, in a folder removed at exit."""
    if path not in _extracted:
        _extracted[path] = extract(str(path), unzipdir=f"{_UNZIP_ROOT.name}/{len(_extracted)}")
    return _extracted[path]


def compiled_extension(name: str, where: Path) -> ModuleType:
    """The C extension module ``name`` (a key of fmu_src.toolchain.build.EXTENSIONS) compiled into
    ``where`` as the FMU build compiles it, and loaded into this process (not into sys.modules)."""
    source = REPO_ROOT / EXTENSIONS[name]
    path = where / f"{source.stem}.abi3.so"
    path.write_bytes(compile_extension(source, ensure_runtime(), where))
    spec = importlib.util.spec_from_file_location(source.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module



class Frames:
    """The Python functions entered while active (``sys.setprofile``), by name: those whose file
    name contains ``part`` (e.g. ``/_ftc_``: the code an FMU bundles, from whichever unpacked copy
    this process imported it first), or every one but this module's."""

    def __init__(self, part: str | None = None) -> None:
        self.part = part
        self.entered: list[str] = []

    def _profile(self, frame: FrameType, event: str, arg: object) -> None:
        code = frame.f_code
        if event != "call" or code is Frames.__exit__.__code__ or code.co_filename == __file__:
            return  # this module's own frames (shim_calls' stand-ins for the shim) are not the model's
        if self.part is None or self.part in code.co_filename:
            self.entered.append(code.co_name)

    def __enter__(self) -> Frames:
        sys.setprofile(self._profile)
        return self

    def __exit__(self, *exc: object) -> None:
        sys.setprofile(None)


# A model's __dict__ values compared by their repr (bit-exact floats, nan and -0.0 included; bools are
# ints); the rest (pythonfmu's machinery, fmu_support's tables, laws, closures) are each slave's own.
PLAIN = (float, int, str, tuple, frozenset, type(None))


class Real(float):
    """A float of another type (as numpy's float64): the compiled calls hand it to Python."""


class DirectCalls(ctypes.Structure):
    """controller/direct_calls.h's struct: a model extension's C entries, called through ctypes as
    the shim calls them (the GIL held; an exception they set is raised here)."""

    _fields_ = [("version", ctypes.c_int),
                ("step", ctypes.PYFUNCTYPE(ctypes.c_int, ctypes.py_object, ctypes.c_double, ctypes.c_double)),
                ("refresh", ctypes.PYFUNCTYPE(ctypes.c_int, ctypes.py_object))]


_CAPSULE_POINTER = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.py_object, ctypes.c_char_p)(
    ("PyCapsule_GetPointer", ctypes.pythonapi))


def direct_calls(capsule: object) -> DirectCalls:
    """The C entries in a model extension's capsule (named as the shim asks for it)."""
    return DirectCalls.from_address(_CAPSULE_POINTER(capsule, b"ftc_direct_calls"))


def handed(slave: Any) -> tuple[Any, Any, Any, Any]:
    """What fmu_support hands the shim for the model object ``slave``: the step and refresh
    callables, the capsule of their C entries and the binding those take (None, None: none)."""
    binding = slave._fmu_direct_binding()
    return binding[2], binding[3], binding[10], binding[11]


def shim_calls(slave: Any) -> tuple[Callable[..., Any], Callable[..., Any]]:
    """The step and refresh of the model object ``slave`` as the FMU's shim makes them
    (cosimulation.c): the model's C entries first, where it has them (1: done; an exception set:
    raised), and the callables fmu_support hands over where those answer 0 (not the usual path)."""
    step, refresh, capsule, model = handed(slave)
    if capsule is None:
        return step, refresh
    entries = direct_calls(capsule)
    assert entries.version == 1

    def shim_step(t: float, h: float) -> Any:
        return True if entries.step(model, t, h) == 1 else step(t, h)

    def shim_refresh() -> None:
        if entries.refresh(model) != 1:
            refresh()

    return shim_step, shim_refresh


def plain(slave: Any) -> dict[str, str]:
    """A model object's simulation entries, each as its repr, and its log queue's messages: what a
    compiled call and the Python method it stands for must leave alike."""
    entries = {key: repr(value) for key, value in vars(slave).items() if isinstance(value, PLAIN)}
    entries["messages"] = repr([str(message) for message in slave.log_queue])
    return entries


def outcome(call: Callable[..., Any], *args: Any) -> Any:
    """A call's result, or its exception's type and message."""
    try:
        return call(*args)
    except Exception as error:  # noqa: BLE001 - any exception must be the Python code's
        return type(error).__name__, str(error)


class Slave:
    """One FMU instance driven by name: ``set``/``get`` of variables, ``step`` from time t."""

    def __init__(self, path: Path, instance_name: str) -> None:
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=unzipped(path),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=instance_name,
        )
        self.fmu.instantiate()

    def set(self, **values: float) -> None:
        for name, value in values.items():
            if self.types[name] == "Integer":
                self.fmu.setInteger([self.vr[name]], [int(value)])
            else:
                self.fmu.setReal([self.vr[name]], [float(value)])

    def get(self, *names: str) -> list[float]:
        return [
            self.fmu.getInteger([self.vr[n]])[0]
            if self.types[n] == "Integer"
            else self.fmu.getReal([self.vr[n]])[0]
            for n in names
        ]

    def initialize(self, start_time: float = 0.0, **parameters: float) -> None:
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()
        self.set(**parameters)
        self.fmu.exitInitializationMode()

    def step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)


@contextmanager
def open_slaves(paths: Mapping[str, Path]) -> Iterator[dict[str, Slave]]:
    """Instantiate several FMUs (instance name -> FMU path); terminated and freed on every path."""
    with ExitStack() as stack:
        slaves = {}
        for name, path in paths.items():
            slave = Slave(path, name)
            stack.callback(slave.fmu.freeInstance)
            slaves[name] = slave
        yield slaves


@contextmanager
def open_slave(path: Path, name: str = "instance") -> Iterator[Slave]:
    """One FMU instance, freed on every path."""
    slave = Slave(path, name)
    try:
        yield slave
    finally:
        slave.fmu.freeInstance()


def solve_held(
    rhs: Callable[..., Sequence[float]], t0: float, y0: Sequence[float], inputs: Sequence[float], h: float
) -> np.ndarray:
    """The oracle: solve_ivp (DOP853, rtol 1e-10) interval by interval with input k held on
    [t0 + k h, t0 + (k + 1) h]; returns the states at the end of every interval."""
    y = np.asarray(y0, dtype=float)
    out = np.empty((len(inputs), len(y)))
    for k, u in enumerate(inputs):
        ta, tb = t0 + k * h, t0 + (k + 1) * h
        sol = solve_ivp(lambda t, s, u=u: rhs(t, s, u), (ta, tb), y, method="DOP853", rtol=1e-10, atol=1e-13)
        y = sol.y[:, -1]
        out[k] = y
    return out


def reference_formula(
    t: float, amplitude: float, omega: float, phase: float, offset: float
) -> tuple[float, ...]:
    """yd, yd', yd'' of amplitude sin(omega t + phase) + offset, written out independently."""
    angle = omega * t + phase
    return (
        amplitude * math.sin(angle) + offset,
        amplitude * omega * math.cos(angle),
        -amplitude * omega**2 * math.sin(angle),
    )


# The actuator of SPEC section 2, written out independently of fmu_src.models.
def dead_zone_formula(v: float, p: dict) -> float:
    """u(v) of SPEC section 2, written out."""
    if v >= p["b_r"]:
        return p["m_r"] * (v - p["b_r"])
    if v <= -p["b_l"]:
        return p["m_l"] * (v + p["b_l"])
    return 0.0


def uf_formula(t: float, v: float, x1: float, x2: float, p: dict) -> float:
    if t < p["t_fault"]:
        return v
    K = p["K_inf"] + p["K_amp"] * math.exp(-p["K_rate"] * t)
    return K * dead_zone_formula(v, p) + p["L_gain"] * x2 * math.cos(x1) ** 2 + p["L_bias"]


# The plant equations of SPEC section 3, written out independently of fmu_src.models.
def example1(t: float, s: Sequence[float], uf: float) -> list[float]:
    x1, x2, z = s
    return [
        (2 + math.sin(x1)) * x2 + 0.1 * math.sin(x1 * x2) + z * math.sin(x1**2),
        (2 + math.cos(x1 * x2)) * uf + 0.5 * math.sin(x1**2 * x2**2) + x1**2 * z,
        -z - x1**2 + 0.5,
    ]


def pendulum(
    t: float, s: Sequence[float], uf: float, M=0.25, L=4.0, B=0.25, g=10.0, d1=0.2, d2=0.3
) -> list[float]:
    x1, x2, z = s
    return [
        x2 + z * x1 + d1 * math.sin(t),
        uf / (M * L) - (g / L + B / M) * math.sin(x1 * x2) + z * x2 * math.sin(x1) + d2 * math.cos(t),
        -2 * z + 0.25 * x1**2,
    ]


def libcosim_execution(step: float) -> Any:
    """A libcosim execution with a fixed step (given in s; libcosim counts integer ns), quiet logs."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    log_output_level(CosimLogLevel.WARNING)
    return CosimExecution.from_step_size(step_size=round(step * 1e9))


def libcosim_add(execution: Any, path: Path, name: str) -> tuple[int, dict[str, int]]:
    """Add an FMU to a libcosim execution; returns its index and variable name -> reference."""
    from libcosimpy.CosimSlave import CosimLocalSlave

    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(path), instance_name=name))
    assert index >= 0, f"libcosim could not load {path}"
    return index, {v.name.decode(): v.reference for v in execution.slave_variables(index)}
