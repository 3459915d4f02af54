# SPDX-License-Identifier: BSD-2-Clause
"""The engine's fast tier: ``System`` and both masters on in-memory model descriptions and fake
instances (no FMU is built, extracted or loaded).

The fakes are a discrete integrator (x_{k+1} = x_k + h u, output x, no feedthrough) and a gain
(y = k u, direct feedthrough), the loop of tests/orch_helpers.py. Oracles: the closed forms of that
loop (gauss-seidel x_k = x0 (1 + h k)^k; jacobi, one step of delay per connection,
x_{k+1} = x_k + h k x_{k-1}), the FMI 2.0 calling sequence (setup and initialization before any
step, outputs read before the inputs that depend on them are set), and exact decimal time.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi2 import fmi2Discard, fmi2Error, fmi2Fatal, fmi2OK
from fmpy.model_description import CoSimulation, ModelDescription, ModelVariable, Unknown
from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.errors import NonFiniteError, ScenarioError, SimulationError
from orchestrator.fmi import InstanceBase
from orchestrator.master import MASTERS, Master
from orchestrator.ssp import (
    Component,
    Connection,
    Connector,
    Experiment,
    Parameter,
    ParameterSet,
    SystemStructure,
)
from orchestrator.system import PortRef, System, _strong_components

H, K, X0 = 0.1, -2.0, 1.0


def model(name: str, inputs: list[str], outputs: dict[str, list[str]],
          parameters: dict[str, float]) -> ModelDescription:
    """A co-simulation model description: Real inputs (start 0), outputs with their dependencies,
    parameters with their start values."""
    md = ModelDescription(fmiVersion="2.0", modelName=name, instantiationToken="{" + name + "}",
                          coSimulation=CoSimulation(modelIdentifier=name))
    variables: dict[str, ModelVariable] = {}
    for i, (n, causality, start) in enumerate([*[(n, "input", "0") for n in inputs],
                                               *[(n, "output", None) for n in outputs],
                                               *[(n, "parameter", repr(v)) for n, v in parameters.items()]]):
        v = ModelVariable(name=n, valueReference=i, type="Real", causality=causality,
                          variability="fixed" if causality == "parameter" else "continuous",
                          initial={"output": "calculated"}.get(causality, "exact"), start=start)
        variables[n] = v
        md.modelVariables.append(v)
    for index, (n, deps) in enumerate(outputs.items()):
        md.outputs.append(Unknown(index=index, variable=variables[n],
                                  dependencies=[variables[d] for d in deps]))
    return md


INTEGRATOR = model("Integrator", ["u"], {"x": []}, {"x0": 0.0})
GAIN = model("Gain", ["u"], {"y": ["u"]}, {"k": 1.0})


class Fake(InstanceBase):
    """A fake instance: the integrator or the gain in Python, every call appended to ``log``;
    ``fail`` maps (call, step number) -> the status to return instead of fmi2OK."""

    def __init__(self, name: str, md: ModelDescription, log: list[tuple], faults: dict) -> None:
        super().__init__(name, _Messages())
        self.md, self.log, self.faults = md, log, faults
        self.values = {v.valueReference: float(v.start or 0.0) for v in md.modelVariables}
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.steps = 0
        self.do_step, self.get_real, self.set_real = self._do_step, self._get_real, self._set_real

    def _status(self, call: str) -> int:
        return self.faults.get((self.name, call, self.steps), fmi2OK)

    def _output(self, name: str) -> float:
        if self.md is GAIN:
            return self.values[self.vr["k"]] * self.values[self.vr["u"]]
        return self.values[self.vr["x"]]

    def _do_step(self, c: object, t: float, h: float, new_step: int) -> int:
        self.log.append(("doStep", self.name, t, h))
        status = self._status("doStep")
        if status >= fmi2Discard:
            return status
        if self.md is INTEGRATOR:
            self.values[self.vr["x"]] += h * self.values[self.vr["u"]]
        self.steps += 1
        return fmi2OK

    def _get_real(self, c: object, vr, n: int, out) -> int:
        names = [v.name for v in self.md.modelVariables if v.valueReference in list(vr)[:n]]
        self.log.append(("get", self.name, tuple(names)))
        for i in range(n):
            out[i] = self._output(self.md.modelVariables[vr[i]].name)
        if self._status("get") == fmi2OK and self.faults.get((self.name, "nan", self.steps)):
            out[0] = float("nan")
        return self._status("get")

    def _set_real(self, c: object, vr, n: int, values) -> int:
        self.log.append(("set", self.name, tuple(self.md.modelVariables[vr[i]].name for i in range(n))))
        for i in range(n):
            self.values[vr[i]] = values[i]
        return fmi2OK

    def set_start_values(self, values, time: float) -> None:
        self.log.append(("start", self.name, tuple(sorted(values))))
        for _, vr, value in values.values():
            self.values[vr] = float(value)
        if self.md is INTEGRATOR:
            self.values[self.vr["x"]] = self.values[self.vr["x0"]]

    def setup(self, start: float, stop: float, tolerance: float | None = None) -> None:
        self.log.append(("setup", self.name, start, stop))
        self.initialized = True

    def exit_initialization(self, time: float) -> None:
        self.log.append(("exit", self.name, time))

    def terminate(self, time: float) -> None:
        self.log.append(("terminate", self.name, time))
        self.initialized = False

    def release(self) -> None:
        self.log.append(("release", self.name, self.broken))


class _Messages:
    last: dict[str, str] = {}


def loop_system(gain: float = K, x0: float = X0, gain_feedthrough: bool = True) -> System:
    """integrator.x -> gain.u, gain.y -> integrator.u (x' = k x), from in-memory descriptions."""
    gain_md = GAIN if gain_feedthrough else model("Gain", ["u"], {"y": []}, {"k": 1.0})
    real = [("u", "input", "Real"), ("x", "output", "Real")]
    components = (Component("integrator", Path("Integrator.fmu"), tuple(Connector(*c) for c in real)),
                  Component("gain", Path("Gain.fmu"), (Connector("u", "input", "Real"),
                                                       Connector("y", "output", "Real"))))
    connections = (Connection.between("integrator.x", "gain.u"), Connection.between("gain.y", "integrator.u"))
    structure = SystemStructure("loop", components, connections, Experiment(0.0, 1.0, H), ssd_file="loop.ssd")
    return System(structure, overrides={"gain.k": gain, "integrator.x0": x0},
                  model_descriptions={Path("Integrator.fmu"): INTEGRATOR, Path("Gain.fmu"): gain_md})


def master(name: str, system: System, log: list, faults: dict | None = None, stop: float = 1.0) -> Master:
    def fake(comp, workdir, messages, time):
        return Fake(comp.name, comp.model, log, faults or {})

    return MASTERS[name](system, 0.0, stop, H, instances=fake)


def test_system_orders_the_propagation_by_feedthrough():
    system = loop_system()
    order = [(op.kind, op.component, op.inputs) for op in system.schedule]
    # the gain's y depends on its u, which the integrator's x feeds: read x, set u, read y, set u
    assert order == [("get", "integrator", ()), ("set", "gain", ("u",)), ("get", "gain", ()),
                     ("set", "integrator", ("u",))]


def test_system_reports_an_algebraic_loop_naming_its_ports():
    """A loop is no error (issue 32): a warning naming its ports, and the whole schedule one
    span that the gauss-seidel master iterates."""
    fmus = {Path("A.fmu"): GAIN, Path("B.fmu"): GAIN}
    gain = (Connector("u", "input", "Real"), Connector("y", "output", "Real"))
    components = (Component("a", Path("A.fmu"), gain), Component("b", Path("B.fmu"), gain))
    structure = SystemStructure("alg", components,
                                (Connection.between("a.y", "b.u"), Connection.between("b.y", "a.u")),
                                Experiment(0.0, 1.0, H), ssd_file="alg.ssd")
    system = System(structure, model_descriptions=fmus)
    assert system.loops == ["alg.ssd: algebraic loop: a.u -> a.y -> b.u -> b.y -> a.u"]
    assert system.iterated == [(0, 4)] and len(system.schedule) == 4


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 12).flatmap(lambda n: st.tuples(
    st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=3 * n))))
def test_strong_components_agree_with_scipy(graph):
    """The engine's own strongly connected parts (no scipy import at start-up) against scipy's
    csgraph on random directed graphs: the same partition of the nodes."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    n, edges = graph
    nodes = [PortRef(f"c{i:02d}", "y") for i in range(n)]
    succ: dict[PortRef, list[PortRef]] = {}
    for a, b in edges:
        succ.setdefault(nodes[a], []).append(nodes[b])
    ours = _strong_components(nodes, succ)
    pairs = np.array(edges, dtype=int).reshape(-1, 2)
    matrix = csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, theirs = connected_components(matrix, directed=True, connection="strong")
    assert len(set(ours.values())) == len(set(theirs))
    for i in range(n):
        for j in range(n):
            assert (ours[nodes[i]] == ours[nodes[j]]) == (theirs[i] == theirs[j])


def test_gauss_seidel_solves_the_loop_without_delay_on_the_exact_grid():
    log: list[tuple] = []
    rows = master("gauss-seidel", loop_system(), log).run()
    assert rows["time"].tolist() == [float(Fraction(k) * Fraction("0.1")) for k in range(11)]
    np.testing.assert_allclose(rows["integrator.x"], X0 * (1 + H * K) ** np.arange(11), rtol=1e-14)
    np.testing.assert_allclose(rows["gain.y"], K * rows["integrator.x"], rtol=1e-14)


def test_gauss_seidel_calls_in_fmi_order_and_propagates_by_feedthrough():
    log: list[tuple] = []
    master("gauss-seidel", loop_system(), log, stop=0.2).run()
    calls = [entry[:2] if entry[0] in ("doStep", "setup", "exit", "terminate", "release") else entry
             for entry in log]
    propagate = [("get", "integrator", ("x",)), ("set", "gain", ("u",)), ("get", "gain", ("y",)),
                 ("set", "integrator", ("u",))]
    init = [("start", "integrator", ("x0",)), ("setup", "integrator"), ("start", "integrator", ("x0",)),
            ("start", "gain", ("k",)), ("setup", "gain"), ("start", "gain", ("k",)),
            *propagate, ("exit", "integrator"), ("exit", "gain"), *propagate]
    step = [("doStep", "integrator"), ("doStep", "gain"), *propagate]
    end = [("terminate", "integrator"), ("terminate", "gain"), ("release", "gain"), ("release", "integrator")]
    assert calls == [*init, *step, *step, *end]
    assert [e[2:] for e in log if e[0] == "doStep"] == [(0.0, 0.1), (0.0, 0.1), (0.1, 0.1), (0.1, 0.1)]


def test_jacobi_delays_every_connection_by_one_step():
    log: list[tuple] = []
    rows = master("jacobi", loop_system(), log).run()
    x = [X0, X0 + H * K * X0]  # the first step already sees gain.y = k x0 (initialization sweeps)
    for _ in range(9):
        x.append(x[-1] + H * K * x[-2])
    np.testing.assert_allclose(rows["integrator.x"], x, rtol=1e-14)
    step = [e[:2] for e in log if e[0] in ("set", "doStep", "get")][-6:]
    assert step == [("set", "integrator"), ("doStep", "integrator"), ("get", "integrator"),
                    ("set", "gain"), ("doStep", "gain"), ("get", "gain")]


@pytest.mark.parametrize("name", list(MASTERS))
@pytest.mark.parametrize("status, text", [(fmi2Discard, "fmi2Discard"), (fmi2Error, "fmi2Error"),
                                          (fmi2Fatal, "fmi2Fatal")])
def test_a_failed_step_keeps_the_rows_before_it_and_frees_every_instance(name, status, text):
    log: list[tuple] = []
    runner = master(name, loop_system(), log, faults={("integrator", "doStep", 3): status})
    expected = rf"^integrator: fmi2DoStep returned {text} at t=0\.300 s$"
    with pytest.raises(SimulationError, match=expected) as info:
        runner.run()
    assert info.value.rows == 4 and info.value.result["time"].tolist() == [0.0, 0.1, 0.2, 0.3]
    released = sorted(e[1:] for e in log if e[0] == "release")
    assert released == [("gain", False), ("integrator", status == fmi2Fatal)]
    assert not [e for e in log if e[0] == "terminate"]  # a failed run is not terminated normally


def test_a_nan_output_stops_the_run_naming_component_variable_and_time():
    log: list[tuple] = []
    runner = master("gauss-seidel", loop_system(), log, faults={("integrator", "nan", 5): True})
    with pytest.raises(NonFiniteError, match=r"^integrator: output 'x' is nan at t=0\.500 s"):
        runner.run()


def test_a_failed_get_names_the_call():
    runner = master("gauss-seidel", loop_system(), [], faults={("gain", "get", 2): fmi2Error})
    with pytest.raises(SimulationError, match=r"^gain: fmi2GetReal returned fmi2Error at t=0\.200 s$"):
        runner.run()


# -- no silent defaults (issue 22) ------------------------------------------------------------------
def test_a_value_for_a_connected_input_is_refused():
    """Before: --set gain.u=5 on the loop was accepted, recorded in provenance and the plot title,
    and overwritten by integrator.x at the first propagation."""
    expected = r"^overrides: gain\.u is an input fed by integrator\.x: a value given"  # the API field
    with pytest.raises(ScenarioError, match=expected):
        System(loop_system().structure, overrides={"gain.u": 5.0},
               model_descriptions={Path("Integrator.fmu"): INTEGRATOR, Path("Gain.fmu"): GAIN})


def test_a_parameter_given_twice_in_one_set_is_refused():
    """Before: the second value won in silence."""
    twice = ParameterSet("mine.ssv", (Parameter("gain.k", "Real", 2.0), Parameter("gain.k", "Real", 3.0)))
    expected = r"^mine\.ssv: parameter 'gain\.k' is given twice \(2\.0 and 3\.0\)"
    with pytest.raises(ScenarioError, match=expected):
        System(loop_system().structure, [twice],
               model_descriptions={Path("Integrator.fmu"): INTEGRATOR, Path("Gain.fmu"): GAIN})


def test_packing_the_same_files_gives_the_same_bytes(tmp_path):
    """Before: every build wrote the files' modification times into the .ssp."""
    import os

    from orchestrator.ssp import pack_ssp

    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "SystemStructure.ssd").write_text("<ssd/>")
    (tmp_path / "A.fmu").write_bytes(b"fmu bytes" * 100)
    first = pack_ssp(tmp_path / "s", {"A.fmu": tmp_path / "A.fmu"}, tmp_path / "one.ssp").read_bytes()
    for f in (tmp_path / "s" / "SystemStructure.ssd", tmp_path / "A.fmu"):
        os.utime(f, (1e9, 1e9))  # as a later build leaves them: other times, same bytes
    assert pack_ssp(tmp_path / "s", {"A.fmu": tmp_path / "A.fmu"}, tmp_path / "two.ssp").read_bytes() == first


# -- input time series (--input-file) ---------------------------------------------------------------
def lone_gain() -> System:
    """One gain, y = 3 u, its input fed by no connection."""
    components = (Component("gain", Path("Gain.fmu"), (Connector("u", "input", "Real"),
                                                       Connector("y", "output", "Real"))),)
    structure = SystemStructure("one", components, (), Experiment(0.0, 1.0, H), ssd_file="one.ssd")
    return System(structure, overrides={"gain.k": 3.0}, model_descriptions={Path("Gain.fmu"): GAIN})


@pytest.mark.parametrize("name", list(MASTERS))
def test_an_input_series_drives_an_unconnected_input(name):
    """u(t) = 1 + 2t between rows 0.25 s apart (linear interpolation is exact on it) and 5 after
    t = 0.75 (held: the file ends there). Gauss-seidel reads y after setting u at the same point;
    jacobi's FMU uses u(t_k) in the step to t_k+1, like every value it exchanges."""
    from orchestrator.inputs import InputSeries

    series = InputSeries((PortRef("gain", "u"),), np.array([0.0, 0.25, 0.5, 0.75]),
                         np.array([[1.0], [1.5], [2.0], [5.0]]), (False,))
    log: list[tuple] = []

    def fake(comp, workdir, messages, time):
        return Fake(comp.name, comp.model, log, {})

    rows = MASTERS[name](lone_gain(), 0.0, 1.0, H, instances=fake, inputs=series).run()
    u = np.interp(rows["time"], series.time, series.values[:, 0])
    np.testing.assert_allclose(rows["gain.u"], u, rtol=1e-15)
    if name == "gauss-seidel":
        np.testing.assert_allclose(rows["gain.y"], 3 * u, rtol=1e-15)
    else:
        np.testing.assert_allclose(rows["gain.y"][1:], 3 * u[:-1], rtol=1e-15)
    sets = [e for e in log if e[0] == "set"]
    assert len(sets) == 11 and all(e[1:] == ("gain", ("u",)) for e in sets)  # t0, then every step


def test_an_input_file_of_many_blocks_is_read_as_numpy_reads_it(tmp_path, monkeypatch):
    """The CSV is parsed a block at a time into arrays grown in place (issue 44: a 250 MiB file
    took 2.5 times its size): 100 000 rows in blocks of 64 KiB give the very values numpy's
    own parser reads, and a fault deep in the file (time going back, a NaN, a word) is named with
    its line, input and time as before."""
    from orchestrator import inputs
    from orchestrator.errors import UsageError
    from orchestrator.results import ResultFileError

    monkeypatch.setattr(inputs, "BLOCK_BYTES", 1 << 16)
    rng = np.random.default_rng(44)
    t = np.cumsum(rng.uniform(1e-6, 1e-4, 100_000)).tolist()
    u = (rng.standard_normal(100_000) * 10.0 ** rng.integers(-300, 300, 100_000)).tolist()
    lines = ["time,gain.u", *(f"{a!r},{b!r}" for a, b in zip(t, u, strict=True))]
    good = tmp_path / "u.csv"
    good.write_text("\n".join(lines) + "\n")
    assert good.stat().st_size > 40 * inputs.BLOCK_BYTES
    series, _ = inputs.read_inputs(good, lone_gain(), 0.0, 1.0)
    expected = np.loadtxt(good, delimiter=",", skiprows=1)
    assert series.time.tobytes() == expected[:, 0].tobytes()
    assert series.values.tobytes() == expected[:, 1:].tobytes()
    assert series.ports == (PortRef("gain", "u"),)

    def faulty(row: int, text: str) -> Path:
        path = tmp_path / "bad.csv"
        path.write_text("\n".join([*lines[:row], text, *lines[row + 1:]]) + "\n")
        return path

    back = faulty(90_001, f"{t[90_000 - 2]!r},1.0")  # line 90 002: the time of line 90 000
    with pytest.raises(ResultFileError, match=f"bad.csv: column 'time' does not increase at line 90002 "
                                              rf"\(t = {t[90_000 - 2]!r} after {t[90_000 - 1]!r}\)"):
        inputs.read_inputs(back, lone_gain(), 0.0, 1.0)
    nan = faulty(95_000, f"{t[95_000 - 1]!r},nan")
    with pytest.raises(UsageError, match=rf"bad.csv: 'gain.u' is nan at t={t[95_000 - 1]:g} s$"):
        inputs.read_inputs(nan, lone_gain(), 0.0, 1.0)
    word = faulty(99_000, f"{t[99_000 - 1]!r},one")
    with pytest.raises(ResultFileError, match="bad.csv: not a result CSV .*invalid value 'one'"):
        inputs.read_inputs(word, lone_gain(), 0.0, 1.0)


def test_a_discrete_input_holds_its_value_between_rows():
    from orchestrator.inputs import InputSeries

    series = InputSeries((PortRef("a", "u"),), np.array([0.0, 0.5]), np.array([[1.0], [2.0]]), (True,))
    assert [series.at(t)[0] for t in (0.0, 0.2, 0.49999, 0.5, 0.9)] == [1.0, 1.0, 1.0, 2.0, 2.0]
