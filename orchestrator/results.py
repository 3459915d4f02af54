# SPDX-License-Identifier: BSD-2-Clause
"""Results: rows streamed to CSV as the run goes, and kept in memory (every row, or a bounded
preview for plotting when ``keep`` is False, so that memory does not grow with the run length).

Rows are copied into a preallocated array (cheap inside the stepping loop). When a CSV is wanted,
every ``flush_rows`` rows (``FLUSH_ROWS``; or every ``FLUSH_SECONDS`` of wall time, whichever comes first) the
checked rows are formatted and written with one ``write(2)`` to a temporary file beside the result,
renamed onto the result's name when the run ends, so that name never holds a half-written CSV.
``close()`` (called on every path, including a failure or Ctrl-C) writes what is left and renames,
so a failed run keeps every row computed before the failure; a temporary file removed while the
run writes it (``rm -r`` of the output folder) is written again from its open descriptor, its
folder made again (:meth:`Recorder.close`). A process killed outright (SIGKILL)
leaves the temporary file (``.<name>.<host>-<pid>.<random>.part``, named in the sidecar): a CSV of
every row up to the last write, at most ``flush_rows`` rows or ``FLUSH_SECONDS`` before the kill.

Floats are formatted by orjson (:func:`orchestrator.formats.csv_rows`): the shortest text that reads
back to the same double, as ``repr`` gives, at about a tenth of ``repr``'s cost (0.05 against 0.4 us
per value). ``fmpy.util.read_csv`` reads the CSV. Every ``check_rows`` rows the new rows are
checked to be finite.

Only what the file holds is formatted: the columns ``file_columns`` and, with ``interval_ns``, the
rows on the output grid ``t0 + k * interval`` (``--output-variables``, ``--no-inputs``,
``--output-interval``); the null device gets nothing at all. Formatting every row of example1's 26
columns costs 1-3 us of a 10 us step, which ``--output-interval 30`` paid in full (issue 46).
"""

from __future__ import annotations

import os
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np
from fmpy.util import read_csv

from . import files
from .errors import OrchestratorWarning, OutputError, UsageError
from .formats import NS_PER_S, binary_copy_path, csv_rows, read_table, read_tool_csv

__all__ = ["FLUSH_ROWS", "FLUSH_SECONDS", "PREVIEW_BUCKETS", "Columns", "NonFiniteError", "Recorder",
           "ResultFileError", "open_columns", "read_result", "structured"]

FLUSH_SECONDS = 1.0  # the rows computed reach the CSV at least this often (a slow run too)
FLUSH_ROWS = 208  # ... and every this many rows (whole checks of 16 rows)


def structured(data: np.ndarray, columns: Sequence[str]) -> np.ndarray:
    """View a 2-D float array as a structured array with one field per column (no copy)."""
    dtype = np.dtype([(name, np.float64) for name in columns])
    return np.ascontiguousarray(data).view(dtype).reshape(len(data))


def _read_any_csv(path: Path) -> np.ndarray:
    """Our CSV (fmpy's reader), else one another tool wrote (:func:`orchestrator.formats.read_tool_csv`)."""
    try:
        return read_csv(path)
    except (ValueError, IndexError) as exc:
        try:
            return read_tool_csv(path)
        except ValueError:
            raise exc from None


class ResultFileError(UsageError, ValueError):
    """A file given as a result is missing or is not a result CSV; the message names it."""


def read_result(path: str | os.PathLike,
                reader: Callable[[Path], np.ndarray] | None = None) -> np.ndarray:
    """Read a result CSV (``time`` first, one column per signal) with fmpy's reader (``reader``:
    another for CSV, e.g. pyarrow's for a large file); errors name the file. Time must increase
    strictly."""
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such file")
    kind = path.suffix.lower()
    try:  # .parquet and .mat: what 'run --output' writes besides CSV (orchestrator.formats)
        data = read_table(path) if kind in (".parquet", ".mat") else (reader or _read_any_csv)(path)
    except (OSError, ValueError, IndexError, KeyError, UnicodeDecodeError) as exc:
        what = kind[1:].upper() if kind in (".parquet", ".mat") else "CSV"
        raise ResultFileError(f"{path}: not a result {what} ({exc})") from exc
    names = data.dtype.names or ()
    if "time" not in names:
        raise ResultFileError(f"{path}: no 'time' column (columns: {', '.join(names)})")
    _check_time(path, data["time"])
    return data


CSV_BLOCK = 1 << 20  # CSV text parsed at a time


class Columns:
    """A result CSV parsed once, ``CSV_BLOCK`` of text at a time, into one raw float64 file per
    column in ``folder``: a column is read back alone (``columns[name]``) or in parts
    (:meth:`part`), so memory holds a column or a chunk, never the file (fmpy's reader took 4.4
    times its size). Duck-types the structured array :func:`read_result` returns where a comparison
    reads it (``dtype.names`` and ``[name]``). :func:`open_columns` makes one."""

    def __init__(self, names: Sequence[str], rows: int, folder: Path) -> None:
        self.dtype = np.dtype([(n, np.float64) for n in names])
        self.rows, self.folder = rows, folder

    def __len__(self) -> int:
        return self.rows

    def __getitem__(self, name: str) -> np.ndarray:
        names = self.dtype.names or ()
        if name not in names:
            raise KeyError(name)
        return np.fromfile(self.folder / f"{names.index(name)}.f64", dtype=np.float64)

    def part(self, name: str, start: int, count: int) -> np.ndarray:
        """Rows ``start`` to ``start + count`` of column ``name`` (fewer at the end), read alone."""
        names = self.dtype.names or ()
        if name not in names:
            raise KeyError(name)
        return np.fromfile(self.folder / f"{names.index(name)}.f64", dtype=np.float64, count=max(count, 0),
                           offset=8 * max(start, 0))


def _text_blocks(stream: BinaryIO) -> Iterator[bytes]:
    """The rest of ``stream`` in whole lines, about ``CSV_BLOCK`` bytes at a time (a longer line whole)."""
    rest = b""
    while text := stream.read(CSV_BLOCK):
        rest += text
        cut = rest.rfind(b"\n") + 1
        if cut:
            yield rest[:cut]
            rest = rest[cut:]
    if rest.strip():
        yield rest


def _parse_blocks(stream: BinaryIO, names: list[str], folder: Path) -> int:
    """The rows of ``stream`` (after its header) as numbers into ``folder``'s column files; the count.
    Each block of lines is parsed on its own by pyarrow (one thread): its streaming reader read
    ahead and kept memory that grew with the file (about 110 MiB over the interpreter's for a
    166 MB file, 4 MiB blocks 230 MiB), a block at a time holds about the same for any length."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    numbers = pacsv.ConvertOptions(column_types={name: pa.float64() for name in names})
    rows = 0
    outputs = [open(folder / f"{j}.f64", "wb") for j in range(len(names))]  # noqa: SIM115
    try:
        for block in _text_blocks(stream):
            options = pacsv.ReadOptions(column_names=names, use_threads=False, block_size=len(block) + 1)
            table = pacsv.read_csv(pa.BufferReader(block), read_options=options, convert_options=numbers)
            for j, column in enumerate(table.columns):
                column.to_numpy().tofile(outputs[j])
            rows += table.num_rows
    finally:
        for output in outputs:
            output.close()
    return rows


def open_columns(path: str | os.PathLike, folder: str | os.PathLike) -> Columns | np.ndarray:
    """The result CSV ``path`` as :class:`Columns` (its files in ``folder``, which the caller
    removes), checked as :func:`read_result` checks a result; a CSV pyarrow cannot read as
    numbers (another tool's) or another format: :func:`read_result`'s array."""
    import pyarrow as pa

    path, folder = Path(path), Path(folder)
    if path.suffix.lower() in (".parquet", ".mat") or not path.is_file():
        return read_result(path)
    with open(path, "rb") as stream:
        header = stream.readline()  # whole: a wide file (thousands of columns) streams as well
        if b'"' in header or b" " in header or not header.endswith(b"\n"):  # another tool's layout
            return read_result(path)  # (OMSimulator's: quoted names with spaces): read_tool_csv's
        try:
            names = header.decode("utf-8").rstrip("\r\n").split(",")
            if len(set(names)) != len(names):
                return read_result(path)
            rows = _parse_blocks(stream, names, folder)
        except (pa.ArrowException, UnicodeDecodeError):  # not numbers (another tool's CSV): read whole
            return read_result(path)
    columns = Columns(names, rows, folder)
    if "time" not in names:
        raise ResultFileError(f"{path}: no 'time' column (columns: {', '.join(names)})")
    if rows < 2:
        _check_time(path, columns["time"])
    for start in range(0, rows - 1, TIME_CHUNK):  # a chunk at a time, one row of overlap
        _check_time(path, columns.part("time", start, TIME_CHUNK + 1), start)
    return columns


TIME_CHUNK = 1 << 16  # rows of a column file's time checked at once


def _check_time(path: Path, time: np.ndarray, first: int = 0) -> None:
    """ResultFileError unless ``time`` (of the result ``path``; ``first``: the row it starts at)
    has two rows or more and increases strictly (naming the line where it does not)."""
    if len(time) < 2:
        raise ResultFileError(f"{path}: needs at least two rows (has {len(time)})")
    bad = np.flatnonzero(np.diff(time) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise ResultFileError(f"{path}: column 'time' does not increase at line {first + i + 2} "
                              f"(t = {float(time[i])!r} after {float(time[i - 1])!r})")


PREVIEW_BUCKETS = 2000  # keep=False: the preview holds at most two rows per bucket
PREVIEW_HEAD = 2000  # ... after at least this many first rows, kept as they are (the start of a run)


class NonFiniteError(Exception):
    """A recorded row holds a value that is not finite: row ``row`` (0-based), column ``column``.
    The rows before it are kept; it and the rows after it are dropped."""

    def __init__(self, row: int, column: int) -> None:
        super().__init__(row, column)
        self.row, self.column = row, column


class Recorder:
    """Collects rows of ``len(columns)`` floats (``rows`` expected in all) and streams them to the CSV
    ``path`` (if any). ``keep`` False (only with a path): memory holds one block of rows and a
    preview: the first ``PREVIEW_HEAD`` rows or more as they are, then at most ``2 *
    PREVIEW_BUCKETS`` rows (per bucket of consecutive rows, each column's minimum and maximum in
    the order they occur, at the bucket's first and last time), enough to plot any run length;
    ``preview`` False: the first and the last row only."""

    def __init__(self, columns: Sequence[str], rows: int, path: str | os.PathLike | None = None,
                 flush_rows: int = FLUSH_ROWS, keep: bool = True, check_rows: int = 16,
                 binary_copy: bool = False, file_columns: Sequence[int] | None = None,
                 interval_ns: int | None = None, preview: bool = True) -> None:
        self.columns = list(columns)
        # what the file holds: these columns (None: all) of the rows on the grid t0 + k * interval_ns
        every = file_columns is None or list(file_columns) == list(range(len(self.columns)))
        self._file_columns = None if every else np.asarray(file_columns, dtype=np.intp)
        self._interval_ns = interval_ns
        self._origin_ns = 0  # t0 in ns, read from the first row written
        self._sink = False  # the null device: nothing to format
        self.keep = keep or path is None
        self.count = 0  # rows recorded (all checked but the last < check_rows)
        # keep=False: a buffer of one flush (whole checks), whatever the run length; the preview
        # folds each flushed block into buckets of consecutive rows
        capacity = rows if self.keep else check_rows * max(1, -(-flush_rows // check_rows))
        self.data = np.empty((max(capacity, 1), len(self.columns)))
        self._base = 0  # row number of data[0]
        self._checked = 0
        # (rows computed, bytes, rows in the file) of the CSV up to its last whole block: one
        # attribute, stored in one step, so that an exception from a signal handler never finds them
        # disagreeing
        self._committed = (0, 0, 0)
        self._check_rows = check_rows
        self._next_check = check_rows
        self._flush_rows = flush_rows if self.keep else capacity
        self._next_flush = self._flush_rows
        self._preview: _Preview | _Ends | None = (
            None if self.keep else _Preview(max(1, -(-rows // PREVIEW_BUCKETS)), PREVIEW_HEAD) if preview
            else _Ends())
        self._fd: int | None = None  # the temporary file (or device) the CSV is written to
        self._flushed_at = time.monotonic()
        self.failed = False  # the CSV could not be written: no rows of this run are on disk
        self.path = None if path is None else Path(path)
        self.part: Path | None = None  # where the CSV is until the run ends (the path itself for a device)
        self._binary: int | None = None  # binary_copy: the rows as raw float64 (formats.binary_copy_path)
        if self.path is not None:
            self._start_writer(self.path)
            if binary_copy:
                self._open_binary(binary_copy_path(self.path))

    @property
    def saved(self) -> int:
        """The rows computed that the CSV covers: those of them on the output grid are in it (all
        sent once ``close`` returned; none if it failed)."""
        return 0 if self.failed or self.path is None else self._committed[0]

    def _start_writer(self, path: Path) -> None:
        """Create the temporary file (an unwritable folder fails here, before any step) and write the
        header. A path that exists and is not a regular file (``/dev/null``) is written in place."""
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            if path.exists() and not path.is_file():
                self.part = path
                self._fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC)
                self._sink = os.path.samefile(path, os.devnull)
            else:
                self.part = files.reserve(path)
                self._fd = os.open(self.part, os.O_RDWR | os.O_TRUNC | os.O_CLOEXEC)  # read: _rescue
        except OSError as exc:
            self.failed = True
            raise OutputError(f"{path}: {exc.strerror or exc}") from exc
        names = self.columns if self._file_columns is None else [self.columns[j] for j in self._file_columns]
        header = (",".join(names) + "\n").encode("utf-8")
        self._append(header, b"")
        self._committed = (0, len(header), 0)

    def _open_binary(self, path: Path) -> None:
        """Open the float64 copy of the rows that a conversion to another format reads (instead of
        parsing the CSV back: 0.1 s CPU for a 30 s run of example1)."""
        try:
            self._binary = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o666)
        except OSError as exc:
            self._discard()
            raise OutputError(f"{path}: {exc.strerror or exc}") from exc

    def _append(self, text: bytes, raw: bytes) -> None:
        """Append one block: ``text`` to the CSV, ``raw`` to the float64 copy. On an error (disk
        full, ...) the temporary files are removed and OutputError gives the reason."""
        assert self._fd is not None
        try:
            _write_all(self._fd, text)
            if self._binary is not None:
                _write_all(self._binary, raw)
        except OSError as exc:
            self._discard()
            raise OutputError(f"{self.path}: {exc.strerror or exc}") from exc

    def _cut(self) -> None:
        """Cut the CSV and its float64 copy back to the last committed block: an exception (a
        second Ctrl-C, the timeout's grace) between writing a block and committing it would
        otherwise have ``close`` write the block again. A device keeps what it got."""
        assert self._fd is not None
        _, size, written = self._committed
        try:
            if self.part != self.path:
                os.ftruncate(self._fd, size)
                os.lseek(self._fd, size, os.SEEK_SET)
            if self._binary is not None:
                width = self.data.shape[1] if self._file_columns is None else len(self._file_columns)
                kept = written * width * self.data.itemsize
                os.ftruncate(self._binary, kept)
                os.lseek(self._binary, kept, os.SEEK_SET)
        except OSError as exc:
            self._discard()
            raise OutputError(f"{self.path}: {exc.strerror or exc}") from exc

    def _discard(self) -> None:
        """Give the CSV up: close it and remove the temporary file (nothing of this run on disk)."""
        fd, self._fd = self._fd, None
        self.failed = True
        if fd is not None:
            os.close(fd)
        if self.part is not None and self.part != self.path:
            self.part.unlink(missing_ok=True)
        self._close_binary(remove=True)

    def _close_binary(self, remove: bool) -> None:
        binary, self._binary = self._binary, None
        if binary is not None:
            os.close(binary)
            if remove and self.path is not None:
                binary_copy_path(self.path).unlink(missing_ok=True)

    def append(self, row: np.ndarray) -> None:
        """Record one row (copied). Raises NonFiniteError (at most ``check_rows`` rows after the row that
        holds a NaN or an infinity) and OSError when the CSV cannot be written."""
        self.data[self.count - self._base] = row
        self.count += 1
        if self.count >= self._next_check:
            self.check()
            if self.count >= self._next_flush or (self._fd is not None and
                                                 time.monotonic() - self._flushed_at >= FLUSH_SECONDS):
                self.flush()

    def space(self, most: int) -> np.ndarray:
        """The buffer rows the next rows go into (at most ``most``, up to the next write of the CSV
        or the end of the buffer), for an executor that fills them in place; then :meth:`commit`."""
        end = min(self.count + most, self._base + len(self.data), max(self._next_flush, self.count + 1))
        return self.data[self.count - self._base:end - self._base]

    def commit(self, rows: int) -> None:
        """Record the first ``rows`` rows of the last :meth:`space`: checked and, when due, written
        (raises as :meth:`append` does)."""
        self.count += rows
        self.check()
        if self.count >= self._next_flush or (self._fd is not None and
                                              time.monotonic() - self._flushed_at >= FLUSH_SECONDS):
            self.flush()

    def check(self) -> None:
        """Check the rows not yet checked; at a non-finite value drop it and the rows after it and
        raise NonFiniteError."""
        block = self.data[self._checked - self._base:self.count - self._base]
        if block.size and not np.isfinite(block).all():
            bad = np.argwhere(~np.isfinite(block))
            row = int(bad[0, 0])
            columns = bad[bad[:, 0] == row, 1]
            self.count = self._checked + row
            raise NonFiniteError(self.count, int(columns[0]) if len(columns) == 1 else self._origin(columns))
        self._checked = self.count
        self._next_check = self.count + self._check_rows

    @staticmethod
    def _origin(columns: np.ndarray) -> int:
        """Of the non-finite columns of one row, the last one: outputs follow inputs, and an input
        is non-finite because an output connected to it is."""
        return int(columns[-1])

    def flush(self) -> None:
        """Write the checked rows not yet written to the CSV (and, keep=False, fold them into the
        preview and reuse the buffer)."""
        end = self._checked
        sent, size, written = self._committed
        if self._fd is not None and sent < end and not self._sink:
            block = self._selected(self.data[sent - self._base:end - self._base], sent == 0)
            if len(block):
                text = csv_rows(block)
                self._append(text, block.tobytes() if self._binary is not None else b"")
                size += len(text)
                written += len(block)
            self._flushed_at = time.monotonic()
        self._committed = (end, size, written)
        if self._preview is not None and end - self._base == len(self.data):
            self._preview.add(self.data)
            self._base = end
        self._next_flush = self._base + self._flush_rows if not self.keep else end + self._flush_rows

    def _selected(self, block: np.ndarray, first: bool) -> np.ndarray:
        """The rows and columns of ``block`` that the file holds (``first``: its first row is t0)."""
        if self._interval_ns is not None:
            ns = np.round(block[:, 0] * NS_PER_S).astype(np.int64)
            if first:
                self._origin_ns = int(ns[0])
            block = block[(ns - self._origin_ns) % self._interval_ns == 0]
        return block if self._file_columns is None else block[:, self._file_columns]

    def close(self) -> None:
        """Check and write the remaining rows, close the CSV and rename it onto the result's name
        (idempotent; also when interrupted: the rows written are kept). Raises OutputError when it
        could not be written."""
        if self._fd is None:
            return
        try:
            self._cut()
            try:
                self.check()
            except NonFiniteError:
                pass  # reported by whoever appended; the rows before it are written
            self.flush()
        finally:
            fd, self._fd = self._fd, None
            if fd is not None:  # not given up by _append
                self._finish(fd)

    def _finish(self, fd: int) -> None:
        """Close the CSV ``fd`` and rename it onto the result's name. A temporary file that was
        removed while it was written (``rm -r`` of the output folder: the writes went on into the
        unlinked file) is first written again from ``fd``, beside the result, its folder made again."""
        try:
            self._close_binary(remove=False)
            if self.part != self.path and os.fstat(fd).st_nlink == 0:
                self._rescue(fd)
        except OutputError:
            raise  # the rows are kept where it says
        except OSError as exc:
            self._discard()
            raise OutputError(f"{self.path}: {exc.strerror or exc}") from exc
        finally:
            os.close(fd)
        if self.part is not None and self.path is not None and self.part != self.path:
            try:
                os.replace(self.part, self.path)
            except OSError as exc:  # the rows are whole in the temporary file: kept there
                self.failed = True  # the result's name holds none of them
                raise OutputError(f"{self.path}: {exc.strerror or exc}; the {self._committed[0]} "
                                  f"rows written are kept in {self.part}") from exc

    def _rescue(self, fd: int) -> None:
        """The CSV ``fd`` was removed while it was written: its rows copied into a new temporary file
        beside the result (its folder made again; a warning says so), or, where that cannot be, into
        a file of the temporary folder that the OutputError raised names."""
        assert self.path is not None and self.part is not None
        rows, folder = self._committed[0], not self.path.parent.is_dir()
        what = (f"its folder {self.path.parent}" if folder
                else f"the file it was streamed to ({self.part.name})")
        try:
            self.part = files.reserve(self.path)
        except OSError as exc:
            self.part = None
            self.failed = True  # the result's name holds none of them
            handle, kept = tempfile.mkstemp(prefix=f"{self.path.stem}-", suffix=self.path.suffix or ".csv")
            with os.fdopen(handle, "wb") as target:
                _copy(fd, target.fileno())
            raise OutputError(f"{self.path}: {what} was removed during the run and cannot be made again "
                              f"({exc.strerror or exc}); the {rows} rows written are kept in {kept}"
                              ) from None
        _copy(fd, os.open(self.part, os.O_WRONLY | os.O_CLOEXEC), close=True)
        warnings.warn(f"{self.path}: {what} was removed during the run; made again, with all {rows} rows "
                      "written", OrchestratorWarning, stacklevel=2)

    def result(self) -> np.ndarray:
        """The rows recorded so far as a structured array (``time`` first); keep=False: the preview."""
        current = self.data[:self.count - self._base]
        if self._preview is None:
            return structured(current.copy(), self.columns)
        return structured(self._preview.rows(current, len(self.columns)), self.columns)


def _copy(source: int, target: int, close: bool = False) -> None:
    """Copy the whole file ``source`` (from its start) to ``target`` (closed after when ``close``)."""
    try:
        offset = 0
        while chunk := os.pread(source, 1 << 20, offset):
            _write_all(target, chunk)
            offset += len(chunk)
    finally:
        if close:
            os.close(target)


def _write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte of ``data`` is written (OSError as it raises)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class _Ends:
    """The preview of a run nobody plots: its first and last rows."""

    def __init__(self) -> None:
        self.fed = 0  # rows added
        self.first = self.last = np.empty(0)

    def add(self, block: np.ndarray) -> None:
        """Fold ``block`` (the rows after those already added) in."""
        if len(block):
            if not self.fed:
                self.first = block[0].copy()
            self.last = block[-1].copy()
            self.fed += len(block)

    def rows(self, pending: np.ndarray, ncols: int) -> np.ndarray:
        """The first and last of the rows added and then of ``pending`` (one row if that is all)."""
        count = self.fed + len(pending)
        if not count:
            return np.empty((0, ncols))
        first = self.first if self.fed else pending[0]
        last = pending[-1] if len(pending) else self.last
        return np.array([first, last][:min(count, 2)])


class _Preview:
    """A bounded preview of a streamed run, fed block by block: the first ``head`` rows as they are,
    then, per bucket of ``bucket`` consecutive rows, each column's minimum and maximum in the order
    they occur, at the bucket's first and last time (two rows). A bucket may span blocks."""

    def __init__(self, bucket: int, head: int) -> None:
        self.bucket, self.head = bucket, head
        self.parts: list[np.ndarray] = []
        self.fed = 0  # rows added
        self.open: list[np.ndarray] | None = None  # bucket under way: [lo, lo_at, hi, hi_at, times]

    def add(self, block: np.ndarray) -> None:
        """Fold ``block`` (the rows after those already added) in."""
        i = 0
        if self.fed < self.head or self.bucket == 1:
            i = len(block) if self.bucket == 1 else min(len(block), self.head - self.fed)
            self.parts.append(block[:i].copy())
        while i < len(block):
            at = (self.fed + i - self.head) % self.bucket
            if at == 0 and len(block) - i >= self.bucket:  # whole buckets at once
                n = (len(block) - i) // self.bucket * self.bucket
                self.parts.append(_extremes(block[i:i + n].reshape(-1, self.bucket, block.shape[1])))
                i += n
                continue
            take = min(len(block) - i, self.bucket - at)
            self._merge(block[i:i + take], self.fed + i)
            i += take
            if at + take == self.bucket:
                self.parts.append(self._close())
        self.fed += len(block)

    def _merge(self, chunk: np.ndarray, first: int) -> None:
        """Fold rows ``chunk`` (row ``first`` the first of them) into the bucket under way."""
        columns = np.arange(chunk.shape[1])
        lo, hi = chunk.argmin(axis=0), chunk.argmax(axis=0)
        new = [chunk[lo, columns], lo + first, chunk[hi, columns], hi + first,
               np.array([chunk[0, 0], chunk[-1, 0]])]
        if self.open is None:
            self.open = new
            return
        old = self.open
        lower, higher = new[0] < old[0], new[2] > old[2]  # ties: the earlier row, as argmin gives
        self.open = [np.where(lower, new[0], old[0]), np.where(lower, new[1], old[1]),
                     np.where(higher, new[2], old[2]), np.where(higher, new[3], old[3]),
                     np.array([old[4][0], new[4][1]])]

    def _close(self) -> np.ndarray:
        """The two rows of the bucket under way (which ends)."""
        assert self.open is not None
        lo, lo_at, hi, hi_at, times = self.open
        self.open = None
        first = lo_at <= hi_at
        a, z = np.where(first, lo, hi), np.where(first, hi, lo)
        a[0], z[0] = times
        return np.stack([a, z])

    def rows(self, pending: np.ndarray, ncols: int) -> np.ndarray:
        """The preview of every row added and then of ``pending`` (not added: the state is kept)."""
        saved = list(self.parts), self.fed, self.open
        self.add(pending)
        parts = self.parts + ([self._close()] if self.open is not None else [])
        self.parts, self.fed, self.open = saved
        return np.concatenate(parts) if parts else np.empty((0, ncols))


def _extremes(buckets: np.ndarray) -> np.ndarray:
    """Two rows per bucket (``buckets``: bucket, row, column): each column's extremes in the order
    they occur, time set to the bucket's first and last."""
    lo, hi = buckets.argmin(axis=1), buckets.argmax(axis=1)
    earlier, later = np.minimum(lo, hi), np.maximum(lo, hi)
    a = np.take_along_axis(buckets, earlier[:, None, :], axis=1)[:, 0]
    z = np.take_along_axis(buckets, later[:, None, :], axis=1)[:, 0]
    a[:, 0], z[:, 0] = buckets[:, 0, 0], buckets[:, -1, 0]
    return np.stack([a, z], axis=1).reshape(-1, buckets.shape[2])
