# SPDX-License-Identifier: BSD-2-Clause
"""metrics and compare on any grid and any scenario, and results other tools wrote (issue 22).

Each test failed before its fix. Oracles: hand-made signals with known deviations (a constant
offset, a sine sampled on two grids), the metrics' definitions (SPEC section 4: RAE of y = 2 yd is
sqrt(sum yd^2 / sum 4 yd^2) = 0.5), OMSimulator's CSV layout (quoted names
``<model>.<system>.<component>.<variable>``, one row per event iteration), and the model
descriptions' units.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.master import time_grid
from orchestrator.results import read_result


def write(path: Path, columns: dict[str, np.ndarray], record: dict | None = None) -> Path:
    names = list(columns)
    rows = zip(*(columns[n].tolist() for n in names), strict=True)
    path.write_text(",".join(names) + "\n" + "".join(",".join(map(repr, r)) + "\n" for r in rows))
    if record is not None:
        path.with_name(path.name + ".json").write_text(json.dumps(record))
    return path


def usage_error(argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    return capsys.readouterr().err


T = time_grid(0.0, 1.0, 0.001)
S = np.sin(2 * np.pi * T)  # range 2: the default tube (1 % of range) is +-0.02


def test_compare_tol_both_tightens_and_widens(tmp_path, capsys):
    """Before: --tol s=1e-3 kept the 1 % of range (0.02) tube, and a misspelled signal was accepted."""
    baseline = write(tmp_path / "b.csv", {"time": T, "s": S})
    near = write(tmp_path / "near.csv", {"time": T, "s": S + 2e-3})
    far = write(tmp_path / "far.csv", {"time": T, "s": S + 0.1})
    assert main(["compare", str(near), str(baseline)]) == 0
    assert main(["compare", str(near), str(baseline), "--tol", "s=1e-3"]) == 1  # tighter than 1 % of range
    assert main(["compare", str(far), str(baseline)]) == 1
    assert main(["compare", str(far), str(baseline), "--tol", "s=0.2"]) == 0  # wider
    capsys.readouterr()
    err = usage_error(["compare", str(near), str(baseline), "--tol", "plant.s=1e-3"], capsys)
    assert "--tol: no signal plant.s in" in err and "(signals: s)" in err


def test_compare_a_decimated_run_with_its_full_rate_copy(tmp_path, capsys):
    """Before: a result written every 50 ms was interpolated linearly onto the baseline's 1 ms grid,
    and a fast signal compared with its own full-rate copy was a REGRESSION."""
    fast = np.sin(40 * T)
    baseline = write(tmp_path / "b.csv", {"time": T, "s": fast})
    every = slice(None, None, 50)
    decimated = write(tmp_path / "r.csv", {"time": T[every], "s": fast[every]})
    assert main(["compare", str(decimated), str(baseline)]) == 0
    out = capsys.readouterr().out
    assert "PASS: 1 of 1 signals inside their tubes at the 21 times both have" in out


def test_compare_runs_of_different_lengths_compares_what_both_have(tmp_path, capsys):
    """Before: 'REGRESSION: 0 of 0 signals inside their tubes'."""
    baseline = write(tmp_path / "b.csv", {"time": T, "s": S})
    half = T <= 0.5
    short = write(tmp_path / "r.csv", {"time": T[half], "s": S[half] + 0.5 * (T[half] > 0.25)})
    assert main(["compare", str(short), str(baseline)]) == 1
    out = capsys.readouterr().out
    assert "r.csv covers t = 0 .. 0.5 s but" in out
    assert ("REGRESSION: 0 of 1 signals inside their tubes at the baseline's 501 times; 1 problem(s) above"
            in out)


def test_metrics_on_the_signals_a_users_scenario_names(tmp_path, capsys):
    result = write(tmp_path / "mine.csv", {"time": T, "mass.x": 2 * (1 + S), "source.x_ref": 1 + S})
    capsys.readouterr()
    assert main(["metrics", str(result), "--signal", "mass.x", "--reference", "source.x_ref"]) == 0
    row = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| mine |")][0]
    assert row.split("|")[2].strip() == "0.5"  # RAE of y = 2 yd
    assert main(["metrics", str(result)]) == 1
    assert "no column plant.y, reference.yd (choose with --signal and --reference; columns: mass.x, " \
        "source.x_ref)" in capsys.readouterr().err


def test_metrics_refuse_a_result_written_on_a_coarser_grid_than_its_run(tmp_path, capsys):
    """Before: --output-interval 0.05 turned example1's RAE 0.0331 into 0.0575 without a word."""
    every = slice(None, None, 50)
    record = {"step": 0.001, "output": {"format": ".csv", "variables": [], "interval": 0.05, "left_out": []},
              "status": "complete", "stop_time": 1.0}
    columns = {"time": T[every], "plant.y": S[every], "reference.yd": S[every]}
    result = write(tmp_path / "r.csv", columns, record)
    err = usage_error(["metrics", str(result)], capsys)
    assert "written every 0.05 s (--output-interval) of a run at 0.001 s: the metrics need every step" in err


def test_a_result_omsimulator_wrote_is_read_by_metrics_and_compare(tmp_path, capsys):
    """Before: 'not a result CSV (could not convert string to float...)'. The layout of
    OMSimulator 3's --resultFile: quoted qualified names, blanks, a row per event iteration."""
    t = [0.0, 0.001, 0.001, 0.002, 0.002]
    y = [0.5, 0.4, 0.49, 0.3, 0.48]
    text = '"time","m.root.plant.y","m.root.reference.yd"\n' + "".join(
        f"{a}, {b}, {c}\n" for a, b, c in zip(t, y, [0.0, 0.0, 0.0, 0.0, 0.0], strict=True))
    (tmp_path / "oms.csv").write_text(text)
    data = read_result(tmp_path / "oms.csv")
    assert data.dtype.names == ("time", "plant.y", "reference.yd")
    assert data["time"].tolist() == [0.0, 0.001, 0.002] and data["plant.y"].tolist() == [0.5, 0.49, 0.48]
    assert main(["metrics", str(tmp_path / "oms.csv")]) == 0
    ours = write(tmp_path / "ours.csv", {"time": np.array([0.0, 0.001, 0.002]),
                                         "plant.y": np.array(y)[[0, 2, 4]], "reference.yd": np.zeros(3)})
    assert main(["compare", str(tmp_path / "oms.csv"), str(ours)]) == 0


@pytest.mark.system
def test_a_mat_result_carries_descriptions_and_units(built, tmp_path):
    from scipy.io import loadmat

    out = tmp_path / "p.mat"
    assert main(["run", str(built / "ssp" / "pendulum.ssp"), "--stop-time", "0.01", "--quiet", "--no-plot",
                 "--output", str(out)]) == 0
    mat = loadmat(out, chars_as_strings=False)
    names = ["".join(mat["name"][:, j]).strip() for j in range(mat["name"].shape[1])]
    descriptions = ("".join(mat["description"][:, j]).strip() for j in range(len(names)))
    texts = dict(zip(names, descriptions, strict=True))
    assert texts["time"] == "Simulation time [s]"
    assert texts["plant.y"].endswith("[rad]") and texts["plant.x2"].endswith("[rad/s]")
    assert len(texts["plant.y"]) > len(" [rad]")  # the FMU's description before the unit
