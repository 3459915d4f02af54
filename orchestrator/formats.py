# SPDX-License-Identifier: BSD-2-Clause
"""Result formats and output selection: what ``--output`` (by its extension), ``--output-variables``,
``--output-interval`` and ``--no-inputs`` make of the CSV the master streams.

* ``.csv``: text, ``time`` then one column per signal (what the master writes as the run goes);
* ``.parquet``: one float64 column per signal, the same names (pyarrow; read with pandas, polars,
  DuckDB, Spark ...); each field's metadata holds its ``unit`` and ``description``, and the
  schema's ``PANDAS_ATTRS`` the units, so ``pandas.read_parquet(f).attrs["units"]`` has them;
* ``.mat``: the Dymola/OpenModelica trajectory format (MATLAB v4, ``Aclass = Atrajectory 1.1
  binTrans``, ``name``, ``description``, ``dataInfo``, ``data_1``, ``data_2``) that OMSimulator and
  Dymola write, so the tools their users have read it; the same names (scipy).

A name without extension gets CSV; any other extension is a usage error, before anything runs.
The recorder formats only the selected columns and rows (:meth:`Selection.layout`), straight into a
CSV result. Another format is made from the streamed CSV when the run ends (also after a
failure, from the rows kept): the CSV then goes to ``<output>.<pid>.partial.csv`` (the process id:
two runs writing one output do not share it) and is removed once the final file is written.
"""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import files
from .errors import OutputError, UsageError, option

__all__ = ["FORMATS", "Selection", "binary_copy_path", "check_interval", "check_output", "csv_rows",
           "read_table", "read_tool_csv", "staging_path", "write_selected"]

FORMATS = (".csv", ".parquet", ".mat")
NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class Selection:
    """Which columns and rows of a result to write: ``variables`` (fnmatch patterns; empty: all),
    ``interval`` (s; a multiple of the step, rows at ``t0 + k * interval``), ``drop`` (columns left
    out, e.g. inputs that only repeat their source)."""

    variables: tuple[str, ...] = ()
    interval: float | None = None
    drop: tuple[str, ...] = ()

    @property
    def everything(self) -> bool:
        """True when every column and row is kept."""
        return not self.variables and self.interval is None and not self.drop

    def columns(self, names: Sequence[str]) -> list[str]:
        """``time`` and the selected signals of ``names``, in their order; UsageError naming a
        pattern that matches no column."""
        signals = [n for n in names if n != "time" and n not in self.drop]
        if not self.variables:
            return ["time", *signals]
        for pattern in self.variables:
            if not fnmatch.filter(signals, pattern):
                raise UsageError(f"{option('output_variables')}: '{pattern}' matches no column "
                                 f"(columns: {', '.join(signals)})")
        return ["time", *[n for n in signals if any(fnmatch.fnmatchcase(n, p) for p in self.variables)]]

    def kept(self, count: int, step: float) -> int:
        """How many of ``count`` rows computed every ``step`` s from the start the file holds (the
        rows on the output grid, as :meth:`rows` selects them)."""
        if self.interval is None or count <= 0:
            return max(count, 0)
        every = max(1, round(self.interval * NS_PER_S) // round(step * NS_PER_S))
        return -(-count // every)

    def layout(self, names: Sequence[str]) -> tuple[list[int] | None, int | None]:
        """What the recorder writes of rows with columns ``names``: the indices of the selected
        columns (None: all) and the interval in ns (None: every row), the rows kept as :meth:`rows`
        keeps them."""
        selected = self.columns(names)
        indices = None if selected == list(names) else [list(names).index(c) for c in selected]
        return indices, None if self.interval is None else round(self.interval * NS_PER_S)

    def rows(self, time: np.ndarray) -> np.ndarray:
        """Mask of the rows on the output grid ``t0 + k * interval`` (integer nanoseconds)."""
        if self.interval is None or not len(time):
            return np.ones(len(time), dtype=bool)
        ns = np.round(np.asarray(time) * NS_PER_S).astype(np.int64)
        return (ns - ns[0]) % round(self.interval * NS_PER_S) == 0


def check_output(path: str | os.PathLike, step: float | None = None,
                 selection: Selection = Selection()) -> None:
    """UsageError for an extension no writer handles (none: CSV) or an interval that is not a
    positive multiple of the communication step ``step``; OutputError for an existing ``path`` that
    is not a regular file (a folder, a FIFO, which would block the run until a reader comes, a
    device or a socket; ``os.devnull`` excepted)."""
    if not os.fspath(path):
        raise UsageError(f"{option('output')}: the file name is empty")
    unusable = files.not_regular(path)
    if unusable:
        raise OutputError(f"{path}: {unusable}")
    suffix = Path(path).suffix.lower()
    if suffix and suffix not in FORMATS:
        raise UsageError(f"{option('output')} {path}: cannot write '{suffix}' files (choose "
                         f"{', '.join(FORMATS)}; a name without extension gets CSV)")
    interval = selection.interval
    if interval is not None:
        if not (np.isfinite(interval) and interval > 0):
            raise UsageError(f"{option('output_interval')} must be positive and finite "
                             f"(got {interval!r})")
        if step is not None:
            check_interval(interval, step)


def check_interval(interval: float, step: float) -> None:
    """UsageError for an output interval that is not a multiple of the communication step."""
    if round(interval * NS_PER_S) % round(step * NS_PER_S):
        raise UsageError(f"{option('output_interval')} {interval:g} s is not a multiple of the step "
                         f"{step:g} s")


def staging_path(output: str | os.PathLike) -> Path:
    """Where the master streams its CSV: ``output`` itself for a CSV (the recorder writes only the
    selection, :meth:`Selection.layout`), else ``<output>.<pid>.partial.csv``, of this process
    only (turned into ``output`` by :func:`write_selected`)."""
    output = Path(output)
    if output.suffix.lower() in (".csv", ""):
        return output
    return output.with_name(f"{output.name}.{os.getpid()}.partial.csv")


def binary_copy_path(staged: str | os.PathLike) -> Path:
    """Where the rows of a staged CSV are also written as raw float64 (``<staged>.f64``): what
    :func:`write_selected` converts from, removed with the staged CSV."""
    staged = Path(staged)
    return staged.with_name(staged.name + ".f64")


def write_selected(csv: str | os.PathLike, output: str | os.PathLike,
                   selection: Selection = Selection(), descriptions: Mapping[str, str] | None = None,
                   units: Mapping[str, str | None] | None = None) -> Path:
    """Write the selected columns and rows of the result CSV ``csv`` to ``output`` in the format
    of its extension (written to a temporary name, then renamed), and remove ``csv`` when it is
    not ``output`` itself. ``descriptions`` (column -> text, e.g. ``Plant output [rad]``) go into a
    ``.mat`` file's ``description`` matrix and a Parquet field's metadata, ``units`` (column ->
    unit, None: none declared) into the Parquet metadata. Returns ``output``."""
    csv, output = Path(csv), Path(output)
    if csv == output and selection.everything:
        return output
    data = _read_staged(csv)
    binary_copy_path(csv).unlink(missing_ok=True)
    columns = selection.columns(data.dtype.names or ())
    data = data[selection.rows(data["time"])]
    suffix = output.suffix.lower()
    with files.replacing(output) as partial:
        if suffix == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            # from the buffers: pa.table and pa.array import pandas to inspect their argument (0.15 s)
            table = pa.Table.from_arrays(
                [pa.Array.from_buffers(pa.float64(), len(data),
                                       [None, pa.py_buffer(np.ascontiguousarray(data[c], dtype=np.float64))])
                 for c in columns], schema=_parquet_schema(columns, units or {}, descriptions or {}))
            pq.write_table(table, partial)
        elif suffix == ".mat":
            _write_mat(partial, data, columns, descriptions or {})
        else:
            with open(partial, "wb") as out:
                out.write((",".join(columns) + "\n").encode("utf-8"))
                if len(data):
                    out.write(csv_rows(np.column_stack([data[c] for c in columns])))
    if csv != output:
        csv.unlink(missing_ok=True)
    return output


def _parquet_schema(columns: Sequence[str], units: Mapping[str, str | None],
                    descriptions: Mapping[str, str]):  # -> pyarrow.Schema
    """float64 fields carrying their unit and description; the units also as pandas' ``attrs``."""
    import pyarrow as pa

    known = {"time": "s", **{c: units.get(c) for c in columns if c != "time"}}
    fields = []
    for c in columns:
        meta = {k: v for k, v in (("unit", known.get(c)), ("description", descriptions.get(c))) if v}
        fields.append(pa.field(c, pa.float64(), metadata=meta or None))
    import orjson

    return pa.schema(fields, metadata={"PANDAS_ATTRS": orjson.dumps({"units": known}).decode()})


def csv_rows(block: np.ndarray) -> bytes:
    """The CSV lines of a 2-D float64 array: each value the shortest text that reads back to the
    same double (orjson's, e.g. ``1e-6`` where ``repr`` gives ``1e-06``); NaN and infinities as
    ``nan``, ``inf``, ``-inf`` (orjson would write ``null``), one line per row, each ended by a
    newline. orjson (with uuid, 0.36 MB of a run's peak) is imported by the first rows formatted:
    a run writing nothing never formats one."""
    import orjson

    if not block.size:
        return b""
    block = np.ascontiguousarray(block, dtype=np.float64)
    if block.ndim != 2 or block.shape[1] == 0:
        raise ValueError("csv_rows takes a 2-D array with at least one column")
    if np.isfinite(block).all():
        text = orjson.dumps(block, option=orjson.OPT_SERIALIZE_NUMPY)  # [[a,b],[c,d]]
        return text[2:-2].replace(b"],[", b"\n") + b"\n"
    return "".join(",".join(map(repr, row)) + "\n" for row in block.tolist()).encode("ascii")


def _read_staged(csv: Path) -> np.ndarray:
    """The CSV the master streamed, as a structured array: from its float64 copy when it is whole
    (:func:`binary_copy_path`), else parsed by pyarrow (0.1 s CPU for 30 001 rows of 26 columns,
    where fmpy's ``read_csv`` took 0.32 s); every value the same double either way."""
    with open(csv, "rb") as stream:
        names = stream.readline().decode("utf-8").rstrip("\n").split(",")
    copy = binary_copy_path(csv)
    try:
        values = np.fromfile(copy, dtype=np.float64)
    except (OSError, ValueError):
        values = None
    if values is not None and values.size % len(names) == 0:
        rows = values.reshape(-1, len(names))
        with open(csv, "rb") as stream:
            lines = sum(1 for _ in stream)
        if len(rows) == lines - 1:  # the same rows as the CSV
            return np.ascontiguousarray(rows).view([(n, np.float64) for n in names]).reshape(len(rows))
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(csv)
    result = np.empty(table.num_rows, dtype=[(n, np.float64) for n in table.column_names])
    for name in table.column_names:
        result[name] = table[name].to_numpy()
    return result


def _chars(texts: Sequence[str]) -> np.ndarray:
    """A MATLAB v4 character matrix with one text per column (binTrans), padded with blanks."""
    width = max(1, *(len(t) for t in texts))
    matrix = np.full((width, len(texts)), " ", dtype="U1")
    for j, text in enumerate(texts):
        matrix[:len(text), j] = list(text)
    return matrix


def _write_mat(path: Path, data: np.ndarray, columns: list[str], descriptions: Mapping[str, str]) -> None:
    """The Dymola trajectory format (1.1, binTrans): every signal in ``data_2`` (one row per
    variable, time first), ``data_1`` the time span, ``dataInfo`` as OMSimulator writes it, and
    each column's description with its unit in brackets (``Plant output [rad]``), as Dymola does."""
    from scipy.io import savemat

    aclass = np.full((4, 11), " ", dtype="U1")
    for i, text in enumerate(("Atrajectory", "1.1", "", "binTrans")):
        aclass[i, :len(text)] = list(text)
    info = np.zeros((4, len(columns)), dtype=np.int32)
    info[0, 1:] = 2  # every signal in data_2; time (column 0) is the abscissa
    info[1, :] = np.arange(1, len(columns) + 1)
    info[3, :] = -1  # not defined outside the time range
    time = data["time"]
    span = np.array([[time[0], time[-1]]]) if len(time) else np.zeros((1, 2))
    with open(path, "wb") as stream:
        values = np.array([data[c] for c in columns], dtype=np.float64).reshape(len(columns), -1)
        texts = _chars([descriptions.get(c, "Simulation time [s]" if c == "time" else "") for c in columns])
        savemat(stream, {"Aclass": aclass, "name": _chars(columns), "description": texts,
                         "dataInfo": info, "data_1": span, "data_2": values}, format="4")


def read_table(path: str | os.PathLike) -> np.ndarray:
    """A ``.parquet`` or ``.mat`` (Dymola trajectory) result as a structured array, ``time`` first
    (ValueError or OSError when it is not one)."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq

        table = pq.read_table(path)
        columns = {name: table.column(name).to_numpy().astype(np.float64) for name in table.schema.names}
    else:
        from scipy.io import loadmat

        mat = loadmat(path, chars_as_strings=False)
        if "".join(mat["Aclass"][3]).strip() != "binTrans":
            raise ValueError("not a Dymola trajectory file in binTrans layout")
        names = ["".join(mat["name"][:, j]).strip() for j in range(mat["name"].shape[1])]
        info, data = mat["dataInfo"], {1: mat["data_1"], 2: mat["data_2"]}
        columns = {}
        for j, name in enumerate(names):
            matrix = data[2 if j == 0 else int(info[0, j])]
            row = abs(int(info[1, j])) - 1
            values = np.sign(info[1, j]) * matrix[row]
            if matrix is data[1]:  # a constant: its value at every time point
                values = np.full(data[2].shape[1], values[0])
            columns[name] = values
    result = np.zeros(len(next(iter(columns.values()))), dtype=[(n, np.float64) for n in columns])
    for name, values in columns.items():
        result[name] = values
    return result


def read_tool_csv(path: str | os.PathLike) -> np.ndarray:
    """A result CSV another tool wrote, read with pyarrow (quoted names, blanks after commas), as
    a structured array: OMSimulator names its columns ``<model>.<system>.<component>.<variable>``
    and writes a row per event iteration, so names whose every non-time column shares the leading
    segments beyond ``component.variable`` lose them, and of the rows of one time point the last
    is kept (the values the step ended with). ValueError when it is not a table of numbers."""
    import pyarrow.csv as pacsv

    try:
        table = pacsv.read_csv(Path(path))
    except Exception as exc:  # noqa: BLE001 - pyarrow raises its own ArrowInvalid
        raise ValueError(str(exc).splitlines()[0]) from exc
    names = list(table.column_names)
    signals = [n.split(".") for n in names if n != "time"]
    drop = 0
    while signals and all(len(s) > drop + 2 and s[drop] == signals[0][drop] for s in signals):
        drop += 1
    columns = {n if n == "time" else ".".join(n.split(".")[drop:]): table[n].to_numpy().astype(np.float64)
               for n in names}
    if len(columns) != len(names):
        raise ValueError("two columns have one name")
    result = np.zeros(table.num_rows, dtype=[(n, np.float64) for n in columns])
    for name, values in columns.items():
        result[name] = values
    if "time" in columns and len(result) > 1 and np.all(np.diff(result["time"]) >= 0):
        last = np.append(np.diff(result["time"]) > 0, True)  # the last row of each time point
        result = result[last]
    return result
