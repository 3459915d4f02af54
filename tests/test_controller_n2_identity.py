# SPDX-License-Identifier: BSD-2-Clause
"""The n = 2 controller FMU gives the Python reference law's bits on every shipped scenario of the
paper's examples.

The FixedTimeController FMU runs the compiled law (controller/_law.c). Each scenario runs in full with
the built FMUs, then the controller's inputs recorded at every communication point are replayed
through the Python reference (controller.native.ReferenceLaw: controller.law and
controller.stepping.rk4_step) as the FMU steps it (its output's law reused as the first RK4 stage):
every output of the controller at every step (v, z1, z2, zeta1, eta1_hat, eta2_hat, r) has the same
bits. Until issue 47 the replay ran controller/order2.py, the scalar n = 2 path the FMU ran before
issue 35; that path was the general reference's operations in the same order (bit-equal on random
gains, states and runs), so the reference is the same record."""

from __future__ import annotations

import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

import orchestrator
from controller.native import ReferenceLaw
from controller.params import ControllerParameters

pytestmark = pytest.mark.system

SCENARIOS = ("example1", "example1_finite_time", "example1_no_fault", "example1_smooth", "pendulum",
             "pendulum_finite_time", "pendulum_smooth")
GAINS = ("k", "q", "a", "kappa", "rho", "rho_bar")
NS = {"ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}


def controller_parameters(archive: Path) -> ControllerParameters:
    """The library's parameters from the scenario's controller.ssv (the FMU's defaults elsewhere)."""
    with zipfile.ZipFile(archive) as ssp:
        root = etree.fromstring(ssp.read("controller.ssv"))
    values = {p.get("name"): float(next(iter(p)).get("value"))
              for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS)}
    return ControllerParameters(
        **{g: (values[f"{g}1"], values[f"{g}2"]) for g in GAINS}, alpha=values["alpha"], beta=values["beta"],
        mode=int(values["mode"]), discretization=int(values.get("discretization", 0)),
        sample_time=values.get("sample_time", 1e-3), b_max=values.get("b_max", 1.0),
    )


def bits(column: np.ndarray) -> bytes:
    return column.astype("<f8").tobytes()


@pytest.mark.parametrize("name", SCENARIOS)
def test_controller_outputs_are_the_reference_laws_bits(built: Path, name: str) -> None:
    archive = built / "ssp" / f"{name}.ssp"
    rows = orchestrator.run(archive).rows
    params = controller_parameters(archive)
    law = ReferenceLaw(params)
    inputs = np.stack([rows[f"controller.{n}"] for n in ("x1", "x2", "yd", "yd_dot", "yd_ddot")], axis=1)
    h = float(rows["time"][1] - rows["time"][0])
    expected = np.empty((len(rows), 7))
    state: tuple[float, ...] = (params.r0, *params.eta0)  # (r, eta_hat_1, eta_hat_2)
    for k, values in enumerate(map(tuple, inputs.tolist())):
        stage = law.evaluate(state, values)
        expected[k] = (*stage[:4], state[1], state[2], state[0])
        step = float(rows["time"][k + 1] - rows["time"][k]) if k + 1 < len(rows) else h
        state = law.advance(step, stage, state, values)
    for j, output in enumerate(("v", "z1", "z2", "zeta1", "eta1_hat", "eta2_hat", "r")):
        got = rows[f"controller.{output}"]
        if bits(got) != bits(expected[:, j]):
            first = int(np.flatnonzero(got != expected[:, j])[0])
            pack = struct.Struct("<d").pack
            pytest.fail(f"{name}: controller.{output} differs first at t = {rows['time'][first]}: "
                        f"{pack(got[first]).hex()} != {pack(expected[first, j]).hex()}")
