# SPDX-License-Identifier: BSD-2-Clause
"""All five FMUs in one process (one shared interpreter and module cache): a closed loop driven
through fmpy's FMI API against an independent monolithic oracle, a libcosim run of the same
loop, and two builds of one FMU from different sources that must not see each other's modules."""

from __future__ import annotations

import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from fmu_helpers import (
    example1,
    libcosim_add,
    libcosim_execution,
    open_slaves,
    pendulum,
    reference_formula,
    solve_held,
    uf_formula,
)

from controller.params import ControllerParameters
from controller.stepping import AdaptiveController
from fmu_src.toolchain.build import REPO_ROOT, build_fmu

pytestmark = pytest.mark.system

H = 1e-3
ACTUATOR = {
    "m_r": 1.0,
    "m_l": 1.2,
    "b_r": 0.5,
    "b_l": 0.6,
    "K_inf": 0.4,
    "K_amp": 0.6,
    "K_rate": 0.2,
    "L_gain": 1.0,
    "L_bias": 0.0,
    "t_fault": 0.1,
}  # fault early, inside the short run
EXAMPLE1 = dict(k=(10, 10), q=(8, 8), a=(5, 2), kappa=(2, 2), rho=(2, 2), rho_bar=(1, 1))


def test_closed_loop_of_all_five_in_one_process(fmus: dict) -> None:
    """Example 1 loop (reference -> controller -> actuator -> plant, outputs propagated at t_k
    before doStep) plus the pendulum plant driven by the same uf, against the controller library,
    the SPEC actuator formula and solve_ivp."""
    n = 300
    paths = {
        name: fmus[model]
        for name, model in [
            ("reference", "Reference"),
            ("controller", "FixedTimeController"),
            ("actuator", "Actuator"),
            ("plant", "Example1Plant"),
            ("pendulum", "PendulumPlant"),
        ]
    }
    x_plant = np.empty((n + 1, 3))
    x_pendulum = np.empty((n + 1, 3))
    v_seen, uf_seen = np.empty(n), np.empty(n)
    with open_slaves(paths) as s:
        for name, slave in s.items():
            slave.initialize(**({"t_fault": ACTUATOR["t_fault"]} if name == "actuator" else {}))
        for k in range(n):
            t = k * H
            yd = s["reference"].get("yd", "yd_dot", "yd_ddot")
            x1, x2, z = x_plant[k] = s["plant"].get("x1", "x2", "z")
            x_pendulum[k] = s["pendulum"].get("x1", "x2", "z")
            s["controller"].set(x1=x1, x2=x2, yd=yd[0], yd_dot=yd[1], yd_ddot=yd[2])
            [v_seen[k]] = s["controller"].get("v")
            s["actuator"].set(v=v_seen[k], x1=x1, x2=x2)
            [uf_seen[k]] = s["actuator"].get("uf")
            s["plant"].set(uf=uf_seen[k])
            s["pendulum"].set(uf=uf_seen[k])
            for slave in s.values():
                slave.step(t, H)
        x_plant[n] = s["plant"].get("x1", "x2", "z")
        x_pendulum[n] = s["pendulum"].get("x1", "x2", "z")

    # the oracle, step by step on the FMUs' own signals: controller library, SPEC actuator, solve_ivp
    controller = AdaptiveController(ControllerParameters(**EXAMPLE1))
    for k in range(n):
        t = k * H
        yd = reference_formula(t, 0.5, 1.0, 0.0, 0.0)
        assert controller.output(x_plant[k, :2], yd).v == pytest.approx(v_seen[k], rel=1e-10, abs=1e-12)
        controller.advance(x_plant[k, :2], yd, H)
        assert uf_formula(t, v_seen[k], *x_plant[k, :2], ACTUATOR) == pytest.approx(
            uf_seen[k], rel=1e-12, abs=1e-12
        )
        x_next = solve_held(example1, t, x_plant[k], [uf_seen[k]], H)[0]
        np.testing.assert_allclose(x_plant[k + 1], x_next, rtol=0, atol=1e-9)
    assert np.max(np.abs(v_seen)) > 500  # the huge initial control of SPEC section 6
    assert np.any(uf_seen != v_seen)  # the fault is active after t_fault
    pendulum_oracle = solve_held(pendulum, 0.0, (0.6, 0.1, 0.0), uf_seen, H)
    np.testing.assert_allclose(x_pendulum[1:], pendulum_oracle, rtol=0, atol=1e-7)


def test_all_five_in_libcosim(fmus: dict) -> None:
    """libcosim runs the wired loop (its own step order); the run succeeds and stays finite."""
    from libcosimpy.CosimObserver import CosimObserver

    execution = libcosim_execution(H)
    ids = {}
    for name, model in [
        ("reference", "Reference"),
        ("controller", "FixedTimeController"),
        ("actuator", "Actuator"),
        ("plant", "Example1Plant"),
        ("pendulum", "PendulumPlant"),
    ]:
        ids[name] = libcosim_add(execution, fmus[model], name)
    wires = [
        ("reference", "yd", "controller", "yd"),
        ("reference", "yd_dot", "controller", "yd_dot"),
        ("reference", "yd_ddot", "controller", "yd_ddot"),
        ("plant", "x1", "controller", "x1"),
        ("plant", "x2", "controller", "x2"),
        ("controller", "v", "actuator", "v"),
        ("plant", "x1", "actuator", "x1"),
        ("plant", "x2", "actuator", "x2"),
        ("actuator", "uf", "plant", "uf"),
        ("actuator", "uf", "pendulum", "uf"),
    ]
    for a, out, b, inp in wires:
        execution.connect_real_variables(ids[a][0], ids[a][1][out], ids[b][0], ids[b][1][inp])
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.step(100)
    yd = observer.last_real_values(ids["reference"][0], [ids["reference"][1]["yd"]])
    assert yd[0] == pytest.approx(0.5 * math.sin(0.1), abs=1e-14)
    for name in ("plant", "pendulum"):
        index, refs = ids[name]
        values = observer.last_real_values(index, [refs["x1"], refs["x2"], refs["z"]])
        assert all(math.isfinite(value) for value in values)
        assert values[2] != 0.0  # z moved away from z(0) = 0


def test_two_builds_of_a_module_do_not_shadow_each_other(fmus: dict, tmp_path: Path) -> None:
    """Reference built from sources whose models.reference.reference_derivatives adds 1 to yd, and
    so does its compiled refresh (models/_signals.c, an extension module of the same name as the
    original's), loaded next to the original: each instance uses its own bundled modules."""
    root = tmp_path / "src"
    for package in ("fmu_src", "controller"):
        shutil.copytree(REPO_ROOT / package, root / package, ignore=shutil.ignore_patterns("__pycache__"))
    models = root / "fmu_src" / "models" / "reference.py"
    models.write_text(
        models.read_text()
        + "\n\n_original = reference_derivatives\n\n\n"
        + "def reference_derivatives(t, p):\n    yd, *rest = _original(t, p)\n    return (yd + 1.0, *rest)\n"
    )
    compiled = root / "fmu_src" / "models" / "_signals.c"
    source = compiled.read_text()
    assert source.count("        a * s + offset,\n") == 1
    compiled.write_text(source.replace("        a * s + offset,\n", "        a * s + offset + 1.0,\n"))
    changed = build_fmu("Reference", tmp_path / "changed", root=root)
    with open_slaves({"original": fmus["Reference"], "changed": changed}) as s:
        for slave in s.values():
            slave.initialize()
        for k in range(5):
            expected = reference_formula(k * H, 0.5, 1.0, 0.0, 0.0)
            assert s["original"].get("yd", "yd_dot") == pytest.approx(expected[:2], abs=1e-15)
            assert s["changed"].get("yd", "yd_dot") == pytest.approx(
                (expected[0] + 1.0, expected[1]), abs=1e-15
            )
            for slave in s.values():
                slave.step(k * H, H)
    bundles = {name.split(".")[0] for name in sys.modules if name.startswith("_ftc_reference_")}
    assert len(bundles) == 2
