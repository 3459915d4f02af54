# SPDX-License-Identifier: BSD-2-Clause
"""The FixedTimeController FMU against the controller library (controller.stepping) on the same
input sequence: outputs read before each doStep and states after it agree to 1e-12."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmu_helpers import libcosim_add, libcosim_execution, open_slave, reference_formula

from controller.params import ControllerParameters
from controller.stepping import AdaptiveController

pytestmark = pytest.mark.system

H = 1e-3
EXAMPLE1 = dict(k=(10, 10), q=(8, 8), a=(5, 2), kappa=(2, 2), rho=(2, 2), rho_bar=(1, 1))
FINITE_TIME_FMU = {
    "mode": 1,
    "alpha": 1.3,
    "beta": 0.6,
    "k1": 3.0,
    "q2": 5.0,
    "a1": 4.0,
    "rho_bar2": 0.5,
    "eta1_0": 0.2,
    "eta2_0": 0.1,
    "r0": 0.3,
    "mu1": -2.0,
    "mu7": 2.0,
    "tau": 1.5,
    "substeps": 3,
    "gamma_power": 2.0,
}
FINITE_TIME_LIBRARY = dict(
    k=(3, 10),
    q=(8, 5),
    a=(4, 2),
    kappa=(2, 2),
    rho=(2, 2),
    rho_bar=(1, 0.5),
    mode="finite-time",
    alpha=1.3,
    beta=0.6,
    eta0=(0.2, 0.1),
    r0=0.3,
    centers=(-2.0, -1, -0.5, 0, 0.5, 1, 2.0),
    width=1.5,
    gamma_power=2.0,
)


def plant_like_inputs(t: float) -> tuple[tuple[float, float], tuple[float, float, float]]:
    """Inputs with large errors early (|v| in the hundreds) and a smooth part later."""
    x = (0.5 * math.exp(-t) + 0.3 * math.sin(3 * t), 0.5 * math.cos(2 * t) + 0.4 * math.exp(-5 * t))
    return x, reference_formula(t, 0.5, 1.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("fmu_parameters", "library_parameters", "substeps"),
    [({}, EXAMPLE1, 1), (FINITE_TIME_FMU, FINITE_TIME_LIBRARY, 3)],
    ids=["fixed-time-defaults", "finite-time-changed"],
)
def test_controller_matches_library(
    fmus: dict, fmu_parameters: dict, library_parameters: dict, substeps: int
) -> None:
    library = AdaptiveController(ControllerParameters(**library_parameters), substeps=substeps)
    worst = 0.0
    peak_v = 0.0
    with open_slave(fmus["FixedTimeController"]) as slave:
        slave.initialize(**fmu_parameters)
        for k in range(2000):
            t = k * H
            x, yd = plant_like_inputs(t)
            slave.set(x1=x[0], x2=x[1], yd=yd[0], yd_dot=yd[1], yd_ddot=yd[2])
            got = slave.get("v", "z1", "z2", "zeta1", "r", "eta1_hat", "eta2_hat")
            terms = library.output(x, yd)
            expected = [terms.v, *terms.z, terms.zeta[0], *library.state]
            worst = max(worst, max(abs(a - b) / max(1.0, abs(b)) for a, b in zip(got, expected, strict=True)))
            peak_v = max(peak_v, abs(terms.v))
            slave.step(t, H)
            library.advance(x, yd, H)
        assert slave.get("r", "eta1_hat", "eta2_hat") == pytest.approx(library.state, rel=1e-12, abs=1e-12)
    assert worst <= 1e-12
    assert peak_v > 5  # large control effort early, not a trivial run


def test_controller_through_simulate_fmu(fmus: dict) -> None:
    """Constant inputs (start values) over 1 s: every recorded row matches the library."""
    x, yd = (0.8, -0.2), (0.1, 0.4, -0.05)
    inputs = {"x1": x[0], "x2": x[1], "yd": yd[0], "yd_dot": yd[1], "yd_ddot": yd[2]}
    result = simulate_fmu(fmus["FixedTimeController"], stop_time=1.0, output_interval=H, start_values=inputs)
    library = AdaptiveController(ControllerParameters(**EXAMPLE1))
    for row in result:
        terms = library.output(x, yd)
        expected = (
            terms.v,
            terms.z[0],
            terms.z[1],
            terms.zeta[0],
            library.state[1],
            library.state[2],
            library.state[0],
        )
        got = tuple(row[n] for n in ("v", "z1", "z2", "zeta1", "eta1_hat", "eta2_hat", "r"))
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
        library.advance(x, yd, H)
    assert len(result) == 1001


def test_controller_fed_by_reference_in_libcosim(fmus: dict) -> None:
    """libcosim: Reference -> controller (yd, yd', yd''), x1, x2 constant; short run."""
    from libcosimpy.CosimObserver import CosimObserver

    execution = libcosim_execution(H)
    ref, rv = libcosim_add(execution, fmus["Reference"], "reference")
    ctl, cv = libcosim_add(execution, fmus["FixedTimeController"], "controller")
    for name in ("yd", "yd_dot", "yd_ddot"):
        execution.connect_real_variables(ref, rv[name], ctl, cv[name])
    execution.real_initial_value(ctl, cv["x1"], 0.3)
    execution.real_initial_value(ctl, cv["x2"], -0.1)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    n = 200
    assert execution.step(n)
    got = observer.last_real_values(ctl, [cv["r"], cv["eta1_hat"], cv["eta2_hat"], cv["v"]])
    # the oracle: the library fed with the reference at each communication point
    library = AdaptiveController(ControllerParameters(**EXAMPLE1))
    for k in range(n):
        library.advance((0.3, -0.1), reference_formula(k * H, 0.5, 1.0, 0.0, 0.0), H)
    # observed after the last step, before libcosim transfers new inputs: state at t_n, yd(t_{n-1})
    v = library.output((0.3, -0.1), reference_formula((n - 1) * H, 0.5, 1.0, 0.0, 0.0)).v
    np.testing.assert_allclose(got, [*library.state, v], rtol=1e-12, atol=1e-12)
