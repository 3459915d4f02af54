# SPDX-License-Identifier: BSD-2-Clause
"""The SSD's own algorithm annotation chooses the default master (issue 43).

The OSP demo case dp-ship (``tests/ssp_conformance/osp-demo-cases``, written for libcosim, MIT)
declares libcosim's ``osp:FixedStepAlgorithm``. Before issue 43 it ran under gauss-seidel, so the
thrust allocation's ``Fxg`` stayed 0 for the whole run where libcosim gives 0.2 from t = 0.04.
Oracle: libcosim (libcosimpy) running the same file: every output equal at every communication
point, bit for bit, under the default master (an input libcosim reports at t is the one used in
the step ending at t; ours at t is the one transferred at t). ``--master`` still overrides, and
``inspect`` and the provenance say which master and why.
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from ssp_conformance.conformance import HERE, libcosim_series

import orchestrator
from orchestrator import RunOptions
from orchestrator.inspection import inspect_scenario

pytestmark = [pytest.mark.system, pytest.mark.filterwarnings("ignore::orchestrator.errors.ScenarioWarning")]
DP_SHIP = HERE / "osp-demo-cases" / "dp-ship"
LIBCOSIM_DEMO = HERE / "libcosim" / "ssp" / "demo"
OMS_CASE = HERE / "omsimulator" / "toplevelparameter1"
FXG = "Thrust Allocation.Fxg"


def test_dp_ship_runs_libcosims_algorithm_by_default_and_agrees_with_libcosim() -> None:
    pytest.importorskip("libcosimpy")
    result = orchestrator.run(DP_SHIP, RunOptions(stop_time=1.0))
    assert result.provenance["master"] == "jacobi"
    assert "libcosim's osp:FixedStepAlgorithm" in str(result.provenance["master_from"])
    rows = result.rows
    assert rows[FXG][0] == 0.0 and (rows[FXG][1:] == 0.2).all()  # the README's thrust command
    with orchestrator.open_system(DP_SHIP) as system:
        outputs = [f"{n}.{o}" for n, c in system.components.items() for o in c.outputs]
        inputs = [f"{n}.{i}" for n, c in system.components.items() for i in c.inputs]
    theirs = libcosim_series(DP_SHIP, 1.0, outputs + inputs)
    assert len(theirs["time"]) == len(rows) == 26
    for name in outputs:
        assert (np.array(theirs[name]) == rows[name]).all(), name
    for name in inputs:
        assert (np.array(theirs[name][2:]) == rows[name][1:-1]).all(), name


def test_master_option_overrides_the_files_algorithm() -> None:
    """Gauss-Seidel on dp-ship: the loop through the thrust allocation is iterated at every point,
    and Fxg stays 0 (what main gave before issue 43); the provenance names the option."""
    result = orchestrator.run(DP_SHIP, RunOptions(stop_time=0.2, master="gauss-seidel"))
    assert result.provenance["master"] == "gauss-seidel" and result.provenance["master_from"] == "master"
    assert (result.rows[FXG] == 0.0).all()


def test_inspect_names_the_master_and_why(tmp_path: Path) -> None:
    def master(scenario: Path, **kwargs: object) -> tuple[str, str]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            timing = inspect_scenario(scenario, **kwargs).timing  # type: ignore[arg-type]
        return next((value, origin) for what, value, origin in timing if what == "master")

    osp = master(LIBCOSIM_DEMO, root=HERE / "libcosim")
    assert osp[0] == "jacobi" and "osp:FixedStepAlgorithm" in osp[1]
    oms = master(OMS_CASE)
    assert oms[0] == "gauss-seidel" and "OMSimulator's oms:FixedStepMaster" in oms[1]
    ssd = (OMS_CASE / "SystemStructure.ssd").read_text()
    start = ssd.index("<ssd:Annotations>")
    plain = tmp_path / "plain"
    plain.mkdir()
    for path in OMS_CASE.rglob("*"):
        if path.is_file():
            target = plain / path.relative_to(OMS_CASE)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(path.read_bytes())
    (plain / "SystemStructure.ssd").write_text(ssd[:start] + ssd[ssd.index("</ssd:Annotations>") + 18:])
    assert master(plain) == ("gauss-seidel", "the default (the SSD names no algorithm)")


def test_cli_run_records_the_master_in_the_provenance(tmp_path: Path) -> None:
    out = tmp_path / "dp.csv"
    command = [str(Path(sys.executable).parent / "orchestrate"), "run", str(DP_SHIP), "--stop-time", "0.2",
               "--output", str(out), "--no-plot"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    record = json.loads(Path(f"{out}.json").read_text())
    assert record["master"] == "jacobi" and "osp:FixedStepAlgorithm" in record["master_from"]
