# SPDX-License-Identifier: BSD-2-Clause
"""Input time series (``--input-file``): a CSV that drives inputs no connection feeds.

FMPy's convention: a ``time`` column, then one column per input, named ``<component>.<input>``
as result columns are. At each communication point the masters set every driven input to its
value at that time: linear interpolation for a continuous input, the last row at or before it for
a discrete one; before the first row the first value, after the last row the last value (a file
that does not cover the run is a ScenarioWarning, not a silent hold).

The whole file is held in memory as float64 for the run (it is read once), so it may have at most
``MAX_INPUT_BYTES``: a 1 GB file reached 6.9 GB of memory and was still being parsed after 400 s.
A CSV file is parsed by pyarrow one block at a time into arrays that grow in place: memory holds
8 bytes per value and one block of text, never the whole text nor a second copy of the values
(a 250 MiB file of 4 columns: see ``benchmarks/orchestrate_limits.py input-file``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UsageError, option
from .results import ResultFileError, read_result
from .ssp import PortRef
from .system import System

__all__ = ["MAX_INPUT_BYTES", "InputSeries", "read_inputs"]

MAX_INPUT_BYTES = 256 << 20  # about 10 million values as CSV text
BLOCK_BYTES = 1 << 20  # CSV text pyarrow parses at a time (16 MiB: 250 MB more for its read-ahead)
CHECK_ROWS = 1 << 16  # rows checked for non-finite values at a time


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


def _csv_names(path: Path) -> list[str]:
    """The column names of the CSV ``path`` (its first line, as pyarrow reads it)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        with pacsv.open_csv(path, read_options=pacsv.ReadOptions(block_size=1 << 20)) as reader:
            return list(reader.schema.names)
    except pa.ArrowException as exc:
        raise ResultFileError(f"{path}: not a result CSV ({str(exc).splitlines()[0]})") from None


def _read_csv(path: Path, names: list[str], columns: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``time`` and ``columns`` (rows x columns) of the CSV ``path`` whose columns are ``names``:
    parsed by pyarrow one block of ``BLOCK_BYTES`` at a time into arrays grown in place, so that
    memory holds the values (8 bytes each) and one block, never the whole text or a second copy."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    where = [names.index("time"), *(names.index(c) for c in columns)]
    capacity = 1 << 16
    time, values = np.empty(capacity), np.empty((capacity, len(columns)))
    n = 0
    try:
        with pacsv.open_csv(path, read_options=pacsv.ReadOptions(block_size=BLOCK_BYTES),
                            convert_options=pacsv.ConvertOptions(
                                column_types={name: pa.float64() for name in names})) as reader:
            for batch in reader:
                k = batch.num_rows
                if n + k > capacity:  # in place (realloc): no second copy of what is read
                    capacity = max(2 * capacity, n + k)
                    time.resize(capacity, refcheck=False)
                    values.resize((capacity, len(columns)), refcheck=False)
                time[n:n + k] = batch.column(where[0]).to_numpy(zero_copy_only=False)
                for j, c in enumerate(where[1:]):
                    values[n:n + k, j] = batch.column(c).to_numpy(zero_copy_only=False)
                _increasing(path, time, max(0, n - 1), n + k)
                n += k
    except pa.ArrowException as exc:
        raise ResultFileError(f"{path}: not a result CSV ({str(exc).splitlines()[0]})") from None
    time.resize(n, refcheck=False)
    values.resize((n, len(columns)), refcheck=False)
    return time, values


def _increasing(path: Path, time: np.ndarray, start: int, end: int) -> None:
    """ResultFileError naming the line where ``time[start:end]`` does not increase strictly."""
    bad = np.flatnonzero(np.diff(time[start:end]) <= 0)
    if len(bad):
        i = start + int(bad[0]) + 1
        raise ResultFileError(f"{path}: column 'time' does not increase at line {i + 2} "
                              f"(t = {float(time[i])!r} after {float(time[i - 1])!r})")


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
    data = None if path.suffix.lower() not in (".parquet", ".mat") else read_result(path)
    header = list(data.dtype.names or ()) if data is not None else _csv_names(path)
    if "time" not in header:
        raise ResultFileError(f"{path}: no 'time' column (columns: {', '.join(header)})")
    names = [n for n in header if n != "time"]
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
    if data is not None:
        time, values = data["time"].copy(), np.column_stack([data[str(p)] for p in ports])
    else:
        time, values = _read_csv(path, header, [str(p) for p in ports])
    if len(time) < 2:
        raise ResultFileError(f"{path}: needs at least two rows (has {len(time)})")
    for first in range(0, len(values), CHECK_ROWS):  # a block at a time: no mask as large as the values
        bad = np.argwhere(~np.isfinite(values[first:first + CHECK_ROWS]))
        if len(bad):
            row, column = first + int(bad[0, 0]), int(bad[0, 1])
            value = float(values[row, column])
            raise UsageError(f"{option('input_file')} {path}: '{ports[column]}' is {value!r} at "
                             f"t={float(time[row]):g} s")
    warnings = []
    if time[0] > start or time[-1] < stop:
        warnings.append(f"{option('input_file')} {path} covers t = {time[0]:g} .. {time[-1]:g} s of the "
                        f"run's {start:g} .. {stop:g} s: its first and last values are held outside")
    return InputSeries(tuple(ports), time, values, tuple(discrete)), warnings
