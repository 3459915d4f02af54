"""Results: rows streamed to CSV as the run goes, and kept in memory (every row, or a bounded
preview for plotting when ``keep`` is False, so that memory does not grow with the run length).

Rows are copied into a preallocated array (cheap inside the stepping loop). When a CSV is wanted,
blocks of ``flush_rows`` raw rows go through a pipe to a child process
(``orchestrator._csvwriter``) that formats and flushes them: float formatting costs about 0.5 us
per value in Python and would otherwise dominate the master's overhead. The writer writes a
temporary file beside the result and renames it when the run ends, so the result's name never
holds a half-written CSV. ``close()`` (called on every path, including a failure or Ctrl-C) sends
what is left and waits for the writer, so a failed run keeps every row computed before the failure;
if the parent process itself dies, the CSV still holds every block sent. Floats are written with
``repr`` (shortest exact round trip), so the CSV reproduces the in-memory values bit for bit;
``fmpy.util.read_csv`` reads it. Every ``check_rows`` rows the new rows are checked to be finite.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from fmpy.util import read_csv

from . import files
from .errors import UsageError
from .formats import read_table, read_tool_csv

__all__ = ["PREVIEW_BUCKETS", "NonFiniteError", "Recorder", "ResultFileError", "read_result", "structured"]


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


def read_result(path: str | os.PathLike) -> np.ndarray:
    """Read a result CSV (``time`` first, one column per signal) with fmpy's reader; errors name the
    file. Time must increase strictly."""
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such file")
    kind = path.suffix.lower()
    try:  # .parquet and .mat: what 'run --output' writes besides CSV (orchestrator.formats)
        data = read_table(path) if kind in (".parquet", ".mat") else _read_any_csv(path)
    except (OSError, ValueError, IndexError, KeyError, UnicodeDecodeError) as exc:
        what = kind[1:].upper() if kind in (".parquet", ".mat") else "CSV"
        raise ResultFileError(f"{path}: not a result {what} ({exc})") from exc
    names = data.dtype.names or ()
    if "time" not in names:
        raise ResultFileError(f"{path}: no 'time' column (columns: {', '.join(names)})")
    if len(data) < 2:
        raise ResultFileError(f"{path}: needs at least two rows (has {len(data)})")
    bad = np.flatnonzero(np.diff(data["time"]) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        raise ResultFileError(f"{path}: column 'time' does not increase at line {i + 2} "
                              f"(t = {float(data['time'][i])!r} after {float(data['time'][i - 1])!r})")
    return data


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
    the order they occur, at the bucket's first and last time), enough to plot any run length."""

    def __init__(self, columns: Sequence[str], rows: int, path: str | os.PathLike | None = None,
                 flush_rows: int = 200, keep: bool = True, check_rows: int = 16) -> None:
        self.columns = list(columns)
        self.keep = keep or path is None
        self.count = 0  # rows recorded (all checked but the last < check_rows)
        self.bucket = 1 if self.keep else max(1, -(-rows // PREVIEW_BUCKETS))
        unit = math.lcm(self.bucket, check_rows)  # the buffer fills up exactly at a check
        capacity = rows if self.keep else unit * max(1, -(-flush_rows // unit))
        self.data = np.empty((max(capacity, 1), len(self.columns)))
        self._base = 0  # row number of data[0]
        self._checked = 0
        self._sent = 0
        self._check_rows = check_rows
        self._next_check = check_rows
        self._flush_rows = flush_rows if self.keep else capacity
        self._head = capacity * -(-PREVIEW_HEAD // capacity)  # rows before it are previewed as they are
        self._next_flush = self._flush_rows
        self._preview: list[np.ndarray] = []
        self._writer: subprocess.Popen | None = None
        self.path = None if path is None else Path(path)
        if self.path is not None:
            self._writer = self._start_writer(self.path)

    def _start_writer(self, path: Path) -> subprocess.Popen:
        """Create the temporary file (an unwritable folder fails here, in this process, before any
        step) and start the writer. A path that exists and is not a regular file (``/dev/null``) is
        written in place."""
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.exists() and not path.is_file():
            part = path
            path.open("w").close()
        else:
            part = files.reserve(path)
        self._part = part
        writer = subprocess.Popen(
            [sys.executable, "-m", "orchestrator._csvwriter", str(part), str(path.resolve()),
             str(len(self.columns))],
            stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        self._send(writer, (",".join(self.columns) + "\n").encode("utf-8"))
        return writer

    def _send(self, writer: subprocess.Popen, data: bytes) -> None:
        """Write to the writer; when it has died (disk full, ...) raise OSError with its reason."""
        assert writer.stdin is not None  # a pipe (_start_writer)
        try:
            writer.stdin.write(data)
            writer.stdin.flush()
        except OSError:
            self._writer = None
            raise self._failure(writer) from None

    def _failure(self, writer: subprocess.Popen) -> OSError:
        assert writer.stdin is not None and writer.stderr is not None  # pipes (_start_writer)
        try:
            writer.stdin.close()
        except OSError:
            pass
        writer.wait()
        reason = writer.stderr.read().decode("utf-8", "replace").strip()
        writer.stderr.close()
        return OSError(f"{self.path}: {reason or f'the CSV writer failed (exit status {writer.returncode})'}")

    def append(self, row: np.ndarray) -> None:
        """Record one row (copied). Raises NonFiniteError (at most ``check_rows`` rows after the row that
        holds a NaN or an infinity) and OSError when the CSV cannot be written."""
        self.data[self.count - self._base] = row
        self.count += 1
        if self.count >= self._next_check:
            self.check()
            if self.count >= self._next_flush:
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
        """Send the checked rows not yet sent to the CSV writer (and, keep=False, fold them into the
        preview and reuse the buffer)."""
        end = self._checked
        if self._writer is not None and self._sent < end:
            self._send(self._writer, self.data[self._sent - self._base:end - self._base].tobytes())
        self._sent = end
        if not self.keep and end - self._base == len(self.data):
            self._preview.append(self._fold(self.data, self._base))
            self._base = end
        self._next_flush = self._base + self._flush_rows if not self.keep else end + self._flush_rows

    def _fold(self, block: np.ndarray, first: int) -> np.ndarray:
        """Two rows per bucket of ``block`` (whose first row is row ``first``): each column's extremes
        in the order they occur; a copy of it when it lies in the head of the run."""
        if self.bucket == 1 or first < self._head:
            return block.copy()
        n = len(block) // self.bucket * self.bucket
        parts = [block[:n].reshape(-1, self.bucket, block.shape[1])]
        if n < len(block):
            parts.append(block[n:][None])
        rows = []
        for b in parts:
            lo, hi = b.argmin(axis=1), b.argmax(axis=1)
            earlier, later = np.minimum(lo, hi), np.maximum(lo, hi)
            a = np.take_along_axis(b, earlier[:, None, :], axis=1)[:, 0]
            z = np.take_along_axis(b, later[:, None, :], axis=1)[:, 0]
            a[:, 0], z[:, 0] = b[:, 0, 0], b[:, -1, 0]
            rows.append(np.stack([a, z], axis=1).reshape(-1, block.shape[1]))
        return np.concatenate(rows)

    def close(self) -> None:
        """Check and send the remaining rows and wait until the CSV is complete and in place
        (idempotent). Raises OSError when it could not be written."""
        writer = self._writer
        if writer is None:
            return
        try:
            try:
                self.check()
            except NonFiniteError:
                pass  # reported by whoever appended; the rows before it are sent
            self.flush()
        finally:
            self._writer = None
            assert writer.stdin is not None and writer.stderr is not None  # pipes (_start_writer)
            try:
                writer.stdin.close()
            except OSError:
                pass
            if writer.wait() != 0:
                raise self._failure(writer)
            writer.stderr.close()

    def result(self) -> np.ndarray:
        """The rows recorded so far as a structured array (``time`` first); keep=False: the preview."""
        current = self.data[:self.count - self._base]
        if self.keep:
            return structured(current.copy(), self.columns)
        parts = [*self._preview, self._fold(current, self._base)] if len(current) else list(self._preview)
        data = np.concatenate(parts) if parts else np.empty((0, len(self.columns)))
        return structured(data, self.columns)
