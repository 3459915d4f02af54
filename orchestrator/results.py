"""Results: every row kept in memory and streamed to CSV as the run goes.

Rows are copied into a preallocated array (cheap inside the stepping loop) and written to the CSV
in blocks of at most ``flush_rows`` rows, flushed to the OS after each block; ``close()`` (called
on every path, including a failure or Ctrl-C) writes what is left, so a failed run keeps every row
computed before the failure. Floats are written with ``repr`` (shortest exact round trip), so the
CSV reproduces the in-memory values bit for bit; ``fmpy.util.read_csv`` reads it.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

__all__ = ["Recorder", "structured"]


def structured(data: np.ndarray, columns: Sequence[str]) -> np.ndarray:
    """View a 2-D float array as a structured array with one field per column (no copy)."""
    dtype = np.dtype([(name, np.float64) for name in columns])
    return np.ascontiguousarray(data).view(dtype).reshape(len(data))


class Recorder:
    """Collects rows of ``len(columns)`` floats; writes them to ``path`` (if any) as they come."""

    def __init__(self, columns: Sequence[str], rows: int, path: str | os.PathLike | None = None,
                 flush_rows: int = 500) -> None:
        self.columns = list(columns)
        self.data = np.empty((rows, len(self.columns)))
        self.count = 0
        self._written = 0
        self._flush_rows = flush_rows
        self._file: TextIO | None = None
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(path, "w", encoding="utf-8", newline="\n")  # noqa: SIM115 (closed in close())
            self._file.write(",".join(self.columns) + "\n")
            self._file.flush()

    def append(self, row: np.ndarray) -> None:
        """Record one row (copied)."""
        self.data[self.count] = row
        self.count += 1
        if self.count - self._written >= self._flush_rows:
            self.flush()

    def flush(self) -> None:
        """Write the rows not yet in the file and hand them to the OS."""
        if self._file is not None and self._written < self.count:
            block = self.data[self._written:self.count].tolist()
            self._file.write("".join(",".join(map(repr, row)) + "\n" for row in block))
            self._file.flush()
        self._written = self.count

    def close(self) -> None:
        """Write the remaining rows and close the file (idempotent)."""
        self.flush()
        if self._file is not None:
            self._file.close()
            self._file = None

    def result(self) -> np.ndarray:
        """The rows recorded so far as a structured array (``time`` first)."""
        return structured(self.data[:self.count].copy(), self.columns)
