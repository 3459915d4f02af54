# SPDX-License-Identifier: BSD-2-Clause
"""The campaign table: one row per run, appended to ``runs.csv`` as each run finishes (so Ctrl-C or a
crash keeps every finished row), then rewritten in design order as ``runs.csv`` and ``runs.parquet``.

Columns: ``run`` (index in design order), ``run_id`` (digest of everything that determines the
run: scenario bytes, overrides, stop time, step, master), ``scenario``, one column per varied
parameter, ``stop_time``, ``step``, ``status`` (ok / failed / timeout), ``reason`` (one line),
``wall_time`` (s), then the metric columns. A metric is empty (null) when the run did not finish.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO, cast

from .. import files
from ..errors import UsageError

if TYPE_CHECKING:
    from _csv import Writer

__all__ = [
    "CSV_NAME",
    "META_KEY",
    "PARQUET_NAME",
    "STRING_COLUMNS",
    "Journal",
    "read_rows",
    "read_table",
    "write_parquet",
]

CSV_NAME = "runs.csv"
PARQUET_NAME = "runs.parquet"
META_KEY = b"orchestrate.campaign"
STRING_COLUMNS = ("run_id", "scenario", "status", "reason")
REQUIRED_COLUMNS = ("run", "run_id", "scenario", "status", "reason")  # what a report reads of every row


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _parse(column: str, text: str) -> object:
    """A cell as written by :func:`_cell`: an integer stays an integer (``repr`` of a float always
    has a point, an exponent or is inf/nan), so integer parameters keep their type."""
    if column in STRING_COLUMNS:
        return text
    if text == "":
        return None
    return int(text) if column == "run" or text.lstrip("-").isdigit() else float(text)


def read_rows(path: Path) -> tuple[list[str], list[dict[str, object]]]:
    """Header and typed rows of a campaign CSV (empty cells are None)."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = next(reader, [])
        rows = [
            {c: _parse(c, v) for c, v in zip(header, line, strict=True)}
            for line in reader
            if len(line) == len(header)
        ]  # a torn last line is dropped
    return header, rows


class Journal:
    """Appends rows to ``runs.csv`` as they arrive; :meth:`finish` rewrites it sorted, plus Parquet."""

    def __init__(self, folder: Path, columns: Sequence[str], metadata: Mapping[str, object]) -> None:
        self.folder = folder
        self.columns = list(columns)
        self.metadata = dict(metadata)
        self.csv_path = folder / CSV_NAME
        self.parquet_path = folder / PARQUET_NAME
        self.rows: list[dict[str, object]] = []
        self._file: TextIO | None = None
        self._writer: Writer | None = None

    def start(self, kept: Sequence[dict[str, object]]) -> None:
        """Begin the journal with the rows kept from an earlier run of the campaign."""
        self.folder.mkdir(parents=True, exist_ok=True)
        self.rows = list(kept)
        self._write_sorted()
        self._file = open(self.csv_path, "a", newline="", encoding="utf-8")  # noqa: SIM115 (closed in finish)
        self._writer = csv.writer(self._file)

    def append(self, row: Mapping[str, object]) -> None:
        """Record one finished run (flushed at once)."""
        assert self._file is not None and self._writer is not None, "Journal.append before start"
        self.rows.append(dict(row))
        self._writer.writerow([_cell(row.get(c)) for c in self.columns])
        self._file.flush()

    def finish(self) -> None:
        """Close the journal; write ``runs.csv`` in design order and ``runs.parquet``."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self._write_sorted()
        write_parquet(self.parquet_path, self.columns, self.rows, self.metadata)

    def _write_sorted(self) -> None:
        self.rows.sort(key=lambda r: cast(int, r["run"]))
        with files.replacing(self.csv_path) as partial, open(partial, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(self.columns)
            writer.writerows([_cell(r.get(c)) for c in self.columns] for r in self.rows)


def write_parquet(
    path: Path, columns: Sequence[str], rows: Sequence[Mapping[str, object]], metadata: Mapping[str, object]
) -> None:
    """The table as Parquet; the campaign's description (JSON) goes into the schema metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    def integers(c: str) -> bool:  # every cell an int (not bool), at least one: an integer parameter
        cells = [r.get(c) for r in rows if r.get(c) is not None]
        return bool(cells) and all(isinstance(v, int) and not isinstance(v, bool) for v in cells)

    def kind(c: str) -> pa.DataType:
        if c in STRING_COLUMNS:
            return pa.string()
        return pa.int64() if c == "run" or integers(c) else pa.float64()

    schema = pa.schema(
        [pa.field(c, kind(c)) for c in columns],
        metadata={META_KEY: json.dumps(metadata, default=str).encode()},
    )
    arrays = {c: [r.get(c) for r in rows] for c in columns}
    with files.replacing(path) as partial:
        pq.write_table(pa.table(arrays, schema=schema), partial)


def read_table(path: str | os.PathLike) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows and campaign metadata of a campaign table (``runs.parquet``, or ``runs.csv`` with the
    metadata read from ``campaign.json`` beside it). A file that is not one (bytes that are not
    UTF-8, not CSV or Parquet, no ``run``/``status`` columns) is a :class:`UsageError` naming it."""
    path = Path(path)
    try:
        if path.suffix == ".parquet":
            import pyarrow.parquet as pq

            table = pq.read_table(path)
            raw = (table.schema.metadata or {}).get(META_KEY, b"{}")
            header, rows, meta = table.column_names, table.to_pylist(), json.loads(raw)
        else:
            header, rows = read_rows(path)
            meta_path = path.with_name("campaign.json")
            meta = json.loads(meta_path.read_text(encoding="utf-8")) if meta_path.is_file() else {}
    except (OSError, UnicodeDecodeError, ValueError, csv.Error) as error:  # pyarrow's errors are ValueErrors
        raise UsageError(f"{path}: not a campaign table ({error})") from error
    missing = [column for column in REQUIRED_COLUMNS if column not in header]
    if missing or not isinstance(meta, dict):
        raise UsageError(f"{path}: not a campaign table (no {', '.join(missing) or 'metadata object'})")
    return rows, meta
