# SPDX-License-Identifier: BSD-2-Clause
"""compare's own behaviour on hand-made CSVs: tubes, times and sizes of excursions, missing columns,
exit codes, tolerance files; and the shape of the stored baselines."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from orch_helpers import BASELINE_DIR

from orchestrator.cli import main
from orchestrator.master import time_grid
from orchestrator.regress.tubes import (
    BASELINE_GRID,
    RegressionError,
    Tolerance,
    Tolerances,
    compare,
    compare_files,
    format_comparison,
    load_tolerances,
    write_baseline,
)
from orchestrator.results import ResultFileError, read_result


def table(t: np.ndarray, **columns: np.ndarray) -> np.ndarray:
    data = np.zeros(len(t), dtype=[("time", float)] + [(n.replace("__", "."), float) for n in columns])
    data["time"] = t
    for name, values in columns.items():
        data[name.replace("__", ".")] = values
    return data


def write(path: Path, data: np.ndarray) -> Path:
    names = data.dtype.names
    lines = [",".join(names)] + [",".join(repr(float(v)) for v in row) for row in data.tolist()]
    path.write_text("\n".join(lines) + "\n")
    return path


T = time_grid(0.0, 10.0, 0.01)
TUBE = Tolerances({"p.y": Tolerance(atol=0.1), "p.u": Tolerance(atol=0.1)})


def test_identical_signal_passes() -> None:
    base = table(T, p__y=np.sin(T), p__u=np.cos(T))
    result = compare(base.copy(), base, TUBE)
    assert result.passed
    assert [c.name for c in result.checks] == ["p.y", "p.u"]
    assert all(c.max_deviation == 0 for c in result.checks)


def test_step_beyond_the_tube_fails_with_its_time_and_size() -> None:
    base = table(T, p__y=np.sin(T), p__u=np.cos(T))
    stepped = base.copy()
    stepped["p.y"] = np.where(T >= 4.0, np.sin(T) + 0.5, np.sin(T))
    result = compare(stepped, base, TUBE)
    assert not result.passed
    [bad] = result.failed
    assert bad.name == "p.y"
    assert bad.first_out == 4.0
    assert bad.worst_excess == pytest.approx(0.4, abs=1e-12)  # 0.5 step minus the 0.1 tube
    assert bad.max_deviation == pytest.approx(0.5, abs=1e-12)
    assert bad.n_out == np.count_nonzero(T >= 4.0)


def test_step_inside_the_tube_passes() -> None:
    base = table(T, p__y=np.sin(T))
    stepped = base.copy()
    stepped["p.y"] += 0.09
    assert compare(stepped, base, TUBE).passed


def test_first_and_last_samples_are_checked() -> None:
    """validate_signal skips the band's end points; compare pads the band so they count."""
    base = table(T, p__y=np.sin(T))
    for index in (0, -1):
        changed = base.copy()
        changed["p.y"][index] += 1.0
        [bad] = compare(changed, base, TUBE).failed
        assert bad.first_out == T[index]
        assert bad.worst_excess == pytest.approx(0.9)


def test_horizontal_tolerance_accepts_a_small_time_shift() -> None:
    base = table(T, p__y=np.where(T >= 5.0, 1.0, 0.0))
    late = table(T, p__y=np.where(T >= 5.02, 1.0, 0.0))
    assert not compare(late, base, Tolerances({"p.y": Tolerance(atol=0.01)})).passed
    assert compare(late, base, Tolerances({"p.y": Tolerance(atol=0.01, dt=0.03)})).passed


def test_quiet_phase_has_its_own_tube() -> None:
    tolerances = Tolerances({"p.y": Tolerance(atol=0.1, quiet_atol=1e-6)}, quiet_until=1.0)
    base = table(T, p__y=np.sin(T))
    early = base.copy()
    early["p.y"][T <= 1.0] += 1e-5
    [bad] = compare(early, base, tolerances).failed
    assert bad.first_out == 0.0
    late = base.copy()
    late["p.y"][T > 1.0] += 0.05
    assert compare(late, base, tolerances).passed


def test_flat_and_zero_signals_get_the_tube_asked_for() -> None:
    """validate_signal would give a flat zero reference a fixed 0.5 band."""
    base = table(T, p__y=np.zeros_like(T), p__u=np.full_like(T, 3.0))
    off = table(T, p__y=np.full_like(T, 0.2), p__u=np.full_like(T, 3.2))
    assert [c.name for c in compare(off, base, TUBE).failed] == ["p.y", "p.u"]


def test_non_finite_result_fails() -> None:
    base = table(T, p__y=np.sin(T))
    broken = base.copy()
    broken["p.y"][500:] = np.nan
    [bad] = compare(broken, base, TUBE).failed
    assert bad.first_out == T[500]
    assert math.isinf(bad.worst_excess)


def test_result_on_a_finer_grid_is_compared_on_the_baseline_grid() -> None:
    fine = time_grid(0.0, 10.0, 0.001)
    coarse = table(T, p__y=np.sin(T))
    assert compare(table(fine, p__y=np.sin(fine)), coarse, TUBE).passed


def test_missing_columns_short_results_and_extra_columns() -> None:
    """A baseline column the result lacks is listed, and fails only when chosen (issue 36)."""
    base = table(T, p__y=np.sin(T), p__u=np.cos(T))
    partial = table(T, p__y=np.sin(T), p__extra=np.ones_like(T))
    result = compare(partial, base, TUBE, "r.csv", "b.csv")
    assert result.passed
    assert result.missing == ["p.u"] and result.lost == []
    assert result.extra == ["p.extra"]
    assert [c.name for c in result.checks] == ["p.y"]
    assert "missing in r.csv (not compared): p.u" in format_comparison(result)
    assert "PASS: 1 of 1 signals" in format_comparison(result)
    chosen = compare(partial, base, TUBE, "r.csv", "b.csv", signals=["p.y", "p.u"])
    assert not chosen.passed and chosen.lost == ["p.u"]
    assert "missing in r.csv (required): p.u" in format_comparison(chosen)
    assert compare(partial, base, TUBE, signals=["p.y"]).passed
    with pytest.raises(RegressionError, match="b.csv: no column p.z"):
        compare(partial, base, TUBE, "r.csv", "b.csv", signals=["p.z"])
    nothing = compare(table(T, p__other=np.sin(T)), base, TUBE, "r.csv", "b.csv")
    assert not nothing.passed
    assert "r.csv has none of the 2 signal(s) of b.csv: nothing compared" in nothing.problems
    short = compare(base[:500], base, TUBE, "r.csv", "b.csv")
    assert not short.passed
    assert "r.csv covers t = 0 .. 4.99 s but b.csv runs over t = 0 .. 10 s" in short.problems[0]


def test_command_exit_status_table_and_plots(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    base = table(T, p__y=np.sin(T), p__u=np.cos(T))
    (tmp_path / "tolerances.json").write_text(json.dumps(
        {"signals": {"p.y": {"atol": 0.1, "reason": "test"}, "p.u": {"atol": 0.1}}}))
    baseline = write(tmp_path / "base.csv", base)
    same = write(tmp_path / "same.csv", base)
    assert main(["compare", str(same), str(baseline)]) == 0
    assert "PASS: 2 of 2 signals" in capsys.readouterr().out

    stepped = base.copy()
    stepped["p.y"] = np.where(T >= 4.0, np.sin(T) + 0.5, np.sin(T))
    bad = write(tmp_path / "bad.csv", stepped)
    plots = tmp_path / "plots"
    assert main(["compare", str(bad), str(baseline), "--plot-dir", str(plots)]) == 1
    out = capsys.readouterr().out
    assert "| p.y | 0.1 | 4.000 |" in out
    assert "REGRESSION: 1 of 2 signals" in out
    assert (plots / "p.y.png").stat().st_size > 1000
    assert not (plots / "p.u.png").exists()
    # a wider tube given on the command line accepts the step
    assert main(["compare", str(bad), str(baseline), "--tol", "p.y=0.6"]) == 0

    missing = write(tmp_path / "missing.csv", table(T, p__y=np.sin(T)))
    assert main(["compare", str(missing), str(baseline)]) == 0
    assert "missing in" in capsys.readouterr().out
    assert main(["compare", str(missing), str(baseline), "--signal", "p.*"]) == 1
    assert f"missing in {missing} (required): p.u" in capsys.readouterr().out
    assert exit_status(["compare", str(missing), str(baseline), "--signal", "q.*"]) == 2
    assert "--signal: no signal of" in capsys.readouterr().err


def exit_status(argv: list[str]) -> int:
    """``orchestrate ARGV``'s exit status, whether returned or raised by argparse (usage errors)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def test_command_errors_name_the_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    baseline = write(tmp_path / "base.csv", table(T, p__y=np.sin(T)))
    assert exit_status(["compare", str(tmp_path / "nope.csv"), str(baseline)]) == 2
    assert "nope.csv: no such file" in capsys.readouterr().err
    no_time = tmp_path / "no_time.csv"
    no_time.write_text("t,p.y\n0,1\n1,2\n")
    assert exit_status(["compare", str(no_time), str(baseline)]) == 2
    assert "no_time.csv: no 'time' column" in capsys.readouterr().err
    garbage = tmp_path / "garbage.csv"
    garbage.write_text("time,p.y\n0,abc\n")
    assert exit_status(["compare", str(garbage), str(baseline)]) == 2
    assert "garbage.csv: not a result CSV" in capsys.readouterr().err
    backwards = tmp_path / "backwards.csv"
    backwards.write_text("time,p.y\n0,1\n1,2\n0.5,3\n")
    with pytest.raises(ResultFileError, match="backwards.csv: column 'time' does not increase at line 4"):
        read_result(backwards)
    assert exit_status(["compare", str(baseline), str(baseline), "--tol", "p.y=wide"]) == 2
    assert "'wide' is not a number" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["compare", str(baseline)])


def test_tolerance_file_errors_name_file_and_signal(tmp_path: Path) -> None:
    path = tmp_path / "tol.json"
    path.write_text(json.dumps({"signals": {"p.y": {"atol": -1}}}))
    with pytest.raises(RegressionError, match=r"tol.json: signal 'p.y': tolerance atol must be"):
        load_tolerances(path)
    path.write_text(json.dumps({"signals": {"p.y": {"abs": 1}}}))
    with pytest.raises(RegressionError, match=r"signal 'p.y': unknown key\(s\) abs"):
        load_tolerances(path)
    path.write_text("{")
    with pytest.raises(RegressionError, match="tol.json: cannot read tolerances"):
        load_tolerances(path)


def test_baseline_writer_round_trips_through_fmpy(tmp_path: Path) -> None:
    base = table(T, p__y=np.sin(T) * 1e-4, p__u=np.cos(T) * 1e4)
    path = write_baseline(base, tmp_path / "b.csv")
    again = read_result(path)
    assert np.array_equal(again["time"], T)
    assert compare_files(path, path, TUBE).passed
    assert np.allclose(again["p.y"], base["p.y"], rtol=1e-8, atol=0)
    assert (path.stat().st_mode & 0o777) != 0o600


def test_stored_baselines_and_tolerances_agree() -> None:
    """Every stored baseline is on the 20 ms grid over 30 s, and every column has its own reasoned tube."""
    tolerances = load_tolerances(BASELINE_DIR / "tolerances.json")
    raw = json.loads((BASELINE_DIR / "tolerances.json").read_text())
    assert all(entry.get("reason") for entry in raw["signals"].values())
    baselines = sorted(BASELINE_DIR.glob("*.csv"))
    assert {p.stem for p in baselines} >= {"example1", "example1_finite_time", "example1_no_fault",
                                             "pendulum", "pendulum_finite_time"}
    for path in baselines:
        data = read_result(path)
        assert np.array_equal(data["time"], time_grid(0.0, 30.0, BASELINE_GRID)), path
        unlisted = [n for n in data.dtype.names[1:] if n not in tolerances.signals]
        assert not unlisted, f"{path}: no tolerance for {unlisted}"


def test_compare_a_column_at_a_time_gives_the_whole_files_verdict(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture) -> None:
    """``orchestrate compare`` reads each file once into a column file per signal and compares a
    signal at a time (issue 44: two 10^6-row files took 833 MB); the oracle is the comparison of
    the whole files as fmpy's reader gives them: the same table, line for line, for a result on
    the baseline's grid, one interpolated onto it, and one on a coarser grid, with a step out of
    its tube, a quiet phase and a time shift accepted; every column read back is fmpy's, bit for bit."""
    from orchestrator.results import open_columns

    rng = np.random.default_rng(44)
    tubes = {"quiet_until": 2.0, "signals": {"p.y": {"atol": 0.05, "quiet_atol": 1e-3, "dt": 0.02},
                                             "p.u": {"rtol": 0.02}}}
    (tmp_path / "tolerances.json").write_text(json.dumps(tubes))
    baseline = write(tmp_path / "base.csv", table(T, p__y=np.sin(T), p__u=np.cos(3 * T), p__v=T ** 2))
    grids = {"same": T, "finer": time_grid(0.0, 10.0, 0.004), "coarser": time_grid(0.0, 10.0, 0.05)}
    for name, t in grids.items():
        y = np.where(t >= 6.0, np.sin(t) + 0.2, np.sin(t + 0.01)) + 1e-4 * rng.standard_normal(len(t))
        result = write(tmp_path / f"{name}.csv", table(t, p__y=y, p__u=np.cos(3 * t), p__w=t))
        folder = tmp_path / f"{name}-columns"
        folder.mkdir()
        columns = open_columns(result, folder)
        whole = read_result(result)
        assert not isinstance(columns, np.ndarray) and columns.dtype.names == whole.dtype.names
        for column in whole.dtype.names:
            assert columns[column].tobytes() == whole[column].tobytes()
        expected = format_comparison(compare_files(result, baseline))
        assert main(["compare", str(result), str(baseline)]) == 1
        out = capsys.readouterr().out
        assert out.split("\n", 2)[2] == expected + "\n", name
        assert "| p.y |" in out and "REGRESSION: 1 of 2 signals" in out


@pytest.mark.parametrize("chunk", [7, 1 << 16])
def test_compare_streamed_a_chunk_at_a_time_gives_the_whole_arrays_figures(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk: int) -> None:
    """Two files on the same uniform grid are compared a chunk of rows at a time (issue 44: memory
    O(columns), not O(rows)); the oracle is the comparison of the whole arrays (fmpy's
    validate_signal tube): every signal's verdict and figures, whether it passes or not, with a
    quiet phase, a time tolerance (the chunks overlap by it), a flat reference, a value that is not
    finite and chunks of 7 rows (every chunk boundary inside a window)."""
    from orchestrator.regress import tubes
    from orchestrator.results import open_columns

    monkeypatch.setattr(tubes, "CHUNK", chunk)
    rng = np.random.default_rng(7)
    shaky = np.sin(T) + 0.04 * rng.standard_normal(len(T))
    broken = np.cos(T)
    broken[500] = np.nan
    reference = table(T, p__y=np.sin(T), p__u=np.cos(3 * T), p__f=np.ones(len(T)), p__n=np.cos(T))
    result = table(T, p__y=shaky, p__u=np.cos(3 * T + 0.03), p__f=np.ones(len(T)) + 1e-4, p__n=broken)
    tolerances = Tolerances({"p.y": Tolerance(atol=0.1, quiet_atol=0.01, dt=0.05),
                             "p.u": Tolerance(rtol=0.02, dt=0.03), "p.f": Tolerance(atol=1e-3),
                             "p.n": Tolerance(atol=0.1)}, quiet_until=1.0)
    files = []
    for name, data in (("result", result), ("baseline", reference)):
        folder = tmp_path / name
        folder.mkdir()
        files.append(open_columns(write(tmp_path / f"{name}.csv", data), folder))
    streamed = compare(*files, tolerances, keep_passed=False)
    whole = compare(result, reference, tolerances)
    assert [c.name for c in streamed.checks] == [c.name for c in whole.checks] == ["p.y", "p.u", "p.f", "p.n"]
    chunked = [tubes._check_streamed(c.name, *files, tolerances.of(c.name), 1.0) for c in whole.checks]
    for mine, theirs in zip(chunked, whole.checks, strict=True):
        assert mine is not None
        assert (mine.n_out, mine.first_out, mine.worst_time) == (theirs.n_out, theirs.first_out,
                                                                theirs.worst_time), mine.name
        for a, b in ((mine.width, theirs.width), (mine.worst_excess, theirs.worst_excess),
                     (mine.max_deviation, theirs.max_deviation)):
            assert a == b or math.isclose(a, b, rel_tol=1e-12), (mine.name, a, b)
    assert [c.passed for c in whole.checks] == [False, True, True, False]  # the cases are real
    assert [c.passed for c in streamed.checks] == [c.passed for c in whole.checks]
    assert streamed.passed == whole.passed and streamed.grid == whole.grid


@pytest.mark.parametrize("chunk", [7, 1 << 16])
def test_compare_merged_on_any_grids_gives_the_whole_arrays_figures(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunk: int) -> None:
    """Two files on different grids (the result interpolated onto the baseline's times, or compared
    at the times both have when its grid is coarser; either grid uniform or not, a result shorter
    than the baseline) are compared a chunk of rows at a time, both files walked together (issue
    44: memory O(columns), not O(rows)). The oracle is the comparison of the whole arrays
    (np.interp, fmpy's validate_signal tube): the grid, the problems and every signal's figures,
    bit for bit, whether it passes or not, with a quiet phase, time tolerances wider than a chunk,
    a flat reference; chunks of 7 rows put a chunk boundary inside every window and make the
    median step's search take several passes."""
    from orchestrator.regress import tubes
    from orchestrator.regress.merged import (
        _check,
        _ends,
        _inside,
        _median_steps,
        _points,
        compare_columns,
        compare_merged,
    )
    from orchestrator.results import open_columns

    monkeypatch.setattr(tubes, "CHUNK", chunk)
    rng = np.random.default_rng(44)
    tolerances = Tolerances({"p.y": Tolerance(atol=0.05, quiet_atol=1e-3, dt=0.02),
                             "p.u": Tolerance(rtol=0.02, dt=0.3), "p.f": Tolerance(atol=1e-3)},
                            quiet_until=2.0)
    bases = {"uniform": T, "jittered": np.sort(np.concatenate(([0.0, 10.0], rng.uniform(0, 10, 900))))}
    results = {"shifted": time_grid(0.0, 10.0, 0.0137), "finer": time_grid(0.0, 10.0, 0.004),
               "coarser": time_grid(0.0, 10.0, 0.05), "short": time_grid(1.0, 8.0, 0.01), "same": T,
               "jittered": np.sort(np.concatenate(([0.0, 10.0], rng.uniform(0, 10, 700))))}
    grids, verdicts = set(), set()
    for base_name, tb in bases.items():
        baseline = table(tb, p__y=np.sin(tb), p__u=np.cos(3 * tb), p__f=np.ones(len(tb)), p__v=tb ** 2)
        for name, t in results.items():
            y = np.where(t >= 6.0, np.sin(t) + 0.2, np.sin(t + 0.01)) + 1e-4 * rng.standard_normal(len(t))
            result = table(t, p__y=y, p__u=np.cos(3 * t), p__f=np.ones(len(t)) + 1e-4 * (t > 5), p__w=t)
            files = []
            for role, data in (("result", result), ("baseline", baseline)):
                folder = tmp_path / f"{base_name}-{name}-{role}"
                folder.mkdir()
                files.append(open_columns(write(tmp_path / f"{base_name}-{name}-{role}.csv", data), folder))
            whole = compare(result, baseline, tolerances)
            merged = compare_merged(*files, tolerances, "result", "baseline", None)
            assert (merged.grid, merged.problems) == (whole.grid, whole.problems), (base_name, name)
            assert compare_columns(*files, tolerances, "result", "baseline").passed == whole.passed
            bare = compare_columns(*files, tolerances, "result", "baseline", failed_arrays=False)
            assert format_comparison(bare) == format_comparison(whole), (base_name, name)  # severity, counts
            assert all(len(c.time) == 0 for c in bare.checks)
            ends, eps = _ends(files[0]), 1e-9 * 10.0
            rows = _inside(files[1], ends[0] - eps, ends[1] + eps)
            steps = _median_steps(_points(*files, "time", rows, "coarser" in whole.grid))
            for theirs in whole.checks:
                points = _points(*files, theirs.name, rows, "coarser" in whole.grid)
                mine = _check(theirs.name, points, tolerances.of(theirs.name), tolerances.quiet_until, steps)
                figures = [(c.n_out, c.first_out, c.worst_time, c.width, c.worst_excess, c.max_deviation)
                           for c in (mine, theirs)]
                assert figures[0] == figures[1], (base_name, name, theirs.name)
                verdicts.add(theirs.passed)
            grids.add(whole.grid.partition(" (")[2] or "rows")
    assert verdicts == {True, False}  # the cases are real: signals inside and outside their tubes
    assert grids == {"rows", "the result's grid is coarser)", "the result interpolated)"}


@pytest.mark.parametrize("block", [1, 50, 1 << 20])
def test_columns_parsed_a_block_at_a_time_are_fmpys(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    block: int) -> None:
    """Each block of lines is parsed on its own (issue 44: pyarrow's streaming reader kept memory that
    grew with the file); the oracle is fmpy's reader of the whole file: every column bit for bit,
    with blocks of 1 and 50 bytes (every line cut across blocks), CRLF line ends and a last line
    without its line end."""
    from orchestrator import results

    monkeypatch.setattr(results, "CSV_BLOCK", block)
    rng = np.random.default_rng(5)
    data = table(T[:300], p__y=rng.standard_normal(300), p__u=np.exp(rng.standard_normal(300) * 30))
    text = write(tmp_path / "r.csv", data).read_text().replace("\n", "\r\n").rstrip("\r\n")
    (tmp_path / "r.csv").write_bytes(text.encode())
    (tmp_path / "columns").mkdir()
    columns = results.open_columns(tmp_path / "r.csv", tmp_path / "columns")
    whole = read_result(tmp_path / "r.csv")
    assert isinstance(columns, results.Columns) and len(columns) == 300
    for name in whole.dtype.names:
        assert columns[name].tobytes() == whole[name].tobytes() == data[name].tobytes(), name


def test_a_wide_file_streams_and_its_columns_are_fmpys(tmp_path: Path) -> None:
    """A header above 64 KiB (4,000 columns, 72 KB) is read whole: before, such a file fell back to
    read_result, the whole file in memory; the oracle is fmpy's reader, every column bit for bit."""
    from orchestrator import results

    rng = np.random.default_rng(7)
    data = table(T[:20], **{f"c{k:04d}__signal_{k:04d}": rng.standard_normal(20) for k in range(4000)})
    path = write(tmp_path / "wide.csv", data)
    assert len(path.read_bytes().split(b"\n", 1)[0]) > 1 << 16
    (tmp_path / "columns").mkdir()
    columns = results.open_columns(path, tmp_path / "columns")
    whole = read_result(path)
    assert isinstance(columns, results.Columns) and len(columns) == 20
    for name in whole.dtype.names:
        assert columns[name].tobytes() == whole[name].tobytes(), name
