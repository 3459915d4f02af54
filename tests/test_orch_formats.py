# SPDX-License-Identifier: BSD-2-Clause
"""Issue 12 part 5: result formats by extension (CSV, Parquet, MAT) and output selection.

Oracles: a CSV written by hand (values known), pyarrow's and scipy's readers, and the MAT file
OMSimulator itself writes for a scenario (the layout Dymola/OpenModelica tools read).
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io as sio
from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.errors import UsageError
from orchestrator.formats import (
    Selection,
    binary_copy_path,
    check_output,
    csv_rows,
    staging_path,
    write_selected,
)

TIMES = [k / 100 for k in range(11)]  # 0 .. 0.1 s, step 0.01 s
OMSIMULATOR = Path(__file__).resolve().parents[2] / "shared" / "tools" / "omsimulator" / "bin" / "OMSimulator"


def _csv(path: Path) -> Path:
    """time, a.x = 2 t, a.u = t^2, b.y = -t (repr'd, exact)."""
    lines = ["time,a.x,a.u,b.y"] + [f"{t!r},{2 * t!r},{t * t!r},{-t!r}" for t in TIMES]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_unknown_extension_and_bad_interval_are_usage_errors():
    """Before: --output r.xlsx (or .mat, .parquet) got CSV text under that name, silently."""
    for name in ("r.xlsx", "r.txt", "r.csv.gz"):
        with pytest.raises(UsageError, match=r"cannot write .* files \(choose \.csv, \.parquet, \.mat;"):
            check_output(name)
    for name in ("r.csv", "r.parquet", "r.MAT", "r"):  # no extension: CSV, as before
        check_output(name)
    with pytest.raises(UsageError, match="not a multiple of the step 0.01 s"):
        check_output("r.csv", 0.01, Selection(interval=0.015))
    check_output("r.csv", 0.01, Selection(interval=0.05))


def test_parquet_with_selection(tmp_path):
    selection = Selection(variables=("a.*",), interval=0.05, drop=("a.u",))
    source = _csv(staging_path(tmp_path / "r.parquet"))
    assert source.name == f"r.parquet.{os.getpid()}.partial.csv"  # this process's own
    out = write_selected(source, tmp_path / "r.parquet", selection)
    table = pq.read_table(out)
    assert table.schema.names == ["time", "a.x"]
    assert table.column("time").to_pylist() == [0.0, 0.05, 0.1]
    assert table.column("a.x").to_pylist() == [0.0, 2 * 0.05, 2 * 0.1]
    assert not source.exists()


def test_csv_selection_in_place_and_unmatched_pattern(tmp_path):
    source = _csv(tmp_path / "r.partial.csv")
    with pytest.raises(UsageError, match="'c.\\*' matches no column"):
        write_selected(source, tmp_path / "r.csv", Selection(variables=("c.*",)))
    out = write_selected(source, tmp_path / "r.csv", Selection(variables=("b.y", "a.u")))
    assert out.read_text().splitlines()[:3] == ["time,a.u,b.y", "0.0,0.0,-0.0", f"0.01,{0.01 * 0.01!r},-0.01"]
    full = _csv(tmp_path / "full.csv")
    assert staging_path(full) == full and write_selected(full, full) == full and full.exists()


def test_mat_is_the_dymola_trajectory_layout(tmp_path):
    out = write_selected(_csv(tmp_path / "r.partial.csv"), tmp_path / "r.mat")
    m = sio.loadmat(out, chars_as_strings=False)
    assert ["".join(row).strip() for row in m["Aclass"]] == ["Atrajectory", "1.1", "", "binTrans"]
    names = ["".join(m["name"][:, j]).strip() for j in range(m["name"].shape[1])]
    assert names == ["time", "a.x", "a.u", "b.y"]
    assert m["dataInfo"].tolist() == [[0, 2, 2, 2], [1, 2, 3, 4], [0, 0, 0, 0], [-1, -1, -1, -1]]
    assert m["data_1"].tolist() == [[0.0, 0.1]]
    assert m["data_2"].shape == (4, 11)
    assert m["data_2"][0].tolist() == TIMES and m["data_2"][2].tolist() == [t * t for t in TIMES]


@pytest.mark.system
@pytest.mark.skipif(not OMSIMULATOR.is_file(), reason="OMSimulator is not installed beside the project")
def test_mat_matches_what_omsimulator_writes(built, tmp_path):
    """The same variables, types and conventions as OMSimulator's own result file of a scenario."""
    theirs = tmp_path / "oms.mat"
    done = subprocess.run([str(OMSIMULATOR), str(built / "ssp" / "example1.ssp"), "--stopTime=0.01",
                           f"--resultFile={theirs}"], cwd=tmp_path, capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin"}, timeout=300)
    assert done.returncode == 0 and theirs.is_file(), done.stdout + done.stderr
    from orchestrator.cli import main

    ours = tmp_path / "r.mat"
    assert main(["run", str(built / "ssp" / "example1.ssp"), "--stop-time", "0.01", "--quiet", "--no-plot",
                 "--output", str(ours)]) == 0
    a, b = sio.loadmat(theirs, chars_as_strings=False), sio.loadmat(ours, chars_as_strings=False)
    assert [k for k in a if not k.startswith("__")] == [k for k in b if not k.startswith("__")]
    for key in ("Aclass", "name", "description", "dataInfo", "data_1", "data_2"):
        assert a[key].dtype == b[key].dtype, key
    assert ["".join(r).strip() for r in a["Aclass"]] == ["".join(r).strip() for r in b["Aclass"]]
    assert a["dataInfo"][:, 0].tolist() == b["dataInfo"][:, 0].tolist()  # time: the abscissa
    their_names = {"".join(a["name"][:, j]).strip().removeprefix("example1.example1.")
                   for j in range(a["name"].shape[1])}
    our_names = ["".join(b["name"][:, j]).strip() for j in range(b["name"].shape[1])]
    assert "plant.y" in our_names and set(our_names) <= their_names | {"time"}
    y = our_names.index("plant.y")
    np.testing.assert_array_equal(b["data_2"][0], np.arange(11) / 1000)
    assert b["data_2"][y][0] == 0.5  # Example 1 starts at x1(0) = 0.5
    assert sorted(p.name for p in tmp_path.glob("r.mat*")) == ["r.mat", "r.mat.json"]  # no staging CSV left


@pytest.mark.system
def test_run_writes_the_format_and_selection_also_for_a_failed_run(test_fmus, tmp_path, capsys):
    """--no-inputs leaves out gain.u and integrator.u (each repeats the output connected to it);
    a run that fails at t = 0.05 s still gives its rows kept, as Parquet."""
    from orch_helpers import loop_scenario

    from orchestrator.cli import main

    loop = loop_scenario(tmp_path / "loop", test_fmus, fail_at=0.05, stop=0.1, step=0.01)
    out = tmp_path / "r.parquet"
    assert main(["run", str(loop), "--quiet", "--no-plot", "--output", str(out), "--no-inputs"]) == 1
    assert "rows kept in" in capsys.readouterr().err
    table = pq.read_table(out)
    assert table.schema.names == ["time", "source.y", "gain.y", "integrator.x"]
    assert table.column("time").to_pylist() == [k / 100 for k in range(6)]
    assert sorted(p.name for p in tmp_path.glob("r.parquet*")) == ["r.parquet", "r.parquet.json"]
    with pytest.raises(SystemExit) as info:
        main(["run", str(loop), "--quiet", "--output", str(tmp_path / "r.xlsx")])
    assert info.value.code == 2 and not (tmp_path / "r.xlsx").exists()


@pytest.mark.system
def test_metrics_plot_and_compare_read_every_format(built, tmp_path, capsys):
    """The same run written as CSV, Parquet and MAT gives the same metrics table and compares equal."""
    from orchestrator.cli import main

    tables = {}
    for suffix in (".csv", ".parquet", ".mat"):
        out = tmp_path / f"r{suffix}"
        assert main(["run", str(built / "ssp" / "example1.ssp"), "--stop-time", "0.1", "--quiet",
                     "--output", str(out), "--plot", str(tmp_path / f"r{suffix}.png")]) == 0
        assert main(["metrics", str(out)]) == 0
        tables[suffix] = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| r |")]
        assert main(["plot", str(out), "--output", str(tmp_path / f"p{suffix}.png")]) == 0
    assert tables[".csv"] == tables[".parquet"] == tables[".mat"]
    assert main(["compare", str(tmp_path / "r.mat"), str(tmp_path / "r.csv")]) == 0
    assert main(["compare", str(tmp_path / "r.parquet"), str(tmp_path / "r.csv")]) == 0


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 6).flatmap(lambda n: st.lists(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=n, max_size=n),
    min_size=1, max_size=20)))
def test_csv_rows_read_back_bit_for_bit(rows):
    """orjson's text of every double (subnormals, -0.0, 1e308, NaN, infinities) read back by
    Python's float() (the oracle) gives the same bits; one line per row."""
    block = np.array(rows, dtype=np.float64)
    text = csv_rows(block).decode("ascii")
    lines = text.split("\n")
    assert lines[-1] == "" and len(lines) == len(rows) + 1
    back = np.array([[float(v) for v in line.split(",")] for line in lines[:-1]])
    nan = np.isnan(block)
    assert np.array_equal(np.isnan(back), nan)
    assert back[~nan].tobytes() == block[~nan].tobytes()  # every other value bit for bit, -0.0 too


def test_staged_csv_converts_from_its_binary_copy_or_from_the_text(tmp_path):
    """Parquet from the float64 copy the master writes beside a staged CSV, and from the CSV alone
    when the copy is missing or does not hold the same rows: the same table either way."""
    staged = _csv(tmp_path / "r.parquet.1.partial.csv")
    values = np.array([[t, 2 * t, t * t, -t] for t in TIMES])
    binary_copy_path(staged).write_bytes(values.tobytes())
    write_selected(staged, tmp_path / "a.parquet")
    assert not staged.exists() and not binary_copy_path(staged).exists()
    staged = _csv(tmp_path / "r.parquet.2.partial.csv")
    binary_copy_path(staged).write_bytes(values[:-1].tobytes())  # a row short (cut by a kill): not used
    write_selected(staged, tmp_path / "b.parquet")
    a, b = pq.read_table(tmp_path / "a.parquet"), pq.read_table(tmp_path / "b.parquet")
    assert a.equals(b) and a["b.y"].to_pylist() == [-t for t in TIMES]


def _recorded(path: Path, rows: np.ndarray, selection: Selection, monkeypatch, count: int | None = None,
              binary: bool = False) -> list[int]:
    """``rows`` (or the first ``count`` of them, as a run that fails) recorded into ``path`` by the
    recorder with the layout of ``selection``; returns the sizes of the blocks it formatted."""
    from orchestrator import results
    from orchestrator.results import Recorder

    formatted: list[int] = []

    def counting(block: np.ndarray) -> bytes:
        formatted.append(len(block))
        return csv_rows(block)

    monkeypatch.setattr(results, "csv_rows", counting)
    names = ["time", "a.x", "a.u", "b.y"]
    columns, interval_ns = selection.layout(names)
    recorder = Recorder(names, len(rows), path, keep=False, flush_rows=32, file_columns=columns,
                        interval_ns=interval_ns, binary_copy=binary)
    for row in rows[:count]:
        recorder.append(row)
    recorder.close()
    return formatted


def test_the_recorder_formats_only_the_selected_rows_and_columns(tmp_path, monkeypatch):
    """Issue 46: --output-interval formatted every row and thinned the CSV when the run ended. The
    recorder now writes only the rows and columns asked for; the oracle is the earlier way, the
    whole CSV thinned by write_selected, for a run that completes and for one cut short."""
    times = np.arange(1001) * 0.001  # t_k = k h as the master computes it, h = 1 ms
    rows = np.column_stack([times, np.sin(times), times ** 2, -np.cos(3 * times)])
    selection = Selection(variables=("a.u", "b.*"), interval=0.05)
    for count in (None, 437):
        full, thinned = tmp_path / f"full{count}.csv", tmp_path / f"thinned{count}.csv"
        _recorded(full, rows, Selection(), monkeypatch, count)
        expected = write_selected(full, tmp_path / f"expected{count}.csv", selection)
        formatted = _recorded(thinned, rows, selection, monkeypatch, count)
        assert thinned.read_bytes() == expected.read_bytes()
        kept = selection.kept(count or len(rows), 0.001)
        assert sum(formatted) == kept == len(thinned.read_text().splitlines()) - 1  # nothing else formatted
    staged = tmp_path / "r.parquet.1.partial.csv"  # another format: the staged CSV and its float64 copy
    _recorded(staged, rows, selection, monkeypatch, binary=True)
    copy = np.fromfile(binary_copy_path(staged)).reshape(-1, 3)
    assert np.array_equal(copy, rows[::50][:, [0, 2, 3]])
    assert staged.read_bytes() == (tmp_path / "expectedNone.csv").read_bytes()


def test_the_null_device_gets_no_formatted_row(tmp_path, monkeypatch):
    """--output /dev/null (how a run writes nothing) formatted every row for nobody."""
    rows = np.column_stack([np.arange(500) * 0.01, np.arange(500.0), np.ones(500), np.zeros(500)])
    assert _recorded(Path(os.devnull), rows, Selection(), monkeypatch) == []


def test_a_run_nobody_plots_keeps_no_preview_but_its_first_and_last_rows(tmp_path):
    """'run --no-plot' folded every block into a plot's preview (0.4 us per step) that nobody
    drew; it keeps the first and last rows now, and the CSV is the same."""
    from orchestrator.results import Recorder

    rows = np.column_stack([np.arange(1000) * 0.01, np.sin(np.arange(1000.0))])
    for count in (1, 2, 999, 1000):
        recorder = Recorder(["time", "x"], 1000, tmp_path / f"r{count}.csv", keep=False, preview=False)
        for row in rows[:count]:
            recorder.append(row)
            assert recorder.result()["x"].tolist() == [rows[0, 1], row[1]][:recorder.count]
        recorder.close()
        assert recorder.result()["time"].tolist() == [rows[0, 0], rows[count - 1, 0]][:count]
        text = (tmp_path / f"r{count}.csv").read_bytes()
        assert text == b"time,x\n" + csv_rows(rows[:count])
