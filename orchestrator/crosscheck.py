"""Run the same ``.ssp`` in libcosim (libcosimpy) and return results shaped like ours.

Used by the tests (``jacobi`` must equal libcosim) and the benchmark. libcosimpy is a test
dependency, imported only when this is called.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from ctypes import POINTER, c_double, c_int, c_int64, c_size_t, c_uint32

import numpy as np

from .fmi import interpreter_guard
from .master import NS_PER_S
from .results import structured

__all__ = ["LibcosimError", "run_libcosim"]


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
    with interpreter_guard():
        return _run_libcosim(ssp, stop_time, columns)


def _run_libcosim(ssp: str | os.PathLike, stop_time: float,
                  columns: Sequence[str]) -> tuple[np.ndarray, dict[str, float]]:
    """Body of run_libcosim; the execution (and its FMUs) is freed before returning."""
    import time

    from libcosimpy import CosimLogging
    from libcosimpy._internal import libcosimc, wrap_function
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    CosimLogging.log_output_level(CosimLogging.CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(ssp))
    names = [c for c in columns if c != "time"]
    refs = []
    for column in names:
        component, variable = column.split(".", 1)
        index = execution.slave_index_from_instance_name(component)
        vr = next(v.reference for v in execution.slave_variables(index) if v.name.decode() == variable)
        refs.append((index, vr))
    capacity = int(round(stop_time * 1e4)) + 10  # generous: at least one sample per 0.1 ms
    observer = CosimObserver.create_time_series(buffer_size=capacity)
    execution.add_observer(observer)
    for index, vr in refs:
        observer.start_time_series(index, vr, CosimVariableType.REAL)
    wall, cpu = time.perf_counter(), time.process_time()
    ok = execution.simulate_until(round(stop_time * NS_PER_S))
    timing = {"wall": time.perf_counter() - wall, "cpu": time.process_time() - cpu}

    samples = wrap_function(lib=libcosimc(), funcname="cosim_observer_slave_get_real_samples",
                            argtypes=[POINTER(CosimObserver), c_int, c_uint32, c_int64, c_size_t,
                                      POINTER(c_double), POINTER(c_int64), POINTER(c_int64)],
                            restype=c_int64)
    observer_ptr = observer._CosimObserver__ptr
    data, times = [], None
    for index, vr in refs:
        values, steps, points = (c_double * capacity)(), (c_int64 * capacity)(), (c_int64 * capacity)()
        n = samples(observer_ptr, index, vr, 0, capacity, values, steps, points)
        if n < 0:
            raise RuntimeError(f"libcosim returned no samples for slave {index}, reference {vr}")
        if times is None:
            times = np.array(points[:n], dtype=np.int64) / NS_PER_S
        data.append(np.array(values[:n]))
    del execution, observer  # frees the FMUs inside interpreter_guard
    n = min(len(d) for d in data)
    result = structured(np.column_stack([times[:n]] + [d[:n] for d in data]), ["time"] + names)
    if not ok:
        raise LibcosimError(f"libcosim failed to simulate {ssp} (after {n} samples)", result)
    return result, timing
