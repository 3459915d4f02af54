# SPDX-License-Identifier: BSD-2-Clause
"""The controller FMUs for plant orders 1..4 (issue 35): each one against the controller library of the
same order (controller.stepping.AdaptiveController, the Python reference) on the same input sequence,
bit for bit; and what does not fit is refused with one line: an order without an FMU, a scenario that
wires a plant of order 3 to the controller of order 2."""

from __future__ import annotations

import math
import shutil
import struct
from pathlib import Path

import pytest
from fmu_helpers import open_slave

from controller.params import ControllerParameters
from controller.stepping import AdaptiveController
from fmu_src.controller_core import controller_model
from fmu_src.toolchain.__main__ import main as build_main
from orchestrator.cli import main as orchestrate

REPO = Path(__file__).resolve().parent.parent
DERIVATIVES = ("yd", "yd_dot", "yd_ddot", "yd_dddot", "yd_ddddot")


def library(n: int, **changes: object) -> AdaptiveController:
    """The FMU's defaults for order n (Example 1's gains, steps beyond 2 as step 2), in the library."""
    a = (5.0, *[2.0] * (n - 1))
    params = ControllerParameters(k=(10.0,) * n, q=(8.0,) * n, a=a, kappa=(2.0,) * n, rho=(2.0,) * n,
                                  rho_bar=(1.0,) * n).with_changes(**changes)
    return AdaptiveController(params)


@pytest.mark.system
@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("discretization", [0, 1])
def test_controller_of_order_n_is_the_librarys_law_bit_for_bit(fmus: dict, n: int,
                                                                discretization: int) -> None:
    """500 steps of 1 ms under inputs that change every step (large early errors, |v| in the
    thousands for the higher orders): every output read after the inputs are set, and the states after
    each step, equal the library's (the FMU runs the compiled twin of the same arithmetic)."""
    h = 1e-3
    model = controller_model(n)
    reference = library(n, discretization=discretization, b_max=5.0)
    peak = 0.0
    with open_slave(fmus[model]) as slave:
        slave.initialize(discretization=discretization, b_max=5.0)
        for k in range(500):
            t = k * h
            x = [0.8 * math.cos(t + i) + 0.5 * math.exp(-3 * t) for i in range(n)]
            yd = [0.5 * math.sin(t + j * math.pi / 2) for j in range(n + 1)]
            slave.set(**{f"x{i + 1}": x[i] for i in range(n)}, **dict(zip(DERIVATIVES, yd, strict=False)))
            terms = reference.output(x, yd)
            names = ["v", *(f"z{i}" for i in range(1, n + 1)), *(f"zeta{i}" for i in range(1, n))]
            expected = [terms.v, *terms.z, *terms.zeta[:-1]]
            got = slave.get(*names)
            assert [struct.pack("<d", v) for v in got] == [struct.pack("<d", v) for v in expected], (k, names)
            peak = max(peak, abs(terms.v))
            slave.step(t, h)
            reference.advance(x, yd, h)
            assert slave.get("r", *(f"eta{i}_hat" for i in range(1, n + 1))) == reference.state, k
    assert peak > 20  # a transient worth the name (26 for n = 1, up to thousands for n = 4)


def test_orders_without_an_fmu_are_refused_with_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    for n in (0, 5):
        with pytest.raises(ValueError, match=rf"^there is a controller FMU for plant orders n = 1\.\.4 \(got "
                                             rf"n = {n}\); for other orders use the library") as error:
            controller_model(n)
        assert "\n" not in str(error.value)
    with pytest.raises(SystemExit):
        build_main(["/tmp/unused", "--model", "FixedTimeController5"])
    assert "invalid choice: 'FixedTimeController5'" in capsys.readouterr().err


@pytest.mark.system
def test_a_plant_of_order_three_on_the_controller_of_order_two_is_refused(
        built: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The manipulator's scenario with FixedTimeController (n = 2) in place of FixedTimeController3:
    validate and run name the connectors the order-2 controller does not have, before anything runs."""
    folder = tmp_path / "wrong_order"
    shutil.copytree(REPO / "ssp" / "manipulator", folder)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace("FixedTimeController3.fmu", "FixedTimeController.fmu"))
    (folder / "resources").mkdir()
    for fmu in ("Reference", "FixedTimeController", "Actuator", "ManipulatorPlant"):
        shutil.copy(built / "fmus" / f"{fmu}.fmu", folder / "resources" / f"{fmu}.fmu")
    assert orchestrate(["validate", str(folder)]) == 1
    out = capsys.readouterr().out
    for connector in ("x3", "yd_dddot", "z3", "eta3_hat"):
        assert f"component 'controller', connector '{connector}': the FMU has no variable of that name" in out
    assert orchestrate(["run", str(folder), "--output", str(tmp_path / "out.csv")]) != 0
    err = capsys.readouterr().err
    assert "connector 'x3': the FMU has no variable of that name" in err
    assert not (tmp_path / "out.csv").exists()
