# SPDX-License-Identifier: BSD-2-Clause
"""Campaign designs: which parameters vary and how, read from a TOML or JSON file.

A design names parameters as ``--set`` does (``component.variable``), plus ``stop_time`` and
``step``. Its sections combine as a cross product (an absent section counts as one empty point)::

    description = "Example 1 from every initial state"   # optional
    stop_time = 3.0            # optional: every run's stop time (default: the scenario's)
    step = 0.001               # optional: communication step (default: the scenario's)
    timeout = 120              # optional: wall-time limit per run in s
    master = "gauss-seidel"    # optional

    [fixed]                    # constant overrides applied to every run
    "actuator.t_fault" = 1e9

    [grid]                     # full factorial
    "plant.x1_0" = { start = -10, stop = 10, num = 21 }   # inclusive, evenly spaced
    "controller.mode" = [0, 1]                             # explicit values

    [sample]                   # n points over boxes: "random" (uniform) or "lhs" (Latin hypercube)
    method = "lhs"
    n = 64
    seed = 2026
    ranges = { "actuator.K_inf" = [0.1, 1.0], "actuator.L_bias" = [-1.0, 1.0] }

    [table]                    # explicit points: CSV or Parquet, one column per parameter
    file = "points.csv"        # relative to the design file

    [labels."controller.mode"] # optional: names of a column's values in the report
    "0" = "fixed-time"

    [[plots]]                  # figures for the campaign report (see orchestrator.campaign.report)
    kind = "heatmap"
    x = "plant.x1_0"
    y = "plant.x2_0"
    metric = "settling_time"
    facet = "controller.mode"

A design holds at most ``MAX_POINTS`` points (the product of its sections, counted before any is
made: ``num = 1e9`` reached 3.6 GB in 2 minutes), and a ``[table]`` file at most ``MAX_TABLE_BYTES``.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomllib

from ..errors import OrchestratorError

__all__ = ["EXPERIMENT_KEYS", "MAX_POINTS", "MAX_TABLE_BYTES", "Design", "DesignError", "grid_points",
           "read_design", "sample_points"]

# Names besides component.variable that a design may vary.
EXPERIMENT_KEYS = ("stop_time", "step")
MAX_POINTS = 100_000  # runs of one design: about 3 h of 0.1 s runs on a 1000-core cluster
MAX_TABLE_BYTES = 64 << 20
PLOT_KINDS = ("heatmap", "scatter", "histogram")
_TOP_KEYS = {
    "description",
    "stop_time",
    "step",
    "timeout",
    "master",
    "fixed",
    "grid",
    "sample",
    "table",
    "plots",
    "labels",
}


class DesignError(OrchestratorError):
    """A design file is unusable; the message names the file and the offending key."""

    exit_status = 2


@dataclass(frozen=True)
class Design:
    """The points of a campaign: ``columns`` (varied names, in order) and one value tuple per point."""

    source: str
    columns: tuple[str, ...]
    points: tuple[tuple[float, ...], ...]
    fixed: Mapping[str, object] = field(default_factory=dict)
    stop_time: float | None = None
    step: float | None = None
    timeout: float | None = None
    master: str = "gauss-seidel"
    description: str = ""
    plots: tuple[Mapping[str, object], ...] = ()
    labels: Mapping[str, Mapping[str, str]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.points)

    def variants(self) -> list[dict[str, float]]:
        """One ``{name: value}`` per point, in design order."""
        return [dict(zip(self.columns, p, strict=True)) for p in self.points]


def _name_ok(name: str) -> bool:
    component, dot, variable = name.partition(".")
    return name in EXPERIMENT_KEYS or bool(dot and component and variable)


def _number(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DesignError(f"{where}: expected a finite number (got {value!r})")
    return float(value)


def grid_points(axes: Mapping[str, Sequence[float]]) -> list[tuple[float, ...]]:
    """The full factorial of ``axes`` (name -> values), last axis fastest."""
    return [tuple(p) for p in itertools.product(*axes.values())]


def sample_points(ranges: Mapping[str, tuple[float, float]], n: int, method: str, seed: int) -> np.ndarray:
    """``n`` points in the box ``ranges`` (name -> (low, high)): uniform ``random`` or Latin
    hypercube ``lhs`` (each axis split into ``n`` equal strata, one point in each), reproducible
    from ``seed``."""
    lows = np.array([r[0] for r in ranges.values()], dtype=float)
    highs = np.array([r[1] for r in ranges.values()], dtype=float)
    if method == "lhs":
        from scipy.stats import qmc

        unit = qmc.LatinHypercube(d=len(ranges), rng=np.random.default_rng(seed)).random(n)
    elif method == "random":
        unit = np.random.default_rng(seed).random((n, len(ranges)))
    else:
        raise ValueError(f"unknown sampling method {method!r} (choose lhs or random)")
    return lows + unit * (highs - lows)


def _axis(where: str, spec: object) -> list[float]:
    if isinstance(spec, Mapping):
        return _range(where, spec)
    if isinstance(spec, list) and spec:
        # an integer stays one (a mode, a discretization): the table then writes 1, not 1.0
        return [v if isinstance(v, int) and not isinstance(v, bool) else _number(f"{where}[{i}]", v)
                for i, v in enumerate(spec)]
    raise DesignError(f"{where}: expected a list of values or {{start, stop, num}} (got {spec!r})")


def _range(where: str, spec: Mapping[str, object]) -> list[float]:
    """A grid axis given as ``{start, stop, num}``: ``num`` evenly spaced values, both ends included."""
    unknown = set(spec) - {"start", "stop", "num"}
    if unknown or not {"start", "stop", "num"} <= set(spec):
        raise DesignError(f"{where}: a range needs exactly start, stop and num (got {sorted(spec)})")
    num = spec["num"]
    if isinstance(num, bool) or not isinstance(num, int) or num < 1:
        raise DesignError(f"{where}: num must be a positive integer (got {num!r})")
    if num > MAX_POINTS:
        raise DesignError(f"{where}: num = {num} is more than a design may have in all ({MAX_POINTS})")
    start, stop = _number(f"{where}.start", spec["start"]), _number(f"{where}.stop", spec["stop"])
    return [float(v) for v in np.linspace(start, stop, num)]


def _read_table(where: str, path: Path) -> tuple[list[str], list[tuple[float, ...]]]:
    import pyarrow.csv
    import pyarrow.parquet
    import pyarrow.types as pat

    try:
        size = path.stat().st_size
        if size > MAX_TABLE_BYTES:
            raise DesignError(f"{where}: {path} has {size} bytes, more than a table of points may have "
                              f"({MAX_TABLE_BYTES}; a design has at most {MAX_POINTS} points)")
        table = pyarrow.parquet.read_table(path) if path.suffix == ".parquet" else pyarrow.csv.read_csv(path)
    except (OSError, ValueError) as exc:  # pyarrow.ArrowInvalid is a ValueError
        raise DesignError(f"{where}: cannot read {path}: {str(exc).splitlines()[0]}") from exc
    columns = list(table.column_names)
    for name in columns:
        column = table.column(name)
        if column.null_count or not (pat.is_integer(column.type) or pat.is_floating(column.type)):
            raise DesignError(f"{path}: column '{name}' must hold numbers in every row")
    return columns, _table_rows(path, columns, [table.column(n).to_pylist() for n in columns])


def _table_rows(path: Path, columns: Sequence[str], data: Sequence[list]) -> list[tuple[float, ...]]:
    """The table's rows as tuples of finite numbers, its columns ``data`` given as lists."""
    rows = []
    for i, row in enumerate(zip(*data, strict=True)):
        rows.append(
            tuple(
                _number(f"{path}: row {i + 2}, column '{name}'", v)
                for name, v in zip(columns, row, strict=True)
            )
        )
    if not rows:
        raise DesignError(f"{path}: the table has no rows")
    return rows


def _load(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DesignError(f"{path}: cannot read the design: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise DesignError(f"{path}: cannot read the design: not UTF-8 text ({exc.reason} at byte "
                          f"{exc.start})") from exc
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as exc:
        raise DesignError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'}: {exc}") from exc
    if not isinstance(data, dict):
        raise DesignError(f"{path}: the design must be a table/object at the top level")
    return data


def _count(path: Path, data: Mapping[str, object]) -> None:
    """DesignError when the grid and sample would make more than ``MAX_POINTS`` points, counted from
    their sizes before anything is made (a table's rows are counted once read)."""
    total = 1
    grid = data.get("grid", {})
    for spec in (grid.values() if isinstance(grid, Mapping) else ()):
        num = spec.get("num") if isinstance(spec, Mapping) else len(spec) if isinstance(spec, list) else 1
        total *= num if isinstance(num, int) and num > 0 else 1
    sample = data.get("sample")
    n = sample.get("n") if isinstance(sample, Mapping) else None
    total *= n if isinstance(n, int) and n > 0 else 1
    if total > MAX_POINTS:
        raise DesignError(f"{path}: {total} points, more than a design may have ({MAX_POINTS}); split it")


_Part = tuple[list[str], list[tuple[float, ...]]]


def read_design(path: str | os.PathLike) -> Design:
    """Read a TOML (``.toml``) or JSON (``.json``) design; raises DesignError naming file and key."""
    path = Path(path)
    data = _load(path)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise DesignError(
            f"{path}: unknown key(s) {', '.join(sorted(unknown))} (allowed: {', '.join(sorted(_TOP_KEYS))})"
        )
    parts = _parts(path, data)
    total = math.prod(len(rows) for _, rows in parts)
    if total > MAX_POINTS:
        raise DesignError(f"{path}: {total} points, more than a design may have ({MAX_POINTS}); split it")
    columns = _columns(path, parts)
    points = [
        tuple(itertools.chain.from_iterable(combo))
        for combo in itertools.product(*(rows for _, rows in parts))
    ]
    fixed = _fixed(path, data.get("fixed", {}), columns)
    experiment = _experiment(path, data)
    plots = _plots(path, data.get("plots", []))
    labels = data.get("labels", {})
    if not isinstance(labels, dict) or not all(isinstance(v, dict) for v in labels.values()):
        raise DesignError(f"{path}: [labels] must map a column to {{value = label}} tables")
    return Design(
        source=str(path),
        columns=tuple(columns),
        points=tuple(points),
        fixed=fixed,
        master=str(data.get("master", "gauss-seidel")),
        description=str(data.get("description", "")),
        plots=tuple(plots),
        labels={k: {str(a): str(b) for a, b in v.items()} for k, v in labels.items()},
        **experiment,
    )


def _parts(path: Path, data: Mapping[str, object]) -> list[_Part]:
    """The design's sections that vary something, each as (names, points): grid, sample, table."""
    parts: list[_Part] = []
    grid = data.get("grid", {})
    if not isinstance(grid, dict):
        raise DesignError(f"{path}: [grid] must be a table of name = values")
    _count(path, data)
    if grid:
        axes = {name: _axis(f"{path}: grid '{name}'", spec) for name, spec in grid.items()}
        parts.append((list(axes), grid_points(axes)))
    sample = data.get("sample")
    if sample is not None:
        parts.append(_sample(f"{path}: [sample]", sample))
    table = data.get("table")
    if table is not None:
        if not isinstance(table, dict) or set(table) != {"file"} or not isinstance(table["file"], str):
            raise DesignError(f'{path}: [table] must give file = "points.csv" (or .parquet)')
        parts.append(_read_table(f"{path}: [table]", path.parent / table["file"]))
    return parts


def _sample(where: str, sample: object) -> _Part:
    """The ``[sample]`` section's points, its settings checked first."""
    if not isinstance(sample, dict) or set(sample) - {"method", "n", "seed", "ranges"}:
        raise DesignError(f"{where}: expected method, n, seed and ranges")
    method, n, seed = _sampling(where, sample.get("method", "lhs"), sample.get("n"), sample.get("seed"))
    boxes = _boxes(where, sample.get("ranges"))
    sampled = sample_points(boxes, n, method, seed)
    return list(boxes), [tuple(float(v) for v in p) for p in sampled]


def _sampling(where: str, method: object, n: object, seed: object) -> tuple[str, int, int]:
    """The sample's method, size and seed; DesignError unless the method is known, ``n`` a positive
    count within the limit and ``seed`` a non-negative integer (a sample must be reproducible)."""
    if method not in ("lhs", "random"):
        raise DesignError(f"{where}: method must be 'lhs' or 'random' (got {method!r})")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise DesignError(f"{where}: n must be a positive integer (got {n!r})")
    if n > MAX_POINTS:
        raise DesignError(f"{where}: n = {n} is more than a design may have in all ({MAX_POINTS})")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise DesignError(
            f"{where}: seed must be a non-negative integer, so the sample is reproducible (got {seed!r})"
        )
    return str(method), n, seed


def _boxes(where: str, ranges: object) -> dict[str, tuple[float, float]]:
    """The ``[sample]`` ranges as name -> (low, high), low below high."""
    if not isinstance(ranges, dict) or not ranges:
        raise DesignError(f"{where}: ranges must map each parameter to [low, high]")
    boxes = {}
    for name, r in ranges.items():
        if not (isinstance(r, list) and len(r) == 2):
            raise DesignError(f"{where} ranges '{name}': expected [low, high] (got {r!r})")
        low, high = _number(f"{where} ranges '{name}'", r[0]), _number(f"{where} ranges '{name}'", r[1])
        if not low < high:
            raise DesignError(f"{where} ranges '{name}': low must be below high (got {r!r})")
        boxes[name] = (low, high)
    return boxes


def _columns(path: Path, parts: Sequence[_Part]) -> list[str]:
    """The varied names of all sections in order, each a valid name varied in one section only."""
    columns: list[str] = []
    for names, _ in parts:
        for name in names:
            if not _name_ok(name):
                raise DesignError(f"{path}: '{name}' is not COMPONENT.VARIABLE, stop_time or step")
            if name in columns:
                raise DesignError(f"{path}: '{name}' varies in two sections")
            columns.append(name)
    return columns


def _fixed(path: Path, fixed: object, columns: Sequence[str]) -> dict[str, object]:
    """The ``[fixed]`` overrides: one value per COMPONENT.VARIABLE that no section varies."""
    if not isinstance(fixed, dict):
        raise DesignError(f"{path}: [fixed] must be a table of name = value")
    for name, value in fixed.items():
        if not _name_ok(name) or name in EXPERIMENT_KEYS:
            raise DesignError(
                f"{path}: fixed '{name}' is not COMPONENT.VARIABLE (use the top-level stop_time/step keys)"
            )
        if name in columns:
            raise DesignError(f"{path}: '{name}' is both fixed and varied")
        if isinstance(value, (list, dict)):
            raise DesignError(f"{path}: fixed '{name}': expected one value (got {value!r})")
    return dict(fixed)


def _experiment(path: Path, data: Mapping[str, object]) -> dict[str, float]:
    """The top-level stop_time, step and timeout that are given; step and timeout positive."""
    experiment = {}
    for key in ("stop_time", "step", "timeout"):
        if key in data:
            value = _number(f"{path}: {key}", data[key])
            if value <= 0 and key != "stop_time":
                raise DesignError(f"{path}: {key} must be positive (got {value!r})")
            experiment[key] = value
    return experiment


def _plots(path: Path, plots: object) -> list[dict]:
    """The ``[[plots]]`` tables, each of a known kind (the report checks the rest)."""
    if not isinstance(plots, list) or not all(isinstance(p, dict) for p in plots):
        raise DesignError(f"{path}: plots must be an array of tables ([[plots]])")
    for i, p in enumerate(plots):
        if p.get("kind") not in PLOT_KINDS:
            raise DesignError(
                f"{path}: plots[{i}].kind must be one of {', '.join(PLOT_KINDS)} (got {p.get('kind')!r})"
            )
    return plots
