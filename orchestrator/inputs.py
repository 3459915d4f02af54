# SPDX-License-Identifier: BSD-2-Clause
"""Input time series (``--input-file``): a CSV that drives inputs no connection feeds.

FMPy's convention: a ``time`` column, then one column per input, named ``<component>.<input>``
as result columns are. At each communication point the masters set every driven input to its
value at that time: linear interpolation for a continuous input, the last row at or before it for
a discrete one; before the first row the first value, after the last row the last value (a file
that does not cover the run is a ScenarioWarning, not a silent hold).

The whole file is held in memory as float64 for the run (it is read once), so it may have at most
``MAX_INPUT_BYTES``: a 1 GB file reached 6.9 GB of memory and was still being parsed after 400 s.
CSV files are parsed by pyarrow (about twice the file size while reading).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UsageError, option
from .results import read_result
from .ssp import PortRef
from .system import System

__all__ = ["MAX_INPUT_BYTES", "InputSeries", "read_inputs"]

MAX_INPUT_BYTES = 256 << 20  # about 10 million values as CSV text


@dataclass(frozen=True)
class InputSeries:
    """The driven inputs ``ports``, the file's ``time`` and ``values`` (one column per port), and
    which ports hold their value between rows (``discrete``)."""

    ports: tuple[PortRef, ...]
    time: np.ndarray
    values: np.ndarray
    discrete: tuple[bool, ...]

    def at(self, t: float) -> np.ndarray:
        """Every driven input's value at time ``t``."""
        return self.table(np.array([t]))[0]

    def table(self, times: np.ndarray) -> np.ndarray:
        """Every driven input's value at each of ``times``: one row per time (what the compiled
        executor is handed for a block of steps; :meth:`at` is its row of one time)."""
        rows = np.maximum(0, np.searchsorted(self.time, times, side="right") - 1)
        out = self.values[rows]
        for j, held in enumerate(self.discrete):
            if not held:
                out[:, j] = np.interp(times, self.time, self.values[:, j])
        return out


def _read_csv(path: Path) -> np.ndarray:
    """A CSV of numbers parsed by pyarrow (fmpy's reader needs about 7 times the file's size)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        table = pacsv.read_csv(path)
    except pa.ArrowException as exc:
        raise ValueError(str(exc).splitlines()[0]) from None
    data = np.empty(table.num_rows, dtype=[(n, np.float64) for n in table.column_names])
    for name in table.column_names:
        column = table[name]
        if not (pa.types.is_integer(column.type) or pa.types.is_floating(column.type)):
            raise ValueError(f"column '{name}' is not numbers ({column.type})")
        data[name] = column.to_numpy()
    return data


def read_inputs(path: str | os.PathLike, system: System, start: float,
                stop: float) -> tuple[InputSeries, list[str]]:
    """Read an input file for ``system``: UsageError naming a column that is not an input no
    connection feeds (with the inputs that are), a non-Real input or a non-finite value; the
    warnings (the file does not cover ``start`` .. ``stop``)."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise UsageError(f"{option('input_file')} {path}: {exc.strerror or exc}") from None
    if size > MAX_INPUT_BYTES:
        raise UsageError(f"{option('input_file')} {path}: {size / (1 << 20):.0f} MiB, more than an input "
                         f"file may have ({MAX_INPUT_BYTES >> 20} MiB, held in memory for the run): thin it "
                         "out (the inputs are interpolated between its rows)")
    data = read_result(path, reader=_read_csv)
    names = [n for n in data.dtype.names or () if n != "time"]
    free = {str(PortRef(c.name, i)): (c, PortRef(c.name, i)) for c in system.components.values()
            for i in c.inputs if PortRef(c.name, i) not in system.links}
    ports, discrete, problems = [], [], []
    for name in names:
        found = free.get(name)
        if found is None:
            fed = system.port(name) if "." in name else None
            why = (f"fed by {system.links[fed].start}" if fed is not None and fed in system.links
                   else "not a Real input of the scenario")
            problems.append(f"'{name}' is {why}")
            continue
        comp, port = found
        ports.append(port)
        discrete.append(comp.variables[port.connector].variability == "discrete")
    if problems:
        inputs = ", ".join(free) or "none"
        raise UsageError(f"{option('input_file')} {path}: {'; '.join(problems)} "
                         f"(inputs it can drive: {inputs})")
    if not ports:
        raise UsageError(f"{option('input_file')} {path}: no input column (inputs it can drive: "
                         f"{', '.join(free) or 'none'})")
    values = np.column_stack([np.asarray(data[str(p)], dtype=float) for p in ports])
    if not np.isfinite(values).all():
        row, column = np.argwhere(~np.isfinite(values))[0]
        raise UsageError(f"{option('input_file')} {path}: '{ports[column]}' is {values[row, column]!r} at "
                         f"t={float(data['time'][row]):g} s")
    time = np.asarray(data["time"], dtype=float)
    warnings = []
    if time[0] > start or time[-1] < stop:
        warnings.append(f"{option('input_file')} {path} covers t = {time[0]:g} .. {time[-1]:g} s of the "
                        f"run's {start:g} .. {stop:g} s: its first and last values are held outside")
    return InputSeries(tuple(ports), time, values, tuple(discrete)), warnings
