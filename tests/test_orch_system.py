"""System validation: every inconsistency between SSD and FMUs is reported at once, naming the SSD,
component and connector; propagation order and algebraic loops from ModelStructure dependencies."""

from __future__ import annotations

from pathlib import Path

import pytest
from orch_helpers import loop_scenario, without_start

import orchestrator
from orchestrator import RunOptions, ScenarioError
from orchestrator.ssp import Connection, Experiment, SystemStructure, component, read_scenario, write_ssd
from orchestrator.system import Operation, System

pytestmark = pytest.mark.system


def _edit(folder: Path, old: str, new: str) -> None:
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    assert old in text
    ssd.write_text(text.replace(old, new, 1))


def test_schedule_follows_feedthrough(tmp_path, test_fmus):
    """Integrator output does not depend on its input: read it first, then the gain (feedthrough)
    after its input is set, and set the integrator's input last."""
    system = System(read_scenario(loop_scenario(tmp_path / "s", test_fmus, pack=False)))
    assert system.schedule == [Operation("get", "source"), Operation("get", "integrator"),
                               Operation("set", "gain", ("u",)), Operation("get", "gain"),
                               Operation("set", "integrator", ("u",))]


def test_unknown_connector_in_connection(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    _edit(folder, 'endElement="gain" endConnector="u"', 'endElement="gain" endConnector="w"')
    with pytest.raises(ScenarioError, match=r"SystemStructure\.ssd: connection integrator\.x -> gain\.w: "
                                            r"component 'gain' declares no connector 'w'"):
        orchestrator.run(folder)


def test_connector_missing_in_fmu_and_type_mismatch_reported_together(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    _edit(folder, '<ssd:Connector name="u" kind="input">\n            <ssc:Real/>',
          '<ssd:Connector name="u" kind="input">\n            <ssc:Integer/>')
    _edit(folder,
          '<ssd:Connector name="y" kind="output">\n            <ssc:Real/>\n          </ssd:Connector>',
          '<ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>'
          '<ssd:Connector name="nope" kind="output"><ssc:Real/></ssd:Connector>')
    with pytest.raises(ScenarioError) as info:
        orchestrator.run(folder)
    problems = info.value.problems
    ssd = str(folder / "SystemStructure.ssd")
    assert f"{ssd}: component 'source', connector 'nope': the FMU has no variable of that name" in problems
    assert (f"{ssd}: component 'gain', connector 'u': declared type Integer but the FMU's variable is Real"
            in problems)
    assert (f"{ssd}: connection integrator.x -> gain.u: type mismatch "
            "(integrator.x is Real, gain.u is Integer)") in problems


def test_wrong_direction(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    _edit(folder, 'startElement="integrator" startConnector="x" endElement="gain" endConnector="u"',
          'startElement="gain" startConnector="u" endElement="integrator" endConnector="x"')
    with pytest.raises(ScenarioError, match=r"gain\.u is an input, not an output"):
        orchestrator.run(folder)


def test_input_unconnected_without_start(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    without_start(test_fmus["Gain"], "u", folder / "resources" / "Gain.fmu")
    text = (folder / "SystemStructure.ssd").read_text()
    start = text.index('      <ssd:Connection startElement="integrator" startConnector="x"')
    end = text.index("\n", start) + 1
    (folder / "SystemStructure.ssd").write_text(text[:start] + text[end:])
    with pytest.raises(ScenarioError, match=r"component 'gain', input 'u' is neither connected nor has"):
        orchestrator.run(folder)
    # a start value from a parameter set makes it valid
    result = orchestrator.run(folder, RunOptions(overrides={"gain.u": 0.5}, stop_time=0.05)).rows
    assert (result["gain.y"] == -1.0).all()


def test_bad_parameter_bindings_all_reported(tmp_path, test_fmus):
    folder = loop_scenario(tmp_path / "s", test_fmus, pack=False)
    (folder / "gain.ssv").write_text((folder / "gain.ssv").read_text().replace('name="k"', 'name="kk"'))
    with pytest.raises(ScenarioError) as info:
        orchestrator.run(folder, RunOptions(overrides={"integrator.x": 1.0, "nothere.k": 2.0,
                                                       "gain.k": "abc"}))
    assert set(info.value.problems) == {
        "gain.ssv: component 'gain' has no variable 'kk'",
        "overrides: integrator.x is a continuous output, it cannot be set",  # the API's field (issue 36)
        "overrides: no component named 'nothere' (for nothere.k)",
        "overrides gain.k: 'abc' is not a valid Real",
    }


def test_algebraic_loop_is_reported_by_name(tmp_path, test_fmus):
    gain = [("u", "input", "Real"), ("y", "output", "Real")]
    ring = SystemStructure("ring", (component("a", "Gain.fmu", gain), component("b", "Gain.fmu", gain)),
                           (Connection.between("a.y", "b.u"), Connection.between("b.y", "a.u")),
                           Experiment(0.0, 1.0, 0.1))
    write_ssd(tmp_path, ring)
    (tmp_path / "resources").mkdir()
    (tmp_path / "resources" / "Gain.fmu").write_bytes(test_fmus["Gain"].read_bytes())
    with pytest.raises(ScenarioError, match=r"algebraic loop: a\.u -> a\.y -> b\.u -> b\.y -> a\.u"):
        orchestrator.run(tmp_path)
