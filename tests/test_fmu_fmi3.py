# SPDX-License-Identifier: BSD-2-Clause
"""The FMI 3.0 Co-Simulation variants of the five FMUs (build/fmus3/, fmu_src/toolchain/fmi3.py and
shim/fmi3_functions.c), against independent oracles: fmpy's FMI 3.0 schema and validation, the standard's
function list (fmpy's copy of fmi3Functions.h), the FMI 2.0 FMUs they are made from (same variables,
same numbers bit for bit) and fmusim, a host nobody here wrote, on a machine with no Python."""

from __future__ import annotations

import csv
import ctypes
import re
import shutil
import subprocess
from ctypes import byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint32, c_void_p
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu
from fmu_helpers import unzipped

from orchestrator.crosscheck.colleague import hidden, refusal

pytestmark = pytest.mark.system

TOOLS = Path(__file__).resolve().parents[2] / "shared" / "tools"
FMUSIM = TOOLS / "fmusim" / "bin" / "fmusim"
HEADER = Path(fmpy.__file__).parent / "c-code" / "fmi3Functions.h"
STOP, H = 1.0, 1e-3
CASES = {  # start values: inputs held so that every output moves
    "Reference": {"amplitude": 1.5, "omega": 2.0},
    "FixedTimeController": {"x1": 0.7, "x2": -0.2, "yd": 0.5, "yd_dot": 0.1, "yd_ddot": -0.05},
    "Actuator": {"v": 1.7, "x1": 0.4, "x2": -0.3, "t_fault": 0.5},
    "Example1Plant": {"x1_0": 0.3, "x2_0": -0.2, "uf": 0.5},
    "PendulumPlant": {"x1_0": 0.6, "x2_0": 0.1, "uf": -2.0},
    # issue 35: the controllers of orders 1, 3, 4 and the manipulator
    "FixedTimeController1": {"x1": 0.7, "yd": 0.5, "yd_dot": 0.1},
    "FixedTimeController3": {"x1": 0.7, "x2": -0.2, "x3": 0.3, "yd": 0.5, "yd_dot": 0.1, "yd_ddot": -0.05,
                             "yd_dddot": -0.1},
    "FixedTimeController4": {"x1": 0.7, "x2": -0.2, "x3": 0.3, "x4": 0.1, "yd": 0.5, "yd_dot": 0.1,
                             "yd_ddot": -0.05, "yd_dddot": -0.1, "yd_ddddot": 0.05},
    "ManipulatorPlant": {"x1_0": 0.5, "x2_0": 0.1, "uf": 3.0},
}
TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String"}
NO_NAMESPACE = refusal()


@pytest.fixture(scope="module")
def fmus3(built: Path) -> dict[str, Path]:
    return {path.stem: path for path in sorted((built / "fmus3").glob("*.fmu"))}


def test_every_fmu_has_its_fmi3_twin(fmus: dict[str, Path], fmus3: dict[str, Path]) -> None:
    assert sorted(fmus3) == sorted(fmus) == sorted(CASES)


@pytest.mark.parametrize("model", list(CASES))
def test_fmpy_validates_them(fmus3: dict[str, Path], model: str) -> None:
    """Schema (fmpy's FMI 3.0 XSD), variable names, ModelStructure, start values, units."""
    assert validate_fmu(str(fmus3[model])) == []
    md = fmpy.read_model_description(str(fmus3[model]))
    assert md.fmiVersion == "3.0" and md.coSimulation is not None and md.modelExchange is None


@pytest.mark.parametrize("model", list(CASES))
def test_same_interface_as_the_fmi2_fmu(fmus: dict[str, Path], fmus3: dict[str, Path], model: str) -> None:
    """Every variable of the FMI 2.0 FMU, with its type mapped and the same attributes; output and
    initial-unknown dependencies name the same variables; plus the independent variable time."""
    md2 = fmpy.read_model_description(str(fmus[model]))
    md3 = fmpy.read_model_description(str(fmus3[model]))
    v3 = {v.name: v for v in md3.modelVariables}
    assert set(v3) == {v.name for v in md2.modelVariables} | {"time"}
    assert v3["time"].causality == "independent" and v3["time"].type == "Float64"
    for v in md2.modelVariables:
        w = v3[v.name]
        assert w.type == TYPES[v.type], v.name
        for attribute in (
            "causality",
            "variability",
            "initial",
            "start",
            "min",
            "max",
            "unit",
            "description",
        ):
            assert getattr(w, attribute) == getattr(v, attribute), (v.name, attribute)
    for unknowns2, unknowns3 in ((md2.outputs, md3.outputs), (md2.initialUnknowns, md3.initialUnknowns)):
        deps2 = {u.variable.name: {d.name for d in u.dependencies or ()} for u in unknowns2}
        deps3 = {u.variable.name: {d.name for d in u.dependencies or ()} for u in unknowns3}
        assert deps3 == deps2
    assert [u.name for u in md3.unitDefinitions] == [u.name for u in md2.unitDefinitions]
    assert md3.coSimulation.canGetAndSetFMUstate == md2.coSimulation.canGetAndSetFMUstate is True
    assert md3.coSimulation.modelIdentifier == model


def _exported(binary: Path) -> set[str]:
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("no nm (binutils) to list the exported symbols")
    out = subprocess.run(
        [nm, "-D", "--defined-only", str(binary)], capture_output=True, text=True, check=True
    )
    return {line.split()[-1] for line in out.stdout.splitlines() if line.split()}


def test_exports_exactly_the_fmi3_functions(fmus3: dict[str, Path], tmp_path: Path) -> None:
    """Every function of the standard's fmi3Functions.h, and nothing of FMI 2.0."""
    standard = set(re.findall(r"FMI3_Export\s+fmi3\w+TYPE\s+(fmi3\w+)", HEADER.read_text()))
    assert len(standard) == 75
    folder = Path(fmpy.extract(str(fmus3["Actuator"]), unzipdir=str(tmp_path / "a")))
    assert _exported(folder / "binaries" / "x86_64-linux" / "Actuator.so") == standard


@pytest.mark.parametrize("model", list(CASES))
def test_fmpy_results_equal_the_fmi2_fmu_bit_for_bit(
    fmus: dict[str, Path], fmus3: dict[str, Path], model: str
) -> None:
    r2 = fmpy.simulate_fmu(str(fmus[model]), stop_time=STOP, output_interval=H, start_values=CASES[model])
    r3 = fmpy.simulate_fmu(str(fmus3[model]), stop_time=STOP, output_interval=H, start_values=CASES[model])
    assert r3.dtype.names == r2.dtype.names and len(r3) == round(STOP / H) + 1
    for name in r2.dtype.names:
        np.testing.assert_array_equal(r3[name], r2[name], err_msg=name)


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as file:
        rows = list(csv.reader(file))
    return {name: np.array([float(row[i]) for row in rows[1:]]) for i, name in enumerate(rows[0])}


@pytest.mark.skipif(NO_NAMESPACE is not None, reason=str(NO_NAMESPACE))
@pytest.mark.skipif(not FMUSIM.is_file(), reason=f"fmusim not found at {FMUSIM}")
@pytest.mark.parametrize("model", list(CASES))
def test_fmusim_without_python_equals_fmpy(
    fmus: dict[str, Path], fmus3: dict[str, Path], model: str, tmp_path: Path
) -> None:
    """fmusim (the Reference FMUs' FMI 3.0 host) on a machine with no Python, with and without event
    mode and early return allowed: the same CSV, equal to fmpy's FMI 2.0 run within 1e-13 (fmusim's
    printed time grid differs from the read-back one in the last bit; tests/test_fmu_colleague.py)."""
    sent = Path(shutil.copy(fmus3[model], tmp_path))
    starts = [arg for name, value in CASES[model].items() for arg in ("--start-value", name, repr(value))]
    tables = []
    for extra in ([], ["--event-mode-used", "--early-return-allowed"]):
        out = tmp_path / f"out{len(tables)}.csv"
        command = [
            str(FMUSIM),
            "--interface-type",
            "cs",
            "--stop-time",
            repr(STOP),
            "--output-interval",
            repr(H),
            *extra,
            *starts,
            "--output-file",
            str(out),
            str(sent),
        ]
        result = subprocess.run(hidden(command), capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
        tables.append(out.read_text())
    assert tables[0] == tables[1]
    got = _read_csv(tmp_path / "out0.csv")
    expected = fmpy.simulate_fmu(
        str(fmus[model]), stop_time=STOP, output_interval=H, start_values=CASES[model]
    )
    assert len(got["time"]) == len(expected)
    for name in expected.dtype.names:
        np.testing.assert_allclose(got[name], expected[name], rtol=1e-13, atol=1e-13, err_msg=name)


# -- the C boundary, called directly -----------------------------------------------------------------
LOG = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
OK, ERROR = 0, 3


class Boundary:
    """The FMI 3.0 binary of an FMU loaded with ctypes, its messages collected."""

    def __init__(self, fmu: Path, where: Path) -> None:
        self.md = fmpy.read_model_description(str(fmu))
        self.folder = Path(fmpy.extract(str(fmu), unzipdir=str(where)))
        self.lib = ctypes.PyDLL(
            str(self.folder / "binaries" / "x86_64-linux" / f"{self.md.coSimulation.modelIdentifier}.so")
        )
        self.messages: list[tuple[int, str]] = []
        self.log = LOG(
            lambda env, status, category, message: self.messages.append((status, message.decode()))
        )
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}

    def call(self, name: str, restype: type = c_int, *args: object) -> object:
        f = getattr(self.lib, name)
        f.restype = restype
        return f(*args)

    def instantiate(self, required: int = 0) -> int | None:
        vrs = (c_uint32 * 1)(1)
        f = self.lib.fmi3InstantiateCoSimulation
        f.restype = c_void_p
        return f(
            b"i",
            self.md.guid.encode(),
            str(self.folder / "resources").encode() + b"/",
            c_bool(False),
            c_bool(False),
            c_bool(False),
            c_bool(False),
            vrs,
            c_size_t(required),
            None,
            self.log,
            None,
        )

    def floats(self, instance: int, *names: str) -> tuple[int, list[float]]:
        vrs = (c_uint32 * len(names))(*[self.vr[n] for n in names])
        values = (c_double * len(names))()
        status = self.call(
            "fmi3GetFloat64",
            c_int,
            c_void_p(instance),
            vrs,
            c_size_t(len(names)),
            values,
            c_size_t(len(names)),
        )
        return int(status), list(values)  # type: ignore[call-overload]

    def do_step(self, instance: int, t: float, h: float) -> tuple[int, list[int], float]:
        flags = [ctypes.c_uint8(0xAA) for _ in range(3)]  # not a bool: shows whether it was written
        last = c_double(-1.0)
        status = self.call(
            "fmi3DoStep",
            c_int,
            c_void_p(instance),
            c_double(t),
            c_double(h),
            c_bool(True),
            *(byref(f) for f in flags),
            byref(last),
        )
        return int(status), [f.value for f in flags], last.value  # type: ignore[call-overload]


@pytest.fixture()
def plant(fmus3: dict[str, Path], tmp_path: Path) -> Boundary:
    return Boundary(fmus3["Example1Plant"], tmp_path / "plant")


def test_other_interface_types_refused_with_null_and_a_message(plant: Boundary) -> None:
    """Scheduled Execution (PythonFMU3 aborts the host there) and Model Exchange: NULL and one message;
    required intermediate variables too (providesIntermediateUpdate is false)."""
    f = plant.lib.fmi3InstantiateScheduledExecution
    f.restype = c_void_p
    assert (
        f(b"se", plant.md.guid.encode(), b"/nowhere/", False, False, None, plant.log, None, None, None)
        is None
    )
    f = plant.lib.fmi3InstantiateModelExchange
    f.restype = c_void_p
    assert f(b"me", plant.md.guid.encode(), b"/nowhere/", False, False, None, plant.log) is None
    assert plant.instantiate(required=1) is None
    assert [s for s, _ in plant.messages] == [ERROR] * 3
    assert "fmi3InstantiateScheduledExecution: this FMU is a Co-Simulation FMU only" in plant.messages[0][1]
    assert "fmi3InstantiateModelExchange" in plant.messages[1][1]
    assert "no intermediate update" in plant.messages[2][1]


def test_do_step_writes_every_output_argument(plant: Boundary) -> None:
    """Before initialization: fmi3Error, a message, and still every output written; after it: the
    end of the step, no event, no early return, no termination; time follows the steps."""
    instance = plant.instantiate()
    assert instance
    try:
        assert plant.do_step(instance, 0.0, H) == (ERROR, [0, 0, 0], 0.0)
        assert "fmi3DoStep: not allowed in Instantiated" in plant.messages[-1][1]
        # an error latches the instance (only getters, fmi3Reset and fmi3FreeInstance go on)
        assert plant.call("fmi3Reset", c_int, c_void_p(instance)) == OK
        assert (
            plant.call(
                "fmi3EnterInitializationMode",
                c_int,
                c_void_p(instance),
                c_bool(False),
                c_double(0.0),
                c_double(0.25),
                c_bool(False),
                c_double(0.0),
            )
            == OK
        )
        assert plant.floats(instance, "time") == (OK, [0.25])
        assert plant.call("fmi3ExitInitializationMode", c_int, c_void_p(instance)) == OK
        assert plant.do_step(instance, 0.25, H) == (OK, [0, 0, 0], 0.25 + H)
        status, (time, x1) = plant.floats(instance, "time", "x1")
        assert status == OK and time == 0.25 + H and x1 != 0.5
    finally:
        plant.call("fmi3FreeInstance", None, c_void_p(instance))


def test_refusals_return_an_error_status_and_say_why(plant: Boundary) -> None:
    instance = plant.instantiate()
    assert instance
    c = c_void_p(instance)
    try:
        one = (c_uint32 * 1)(plant.vr["x1"])
        buffer = (c_double * 4)()
        calls = {
            "fmi3GetFloat32": (c, one, c_size_t(1), buffer, c_size_t(1)),  # no such variable type
            "fmi3GetInt64": (c, one, c_size_t(1), buffer, c_size_t(1)),
            "fmi3GetClock": (c, one, c_size_t(1), buffer),
            "fmi3SetFloat64": (c, (c_uint32 * 1)(plant.vr["time"]), c_size_t(1), buffer, c_size_t(1)),
            "fmi3GetNumberOfContinuousStates": (c, byref(c_size_t())),  # Model Exchange
            "fmi3EnterConfigurationMode": (c,),
            "fmi3GetDirectionalDerivative": (
                c,
                one,
                c_size_t(1),
                one,
                c_size_t(1),
                buffer,
                c_size_t(1),
                buffer,
                c_size_t(1),
            ),
            "fmi3EnterEventMode": (c,),  # not instantiated with eventModeUsed
            "fmi3ActivateModelPartition": (c, c_uint32(1), c_double(0.0)),
        }
        for name, args in calls.items():
            before = len(plant.messages)
            assert plant.call(name, c_int, *args) == ERROR, name
            assert len(plant.messages) == before + 1 and name in plant.messages[-1][1], name
        # a value reference no variable has (pythonfmu would fail with fmi2Fatal, ending the instance)
        for vr in (0, 999):
            before = len(plant.messages)
            f = plant.lib.fmi3GetFloat64
            assert f(c, (c_uint32 * 1)(vr), c_size_t(1), buffer, c_size_t(1)) == ERROR
            assert f"no variable has the value reference {vr}" in plant.messages[before][1]
        assert plant.floats(instance, "x1")[0] == OK  # the instance goes on
        # nValues not matching the number of scalar value references
        f = plant.lib.fmi3GetFloat64
        assert f(c, one, c_size_t(1), buffer, c_size_t(2)) == ERROR
        # naming no variable of a type the FMU has none of is fine
        assert plant.call("fmi3GetUInt8", c_int, c, one, c_size_t(0), buffer, c_size_t(0)) == OK
        assert plant.call("fmi3GetVersion", c_char_p) == b"3.0"
    finally:
        plant.call("fmi3FreeInstance", None, c)


def test_fmu_state_restores_outputs_and_time(fmus3: dict[str, Path]) -> None:
    """fmi3GetFMUState / fmi3SetFMUState through fmpy: the continuation from a restored state is
    the same, to the bit, and the time variable comes back with it."""
    fmu = fmus3["Example1Plant"]
    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU3Slave(
        guid=md.guid,
        unzipDirectory=unzipped(fmu),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="state",
    )
    slave.instantiate()
    try:
        slave.setFloat64([vr["uf"]], [0.5])
        slave.enterInitializationMode(startTime=0.0)
        slave.exitInitializationMode()
        for k in range(10):
            slave.doStep(k * H, H)
        state = slave.getFMUState()
        first = []
        for k in range(10, 20):
            slave.doStep(k * H, H)
            first.append(slave.getFloat64([vr["x1"], vr["x2"], vr["time"]]))
        slave.setFMUState(state)
        assert slave.getFloat64([vr["time"]]) == [9 * H + H]  # the end of the tenth step
        again = []
        for k in range(10, 20):
            slave.doStep(k * H, H)
            again.append(slave.getFloat64([vr["x1"], vr["x2"], vr["time"]]))
        assert again == first
        slave.freeFMUState(state)
        slave.terminate()
    finally:
        slave.freeInstance()


def test_build_is_reproducible(fmus: dict[str, Path], fmus3: dict[str, Path], tmp_path: Path) -> None:
    """The FMI 3.0 variant of the same FMI 2.0 archive, built again elsewhere: the same bytes."""
    from fmu_src.toolchain.fmi3 import build_fmu3

    again = build_fmu3(fmus["Actuator"], tmp_path / "again")
    assert again.read_bytes() == fmus3["Actuator"].read_bytes()


FMI2_XML = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{{g}}">
  <CoSimulation modelIdentifier="M"/>
  <ModelVariables>
    <ScalarVariable name="u" valueReference="0" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="{name}" valueReference="1" causality="output">{typed}</ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2" dependencies="1"/></Outputs></ModelStructure>
</fmiModelDescription>"""


def test_what_the_fmi3_layer_does_not_map_is_refused_by_the_build() -> None:
    """An Enumeration (FMI 3.0: Int64 valued, not mapped) or a variable named time: BuildError
    naming it; a plain description translates with dependencies by value reference."""
    from fmu_src.toolchain.build import BuildError
    from fmu_src.toolchain.fmi3 import fmi3_model_description

    enumeration = FMI2_XML.format(name="e", typed='<Enumeration declaredType="E"/>')
    with pytest.raises(BuildError, match="variable e is Enumeration"):
        fmi3_model_description(enumeration.encode(), "t")
    with pytest.raises(BuildError, match="named 'time'"):
        fmi3_model_description(FMI2_XML.format(name="time", typed="<Real/>").encode(), "t")
    xml, time_vr = fmi3_model_description(FMI2_XML.format(name="y", typed="<Real/>").encode(), "t")
    assert time_vr == 3 and b'<Output valueReference="2" dependencies="1" />' in xml
