# SPDX-License-Identifier: BSD-2-Clause
"""The one owner of a run's output file, as libcosim's file observer owns its files: the file's name,
format and selection are checked once, before anything runs; when the run starts it writes the
provenance (status ``running``) and names the CSV the recorder streams to (the result itself, or
a staged CSV when another format is asked for) and what of each row it holds (:meth:`RunOutput.layout`:
the recorder formats nothing else); when the run ends, however it ends, it writes the rows kept in
the format asked for and finishes the provenance.

:class:`RunOutput` with no file keeps only the record (status, rows, last time) for the result. The
null device (``--output /dev/null``: a run that writes nothing) gets the rows, which it drops, and no
provenance: its sidecar would be ``/dev/null.json``, a file in ``/dev`` (root) or a run that fails
(anyone else).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from . import formats, provenance
from .errors import OutputError
from .results import Recorder
from .system import PortRef, System

__all__ = ["RunOutput", "descriptions", "system_columns"]


def system_columns(system: System) -> list[str]:
    """Every connector of a system as a result column names it.

    Parameters
    ----------
    system : System
        A validated system (:func:`orchestrator.open_system`).

    Returns
    -------
    list of str
        ``component.connector`` for each input and output, in the order of the result's columns
        (after ``time``).
    """
    return [str(PortRef(name, c)) for name, comp in system.components.items()
            for c in (*comp.inputs, *comp.outputs)]


def descriptions(system: System) -> dict[str, str]:
    """Each column's description and unit as Dymola writes them into a result file:
    ``Plant output [rad]`` (the FMU's description; the unit in brackets when it declares one)."""
    units = provenance.column_units(system)
    texts = {}
    for name, comp in system.components.items():
        variables = comp.variables
        for k in (*comp.inputs, *comp.outputs):
            column = str(PortRef(name, k))
            text, unit = variables[k].description or "", units.get(column)
            texts[column] = f"{text} [{unit}]".strip() if unit else text
    return texts


class RunOutput:
    """The output file ``path`` (None: none) of a run and what it holds (``variables``,
    ``interval``, ``no_inputs``: :class:`~orchestrator.formats.Selection`). UsageError or
    OutputError at once for a file that cannot be written as asked."""

    def __init__(self, path: str | os.PathLike | None, variables: tuple[str, ...] = (),
                 interval: float | None = None, no_inputs: bool = False) -> None:
        self.path = None if path is None else Path(path)
        self.selection = formats.Selection(variables, interval)
        self.no_inputs = no_inputs
        self.stream: Path | None = None  # the CSV the recorder writes, once started
        self.texts: dict[str, str] = {}
        if self.path is not None:
            formats.check_output(self.path, selection=self.selection)

    def layout(self, columns: Sequence[str]) -> tuple[list[int] | None, int | None]:
        """The columns (indices into ``columns``; None: all) and the interval (ns; None: every row) of
        the rows the recorder writes (:meth:`~orchestrator.formats.Selection.layout`)."""
        return self.selection.layout(columns) if self.path is not None else (None, None)

    @property
    def staged(self) -> bool:
        """The recorder writes a staged CSV (converted when the run ends): a float64 copy beside it."""
        return self.stream is not None and self.stream != self.path

    def start(self, system: System, step: float, record: dict[str, object]) -> Path | None:
        """The run of ``system`` on ``step`` begins: the selection checked against its columns (file
        or not) and the step, the provenance written (``record``); returns the CSV to stream to
        (None: none)."""
        if self.no_inputs:
            self.selection = replace(self.selection, drop=tuple(str(end) for end, link in system.links.items()
                                                                if not link.transformed))
        self.selection.columns(["time", *system_columns(system)])  # a pattern matching nothing: now
        if self.path is None:
            return None
        if self.selection.interval is not None:
            formats.check_interval(self.selection.interval, step)
        self.texts = descriptions(system)
        self.stream = formats.staging_path(self.path)
        record["output"] = {"format": self.path.suffix.lower(), "variables": list(self.selection.variables),
                            "interval": self.selection.interval, "left_out": list(self.selection.drop)}
        if not self.sink:
            provenance.write_provenance(self.path, record)
        return self.stream

    @property
    def sink(self) -> bool:
        """The output is the null device: rows go there and are gone, no provenance beside it."""
        return self.path is not None and os.fspath(self.path) == os.devnull

    def finish(self, recorder: Recorder | None, record: dict[str, object], status: str, message: str,
               time: Callable[[int], float], step: float) -> dict[str, Path]:
        """The run on ``step`` ended with ``status``: the rows on disk written in the format asked
        for and the provenance finished (``rows``: the rows the file holds, after the interval;
        ``rows_computed``: every communication point computed; without a file: ``record``
        updated); returns the files written. ``time(k)`` is t_k."""
        count = recorder.count if recorder is not None else 0
        if self.path is None or self.stream is None or self.sink:
            record.update(status=status, rows=count, last_time=time(count - 1) if count else None)
            if message:
                record["message"] = message
            return {}
        saved = recorder.saved if recorder is not None else 0  # what is on disk, never more
        record["rows_computed"] = count
        kept = self.selection.kept(saved, step)
        outputs = {}
        try:
            outputs["provenance"] = provenance.finish(self.path, record, status, kept,
                                                      time(saved - 1) if saved else None, message)
        except OutputError:
            if status == "complete":
                raise
            # else the error that ended the run (its one line names where its rows are) goes on
        if saved and self.stream.is_file():
            units = record.get("units")  # the rows kept, in the format asked for, with their units
            if self.staged:  # the recorder wrote the selection already
                formats.write_selected(self.stream, self.path, formats.Selection(), self.texts,
                                       units if isinstance(units, dict) else None)
            outputs["result"] = self.path
        with contextlib.suppress(FileNotFoundError, NotADirectoryError):  # not there (its folder gone)
            formats.binary_copy_path(self.stream).unlink()
        return outputs
