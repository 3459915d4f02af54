# SPDX-License-Identifier: BSD-2-Clause
"""libcosim through libcosimpy: runs a ``.ssp`` in this process and returns results shaped like ours.

libcosim's fixed-step algorithm delays every connection by one communication step (our ``jacobi``
master is that algorithm). It reads the step from the ``osp:FixedStepAlgorithm`` annotation and the
first parameter binding of each component. libcosimpy is a test dependency, imported only when
a run is asked for. pythonfmu FMUs run in this interpreter: every run is inside
:func:`~orchestrator.fmi.interpreter_guard`.
"""

from __future__ import annotations

import importlib.util
import os
import time
from collections.abc import Sequence
from ctypes import POINTER, c_double, c_int, c_int64, c_size_t, c_uint32
from pathlib import Path

import numpy as np

from ..fmi import interpreter_guard
from ..master import NS_PER_S
from ..results import structured
from .tools import Scenario, Tolerance, Tool, ToolRun, empty_result

__all__ = ["LibcosimError", "LibcosimTool", "run_libcosim"]


class LibcosimError(RuntimeError):
    """libcosim stopped before the stop time; ``result`` holds the samples recorded until then."""

    def __init__(self, message: str, result: np.ndarray) -> None:
        super().__init__(message)
        self.result = result


def run_libcosim(ssp: str | os.PathLike, stop_time: float,
                 columns: Sequence[str]) -> tuple[np.ndarray, dict[str, float]]:
    """Simulate ``ssp`` with libcosim up to ``stop_time`` recording ``columns`` (``component.variable``)
    with a time-series observer. Step and parameter sets come from the SSD, as libcosim reads them.

    Returns the structured result (``time`` first, one row per communication point including t0) and
    the wall and CPU seconds of the simulation proper (``simulate_until``) as ``{"wall": .., "cpu": ..}``.
    Raises LibcosimError (with the samples so far) if libcosim stops early.
    """
    result, timing, _, ok = _simulate(ssp, stop_time, columns, ())
    if not ok:
        raise LibcosimError(f"libcosim failed to simulate {ssp} (after {len(result)} samples)", result)
    return result, timing


def _simulate(ssp: str | os.PathLike, stop_time: float, columns: Sequence[str], parameters: Sequence[str]
              ) -> tuple[np.ndarray, dict[str, float], dict[str, float], bool]:
    """One libcosim run: (result, timing, parameter values read back after the run, success)."""
    with interpreter_guard():
        return _run(ssp, stop_time, columns, parameters)


def _run(ssp: str | os.PathLike, stop_time: float, columns: Sequence[str], parameters: Sequence[str]
         ) -> tuple[np.ndarray, dict[str, float], dict[str, float], bool]:
    """Body of _simulate; the execution (and its FMUs) is freed before returning."""
    from libcosimpy import CosimLogging
    from libcosimpy._internal import libcosimc, wrap_function
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(ssp))
    wanted = [c for c in columns if c != "time"] + list(parameters)
    known: dict[str, tuple[int, int, int]] = {}  # component.variable -> slave index, reference, type
    for component in {c.split(".", 1)[0] for c in wanted}:
        index = execution.slave_index_from_instance_name(component)
        for v in execution.slave_variables(index):
            known[f"{component}.{v.name.decode()}"] = (index, v.reference, v.type)

    refs = [known[c][:2] for c in columns if c != "time"]
    names = [c for c in columns if c != "time"]
    capacity = int(round(stop_time * 1e4)) + 10  # generous: at least one sample per 0.1 ms
    observer = CosimObserver.create_time_series(buffer_size=capacity)
    last = CosimObserver.create_last_value()
    execution.add_observer(observer)
    execution.add_observer(last)
    for index, vr in refs:
        observer.start_time_series(index, vr, CosimVariableType.REAL)
    wall, cpu = time.perf_counter(), time.process_time()
    ok = execution.simulate_until(round(stop_time * NS_PER_S))
    timing = {"wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu}

    values_read = {}
    for column in parameters:
        index, vr, type_ = known[column]
        if type_ == CosimVariableType.REAL.value:
            values_read[column] = float(last.last_real_values(index, [vr])[0])
        elif type_ == CosimVariableType.INTEGER.value:
            values_read[column] = float(last.last_integer_values(index, [vr])[0])
        elif type_ == CosimVariableType.BOOLEAN.value:
            values_read[column] = float(last.last_boolean_values(index, [vr])[0])

    samples = wrap_function(lib=libcosimc(), funcname="cosim_observer_slave_get_real_samples",
                            argtypes=[POINTER(CosimObserver), c_int, c_uint32, c_int64, c_size_t,
                                      POINTER(c_double), POINTER(c_int64), POINTER(c_int64)],
                            restype=c_int64)
    observer_ptr = observer._CosimObserver__ptr
    data, times = [], np.empty(0)
    for index, vr in refs:
        values, steps, points = (c_double * capacity)(), (c_int64 * capacity)(), (c_int64 * capacity)()
        n = samples(observer_ptr, index, vr, 0, capacity, values, steps, points)
        if n < 0:
            raise RuntimeError(f"libcosim returned no samples for slave {index}, reference {vr}")
        if not len(times):
            times = np.array(points[:n], dtype=np.int64) / NS_PER_S
        data.append(np.array(values[:n]))
    del execution, observer, last  # frees the FMUs inside interpreter_guard
    n = min(len(d) for d in data)
    result = structured(np.column_stack([times[:n]] + [d[:n] for d in data]), ["time"] + names)
    return result, timing, values_read, ok


class LibcosimTool(Tool):
    """libcosim 0.11 through libcosimpy (in this process); Jacobi-like: one step of delay per
    connection."""

    key = "libcosim"
    title = "libcosim 0.11 (libcosimpy)"
    delayed = True
    tolerance = Tolerance(1e-12, 1e-12, "the same algorithm as `jacobi`, same FMUs in the same process: "
                          "equal to the last bit (measured 0)")

    def missing(self) -> str | None:
        if importlib.util.find_spec("libcosimpy") is None:
            return "libcosimpy is not installed (pip install libcosimpy)"
        return None

    def run(self, scenario: Scenario, workdir: Path) -> ToolRun:
        columns = ["time", *scenario.outputs]
        try:
            result, timing, values, ok = _simulate(scenario.path, scenario.stop, columns,
                                                   list(scenario.parameters))
        except Exception as exc:  # noqa: BLE001 -- any failure of the tool is a result of the check
            return ToolRun(empty_result(columns), 0.0, f"libcosim: {type(exc).__name__}: {exc}")
        error = None if ok else f"libcosim stopped at t = {result['time'][-1]:g} s (simulate_until failed)"
        return ToolRun(result, timing["wall"], error, values)
