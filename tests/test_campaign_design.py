# SPDX-License-Identifier: BSD-2-Clause
"""Campaign designs (orchestrator.campaign.design): grids, ranges with counts, random and Latin
hypercube samples, explicit tables, and one-line errors for bad files.

Oracles: counting (a full factorial has prod(n_i) distinct points, each axis value appearing
prod / n_i times), the definition of a Latin hypercube (every axis split into n equal strata holds
exactly one point), evenly spaced inclusive ranges written out by hand, and tables written with
the standard csv module / pyarrow directly.
"""

from __future__ import annotations

import csv
import json
import math
from collections import Counter
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.campaign.design import DesignError, read_design, sample_points

finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False)


def write(tmp: Path, data: dict, name: str = "design.json") -> Path:
    path = tmp / name
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


@settings(max_examples=40, deadline=None)
@given(axes=st.lists(st.lists(finite, min_size=1, max_size=4, unique=True), min_size=1, max_size=3))
def test_grid_is_the_full_factorial(
    tmp_path_factory: pytest.TempPathFactory, axes: list[list[float]]
) -> None:
    names = [f"c{i}.p" for i in range(len(axes))]
    design = read_design(write(tmp_path_factory.mktemp("g"), {"grid": dict(zip(names, axes, strict=True))}))
    assert design.columns == tuple(names)
    assert len(design) == math.prod(len(a) for a in axes)
    assert len(set(design.points)) == len(design)  # no point twice
    for i, axis in enumerate(axes):
        counts = Counter(p[i] for p in design.points)
        assert counts == {v: len(design) // len(axis) for v in axis}


@settings(max_examples=40, deadline=None)
@given(start=finite, stop=finite, num=st.integers(1, 12))
def test_range_with_count_is_inclusive_and_evenly_spaced(
    tmp_path_factory: pytest.TempPathFactory, start: float, stop: float, num: int
) -> None:
    design = read_design(
        write(tmp_path_factory.mktemp("r"), {"grid": {"a.b": {"start": start, "stop": stop, "num": num}}})
    )
    values = [p[0] for p in design.points]
    expected = [start] if num == 1 else [start + i * (stop - start) / (num - 1) for i in range(num)]
    assert values == pytest.approx(expected, abs=1e-9 * (1 + abs(start) + abs(stop)))
    assert values[0] == start and (num == 1 or values[-1] == stop)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 40), dims=st.integers(1, 4), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_latin_hypercube_has_one_point_per_stratum(n: int, dims: int, seed: int, data: st.DataObject) -> None:
    ranges = {}
    for d in range(dims):
        low = data.draw(finite)
        width = data.draw(st.floats(min_value=1e-3, max_value=1e3))
        ranges[f"c.p{d}"] = (low, low + width)
    points = sample_points(ranges, n, "lhs", seed)
    assert points.shape == (n, dims)
    for d, (low, high) in enumerate(ranges.values()):
        column = points[:, d]
        assert ((column >= low) & (column <= high)).all()
        strata = sorted(min(int((x - low) / (high - low) * n), n - 1) for x in column)
        assert strata == list(range(n))
    assert (sample_points(ranges, n, "lhs", seed) == points).all()  # reproducible from the seed


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 30), seed=st.integers(0, 2**32 - 2))
def test_random_sample_stays_in_the_box_and_follows_the_seed(n: int, seed: int) -> None:
    ranges = {"a.x": (-1.0, 1.0), "a.y": (10.0, 20.0)}
    points = sample_points(ranges, n, "random", seed)
    assert ((points[:, 0] >= -1) & (points[:, 0] <= 1)).all()
    assert ((points[:, 1] >= 10) & (points[:, 1] <= 20)).all()
    assert (sample_points(ranges, n, "random", seed) == points).all()
    assert not (sample_points(ranges, n, "random", seed + 1) == points).all()


def test_sections_combine_as_a_cross_product_and_toml_reads_like_json(tmp_path: Path) -> None:
    (tmp_path / "design.toml").write_text(
        'stop_time = 2.5\ntimeout = 10\n[fixed]\n"actuator.t_fault" = 5.0\n'
        '[grid]\n"controller.mode" = [0, 1]\n'
        '[sample]\nmethod = "lhs"\nn = 4\nseed = 7\nranges = { "actuator.K_inf" = [0.1, 1.0] }\n'
        '[labels."controller.mode"]\n"0" = "fixed-time"\n',
        encoding="utf-8",
    )
    design = read_design(tmp_path / "design.toml")
    assert design.columns == ("controller.mode", "actuator.K_inf")
    assert len(design) == 8
    assert Counter(p[0] for p in design.points) == {0.0: 4, 1.0: 4}
    assert len({p[1] for p in design.points}) == 4  # the same 4 samples under each mode
    assert design.stop_time == 2.5 and design.timeout == 10 and design.fixed == {"actuator.t_fault": 5.0}
    assert design.labels == {"controller.mode": {"0": "fixed-time"}}


@pytest.mark.parametrize("kind", ["csv", "parquet"])
def test_explicit_table(tmp_path: Path, kind: str) -> None:
    rows = [(0.1, -1.0, 2), (0.5, 0.0, 3), (1.0, 1.0, 4)]
    names = ["actuator.K_inf", "actuator.L_bias", "stop_time"]
    if kind == "csv":
        with open(tmp_path / "points.csv", "w", newline="") as f:
            csv.writer(f).writerows([names, *rows])
    else:
        pq.write_table(
            pa.table({n: [r[i] for r in rows] for i, n in enumerate(names)}), tmp_path / "points.parquet"
        )
    design = read_design(write(tmp_path, {"table": {"file": f"points.{kind}"}}))
    assert design.columns == tuple(names)
    assert design.points == tuple(tuple(float(v) for v in r) for r in rows)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"grids": {}}, "unknown key(s) grids"),
        ({"grid": {"x1_0": [1, 2]}}, "'x1_0' is not COMPONENT.VARIABLE"),
        ({"grid": {"a.b": {"start": 0, "stop": 1}}}, "grid 'a.b': a range needs exactly start, stop and num"),
        ({"grid": {"a.b": [1, "x"]}}, "grid 'a.b'[1]: expected a finite number"),
        (
            {"grid": {"a.b": [1]}, "sample": {"n": 3, "seed": 1, "ranges": {"a.b": [0, 1]}}},
            "'a.b' varies in two",
        ),
        ({"sample": {"n": 3, "ranges": {"a.b": [0, 1]}}}, "seed must be a non-negative integer"),
        ({"sample": {"n": 3, "seed": 1, "ranges": {"a.b": [1, 0]}}}, "low must be below high"),
        (
            {"sample": {"method": "sobol", "n": 3, "seed": 1, "ranges": {"a.b": [0, 1]}}},
            "method must be 'lhs'",
        ),
        ({"fixed": {"a.b": 1}, "grid": {"a.b": [1]}}, "'a.b' is both fixed and varied"),
        ({"step": 0}, "step must be positive"),
        ({"plots": [{"kind": "pie"}]}, "plots[0].kind must be one of"),
        ({"table": {"file": "missing.csv"}}, "[table]: cannot read"),
    ],
)
def test_bad_designs_fail_with_one_line_naming_the_file(tmp_path: Path, data: dict, message: str) -> None:
    path = write(tmp_path, data)
    with pytest.raises(DesignError) as info:
        read_design(path)
    text = str(info.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text


def test_unreadable_design(tmp_path: Path) -> None:
    (tmp_path / "d.toml").write_text("grid = [", encoding="utf-8")
    with pytest.raises(DesignError, match=r"d\.toml: not valid TOML"):
        read_design(tmp_path / "d.toml")
    with pytest.raises(DesignError, match="cannot read the design"):
        read_design(tmp_path / "absent.toml")


@pytest.mark.parametrize("name, data", [
    ("runs.csv", b"\xde\xad\xbe\xef" * 100),  # not UTF-8
    ("runs.csv", b"a,b\n1,2\n"),  # a CSV, not a campaign table
    ("runs.csv", b""),
    ("runs.parquet", b"PAR1 not really"),
])
def test_campaign_report_on_a_file_that_is_no_campaign_table_is_one_line(tmp_path, capsys, name, data):
    """main (third attack): ``campaign-report`` on bytes that are not UTF-8 was a UnicodeDecodeError
    traceback, and a CSV without the table's columns a KeyError one."""
    from orchestrator.cli import main

    table = tmp_path / name
    table.write_bytes(data)
    with pytest.raises(SystemExit) as info:
        main(["campaign-report", str(table), "--out", str(tmp_path / "report")])
    assert info.value.code == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("usage:")]
    assert len(errors) == 1 and errors[0].startswith(f"orchestrate: error: {table}: not a campaign table")
    assert not (tmp_path / "report").exists()
