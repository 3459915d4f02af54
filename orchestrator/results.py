"""Results: every row kept in memory and streamed to CSV as the run goes.

Rows are copied into a preallocated array (cheap inside the stepping loop). When a CSV is wanted,
blocks of ``flush_rows`` raw rows go through a pipe to a child process
(``orchestrator._csvwriter``) that formats and flushes them: float formatting costs about 0.5 us
per value in Python and would otherwise dominate the master's overhead. ``close()`` (called on
every path, including a failure or Ctrl-C) sends what is left and waits for the writer, so a failed
run keeps every row computed before the failure; if the parent process itself dies, the CSV still
holds every block sent. Floats are written with ``repr`` (shortest exact round trip), so the CSV
reproduces the in-memory values bit for bit; ``fmpy.util.read_csv`` reads it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from fmpy.util import read_csv

from .errors import UsageError

__all__ = ["Recorder", "ResultFileError", "plot_result", "read_result", "structured"]


def structured(data: np.ndarray, columns: Sequence[str]) -> np.ndarray:
    """View a 2-D float array as a structured array with one field per column (no copy)."""
    dtype = np.dtype([(name, np.float64) for name in columns])
    return np.ascontiguousarray(data).view(dtype).reshape(len(data))


class ResultFileError(UsageError, ValueError):
    """A file given as a result is missing or is not a result CSV; the message names it."""


def read_result(path: str | os.PathLike) -> np.ndarray:
    """Read a result CSV (``time`` first, one column per signal) with fmpy's reader; errors name the
    file. Time must increase strictly."""
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such file")
    try:
        data = read_csv(path)
    except (OSError, ValueError, IndexError, UnicodeDecodeError) as exc:
        raise ResultFileError(f"{path}: not a result CSV ({exc})") from exc
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


class Recorder:
    """Collects rows of ``len(columns)`` floats; streams them to the CSV ``path`` (if any)."""

    def __init__(self, columns: Sequence[str], rows: int, path: str | os.PathLike | None = None,
                 flush_rows: int = 200) -> None:
        self.columns = list(columns)
        self.data = np.empty((rows, len(self.columns)))
        self.count = 0
        self._sent = 0
        self._flush_rows = flush_rows
        self._next_flush = flush_rows
        self._writer: subprocess.Popen | None = None
        if path is not None:
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.open("w").close()  # an unwritable path fails here, in this process, before any step
            self._writer = subprocess.Popen(
                [sys.executable, "-m", "orchestrator._csvwriter", str(path.resolve()),
                 str(len(self.columns))],
                stdin=subprocess.PIPE)
            self._writer.stdin.write((",".join(self.columns) + "\n").encode("utf-8"))
            self._writer.stdin.flush()

    def append(self, row: np.ndarray) -> None:
        """Record one row (copied)."""
        self.data[self.count] = row
        self.count += 1
        if self.count >= self._next_flush:
            self.flush()

    def flush(self) -> None:
        """Send the rows not yet sent to the CSV writer."""
        if self._writer is not None and self._sent < self.count:
            self._writer.stdin.write(self.data[self._sent:self.count].tobytes())
            self._writer.stdin.flush()
        self._sent = self.count
        self._next_flush = self.count + self._flush_rows

    def close(self) -> None:
        """Send the remaining rows and wait until the CSV is complete (idempotent)."""
        writer = self._writer
        if writer is None:
            return
        try:
            self.flush()
        finally:
            self._writer = None
            writer.stdin.close()
            if writer.wait() != 0:
                raise OSError(f"the CSV writer failed (exit status {writer.returncode})")

    def result(self) -> np.ndarray:
        """The rows recorded so far as a structured array (``time`` first)."""
        return structured(self.data[:self.count].copy(), self.columns)


PLOT_GROUPS = (("output and reference", ("plant.y", "reference.yd")),
               ("control", ("controller.v", "actuator.uf")))


def plot_result(result: np.ndarray, path: str | os.PathLike, title: str = "") -> Path:
    """Plot tracking (``plant.y`` vs ``reference.yd``) and control (``controller.v``, ``actuator.uf``)
    when the columns exist, otherwise every column, against time; saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in result.dtype.names if n != "time"]
    groups = [(label, [c for c in cols if c in names]) for label, cols in PLOT_GROUPS]
    groups = [g for g in groups if g[1]] or [(n, [n]) for n in names[:8]]
    fig, axes = plt.subplots(len(groups), 1, sharex=True, figsize=(9, 2.6 * len(groups)), squeeze=False)
    for ax, (label, cols) in zip(axes[:, 0], groups, strict=True):
        for c in cols:
            ax.plot(result["time"], result[c], label=c, linewidth=1)
        magnitude = np.abs(np.concatenate([result[c] for c in cols]))
        typical = float(np.percentile(magnitude, 95)) if magnitude.size else 0.0
        if typical > 0.0 and magnitude.max() > 50.0 * typical:  # e.g. the controller's initial spike
            ax.set_yscale("symlog", linthresh=typical)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small")
    axes[-1, 0].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
