# SPDX-License-Identifier: BSD-2-Clause
"""The engine's C code: the plan reader and core (``plan.c``, ``core.c``) built as the compiled
executor (``executor.c``, which ``orchestrate run`` steps by default) and as the exported container's
runtime (``container.c`` with its FMI 2.0 and 3.0 APIs ``container_fmi2.c`` and ``container_fmi3.c``,
:func:`container_library`). Both are compiled with the system C compiler against the lower C layer
(``fmu_src/cbase``: the official FMI headers, ``platform.c``) on first use and kept in the cache folder
(:func:`orchestrator.fmucache.cache_folder`'s parent, ``native/``) under a digest of their sources,
flags and compiler, so a run compiles nothing once one has.

:class:`Stepper` is the executor's Python side: it binds the instances the engine made (fmpy's
library handle and instance) and runs blocks of steps in C, each row copied into the recorder's
buffer (see ``executor.c``).
"""

from __future__ import annotations

import atexit
import ctypes
import functools
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from ctypes import POINTER, c_char_p, c_double, c_int, c_int64, c_long, c_size_t, c_void_p
from pathlib import Path

import numpy as np

import fmu_src.cbase as cbase

from .. import files
from ..fmi import InstanceBase
from ..fmucache import cache_folder
from ..plan import Plan

__all__ = ["FLAGS", "FUNCTIONS", "NO_STATUS", "SOURCES", "Failure", "NativeError", "Stepper",
           "compile_library", "container_library", "executor_library", "unavailable"]

HERE = Path(__file__).resolve().parent
HEADERS = cbase.FMI_HEADERS
SOURCES = {"executor": ("executor.c", "core.c", "plan.c"),
           "container": ("container.c", "container_fmi2.c", "container_fmi3.c", "core.c", "plan.c")}
# No debug info, build id or symbols, so the bytes depend only on source, compiler and flags; no
# contraction of a * b + c into a fused multiply-add, so a connection's factor * value + offset
# rounds as Python's does in the engine's master; symbols bound inside the library, so an embedded
# FMU's fmi2* functions never resolve to the container's.
FLAGS = (*cbase.REPRODUCIBLE_FLAGS, "-fPIC", "-shared", "-fvisibility=hidden", "-ffp-contract=off",
         "-Wl,-Bsymbolic")
LIBS = ("-ldl", "-lm")
# The container for 64-bit Windows (binaries/win64/<id>.dll): mingw-w64, linked against the system's
# KERNEL32 and msvcrt.dll only, no time stamp in the PE header (the bytes depend only on sources,
# compiler and flags, as the FMUs' shim's are), no fused multiply-add (as FLAGS). Only the functions
# marked __declspec(dllexport) (the fmi2* and fmi3*) are exported.
MINGW_FLAGS = (*cbase.REPRODUCIBLE_MINGW_FLAGS, "-shared", "-ffp-contract=off")
# what a step of the executor calls, by code (core.h's enum function)
FUNCTIONS = ("fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2SetInteger", "fmi2GetInteger",
             "fmi2SetBoolean", "fmi2SetString", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
             "fmi2ExitInitializationMode",
             "fmi2Terminate", "fmi2Reset", "fmi2Instantiate", "fmi3EnterEventMode", "fmi3SetClock",
             "fmi3UpdateDiscreteStates", "fmi3EnterStepMode", "fmi3GetIntervalDecimal", "fmi3GetShiftDecimal")
# a failure's status that is no FMI status (core.h), as orchestrator/fmi.py's Instance.tick and
# core.c's fmu_status say it (tests/test_native_tables.py holds the two tables to core's)
NO_STATUS = {-2: "terminateSimulation", -3: "discreteStatesNeedUpdate after 100 calls",
             -4: "an unusable interval"}
WHY = 4096


class NativeError(RuntimeError):
    """The C code cannot be built or loaded here (no C compiler, a compiler error); the message
    says why."""


class Failure(ctypes.Structure):
    """A failed call in C (``struct failure``): component index, function code, status, time."""

    _fields_ = [("component", c_int), ("function", c_int), ("status", c_int), ("time", c_double)]


def _compiler(windows: bool = False) -> tuple[str, str]:
    """The C compiler (``windows``: the mingw-w64 cross compiler) and its version (fmu_src/cbase)."""
    try:
        if windows:
            return cbase.mingw("to build the container's binaries/win64")
        return cbase.c_compiler("to build the engine's C executor")
    except cbase.CompilerError as exc:
        raise NativeError(str(exc)) from exc


@functools.cache
def _scratch() -> Path:
    """A folder of this process for libraries when there is no cache folder (removed at exit)."""
    folder = Path(tempfile.mkdtemp(prefix="orchestrate-native-"))
    atexit.register(shutil.rmtree, folder, True)
    return folder


@functools.cache
def compile_library(kind: str, windows: bool = False) -> Path:
    """The compiled library ``kind`` (``executor`` or ``container``): from the cache folder, or
    compiled now (written under a temporary name and renamed; into a folder of this process when
    the cache's disk cannot hold it). ``windows``: a DLL for 64-bit Windows, cross-compiled with
    mingw-w64. NativeError when it cannot be built."""
    compiler, version = _compiler(windows)
    flags, libs = (MINGW_FLAGS, ()) if windows else (FLAGS, LIBS)
    digest = files.sha256("\0".join([*flags, *libs, version]).encode())
    for source in sorted({*SOURCES[kind], *(p.name for p in HERE.glob("*.h"))}):
        digest.update(source.encode() + b"\0" + (HERE / source).read_bytes())
    for header in sorted([*HEADERS.glob("*.h"), *cbase.HERE.glob("*.[ch]")]):
        digest.update(header.name.encode() + b"\0" + header.read_bytes())
    name = f"{kind}-{digest.hexdigest()[:24]}.{'dll' if windows else 'so'}"
    sources = [*(HERE / s for s in SOURCES[kind]), *(cbase.HERE / s for s in cbase.PLATFORM_SOURCES)]
    command = [compiler, *flags, f"-I{HERE}", f"-I{cbase.HERE}", f"-I{HEADERS}", *map(str, sources), *libs]
    cache = cache_folder()
    if cache is not None:
        try:
            return _build(kind, command, cache.parent / "native", name)
        except NativeError:  # a full or read-only cache disk: this process's own folder will do
            pass
    return _build(kind, command, _scratch(), name)


def _build(kind: str, command: list[str], folder: Path, name: str) -> Path:
    """``folder/name``, compiled now by ``command`` (``-o`` added) unless it is there. NativeError when
    it cannot be built."""
    target = folder / name
    if target.is_file():
        return target
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:
            built = Path(tmp) / target.name
            result = subprocess.run([*command, "-o", str(built)], capture_output=True, text=True)
            if result.returncode != 0:
                raise NativeError(f"{HERE}: {command[0]} failed:\n{result.stderr.strip()}")
            os.replace(built, target)
    except OSError as exc:
        raise NativeError(f"cannot write the compiled {kind} into {folder}: {exc}") from exc
    return target


def container_library(windows: bool = False) -> bytes:
    """The exported container's runtime (``binaries/<platform>/<id>.so``: FMI 2.0 and 3.0 APIs);
    ``windows``: ``binaries/win64/<id>.dll`` (FMI 3.0: ``x86_64-windows``), cross-compiled with
    mingw-w64."""
    return compile_library("container", windows).read_bytes()


@functools.cache
def executor_library() -> ctypes.PyDLL:
    """The compiled executor, loaded once per process. ``PyDLL``: the GIL stays held while it steps,
    which a Python-based FMU would otherwise take back at every call."""
    lib = ctypes.PyDLL(str(compile_library("executor")))
    lib.ftc_executor_open.argtypes, lib.ftc_executor_open.restype = [c_char_p, c_char_p, c_size_t], c_void_p
    lib.ftc_executor_bind.argtypes = [c_void_p, c_int, c_void_p, c_void_p, c_char_p, c_size_t]
    lib.ftc_executor_bind.restype = c_int
    lib.ftc_executor_run.argtypes = [c_void_p, POINTER(c_double), c_int64, c_long, POINTER(c_double),
                                     POINTER(c_double), POINTER(c_int), POINTER(Failure)]
    lib.ftc_executor_run.restype = c_long
    lib.ftc_executor_close.argtypes, lib.ftc_executor_close.restype = [c_void_p], None
    return lib


@functools.cache
def unavailable() -> str:
    """Why the compiled executor cannot run in this process ('' when it can)."""
    try:
        executor_library()
    except (NativeError, OSError) as exc:
        return str(exc).partition("\n")[0]
    return ""


def _pointer(array: np.ndarray | None) -> ctypes._Pointer | None:
    return None if array is None else array.ctypes.data_as(POINTER(c_double))


class Stepper:
    """The compiled executor on one run: ``plan`` and its ``instances`` (initialized by the engine,
    in plan order), bound once; :meth:`run` steps blocks of the run on the engine's value buffer."""

    def __init__(self, plan: Plan, instances: Sequence[InstanceBase]) -> None:
        self.lib = executor_library()
        why = ctypes.create_string_buffer(WHY)
        self.handle = self.lib.ftc_executor_open(plan.text().encode(), why, WHY)
        if not self.handle:
            raise NativeError(why.value.decode(errors="replace"))
        self.failure = Failure()
        self.width = len(plan.columns)
        for i, inst in enumerate(instances):
            native = inst.native()
            if native is None:
                self.close()
                raise NativeError(f"{inst.name}: the instance offers no library for the compiled executor")
            if self.lib.ftc_executor_bind(self.handle, i, *native, why, WHY) != 0:
                self.close()
                raise NativeError(f"{inst.name}: {why.value.decode(errors='replace')}")

    def run(self, values: np.ndarray, k: int, rows: np.ndarray, driven: np.ndarray | None,
            stop: ctypes.c_int) -> int:
        """Steps ``k``, ``k + 1`` ... (at most ``len(rows)``) on ``values``, each row copied into
        ``rows``, the driven inputs of row j from ``driven[j]``; returns the rows made. It stops early
        at a row that is not finite, when ``stop`` is set, or at a failed call (then ``failure``
        holds its component, function code (index into :data:`FUNCTIONS`), status and time)."""
        assert rows.flags.c_contiguous and rows.shape[1] == self.width and values.flags.c_contiguous
        made = self.lib.ftc_executor_run(self.handle, _pointer(values), k, len(rows), _pointer(rows),
                                         _pointer(driven), ctypes.byref(stop), ctypes.byref(self.failure))
        return int(made)

    def close(self) -> None:
        """Free the executor (not the instances: the engine frees them)."""
        if self.handle:
            self.lib.ftc_executor_close(self.handle)
            self.handle = None
