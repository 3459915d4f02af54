"""Input time series (``--input-file``): a CSV that drives inputs no connection feeds.

FMPy's convention: a ``time`` column, then one column per input, named ``<component>.<input>``
as result columns are. At each communication point the masters set every driven input to its
value at that time: linear interpolation for a continuous input, the last row at or before it for
a discrete one; before the first row the first value, after the last row the last value (a file
that does not cover the run is a ScenarioWarning, not a silent hold).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import UsageError
from .results import read_result
from .ssp import PortRef
from .system import System

__all__ = ["InputSeries", "read_inputs"]


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
        row = max(0, int(np.searchsorted(self.time, t, side="right")) - 1)
        out = self.values[row].copy()
        for j, held in enumerate(self.discrete):
            if not held:
                out[j] = np.interp(t, self.time, self.values[:, j])
        return out


def read_inputs(path: str | os.PathLike, system: System, start: float,
                stop: float) -> tuple[InputSeries, list[str]]:
    """Read an input file for ``system``: UsageError naming a column that is not an input no
    connection feeds (with the inputs that are), a non-Real input or a non-finite value; the
    warnings (the file does not cover ``start`` .. ``stop``)."""
    path = Path(path)
    data = read_result(path)
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
        raise UsageError(f"--input-file {path}: {'; '.join(problems)} (inputs it can drive: {inputs})")
    if not ports:
        raise UsageError(f"--input-file {path}: no input column (inputs it can drive: "
                         f"{', '.join(free) or 'none'})")
    values = np.column_stack([np.asarray(data[str(p)], dtype=float) for p in ports])
    if not np.isfinite(values).all():
        row, column = np.argwhere(~np.isfinite(values))[0]
        raise UsageError(f"--input-file {path}: '{ports[column]}' is {values[row, column]!r} at "
                         f"t={float(data['time'][row]):g} s")
    time = np.asarray(data["time"], dtype=float)
    warnings = []
    if time[0] > start or time[-1] < stop:
        warnings.append(f"--input-file {path} covers t = {time[0]:g} .. {time[-1]:g} s of the run's "
                        f"{start:g} .. {stop:g} s: its first and last values are held outside")
    return InputSeries(tuple(ports), time, values, tuple(discrete)), warnings
