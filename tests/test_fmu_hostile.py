# SPDX-License-Identifier: BSD-2-Clause
"""An FMU never crashes its host (issue 30): tests/fmu_hostile_host.c makes the calls real hosts and
careless users make, each scenario in a child process, on all ten FMUs (FMI 2.0 and 3.0) and an
exported container, also under valgrind. Oracles: the FMI standard's state tables as the Modelica
Reference FMUs implement them (their Feedthrough FMU answers the same scenarios, run here by the
same host), the child's exit (a signal is a crash), and the resident memory of the process.

Before (main 5287c35): a missing, empty or non-file resource location and a NULL logger killed the
host (SIGSEGV; NULL: SIGABRT); wrong and NULL GUIDs, steps before initialization, after
fmi2Terminate and of size NaN, 0, -h or inf were answered fmi2OK; a bad value reference or setting an
output was fmi2Fatal logged with a NULL category; 16-34 KB leaked per instantiate/free cycle, 80 KB
per container cycle."""

from __future__ import annotations

import gc
import os
import re
import shutil
import subprocess
from pathlib import Path

import fmpy
import pytest
from fmpy.fmi2 import FMU2Slave
from fmu_helpers import MODELS
from hostile import CC, NAMINGS, NONSENSE, SCENARIOS, Outcome, compile_host, resources_of, run, unpack

from orchestrator.export import export

# `make hostile` (FTC_HOSTILE_ALL=1): every case; `make test`: one real run of each kind.
EVERY_CASE = os.environ.get("FTC_HOSTILE_ALL") == "1"
REFERENCE_FMUS = Path(__file__).resolve().parent.parent.parent / "shared" / "tools" / "reference-fmus"
VALGRIND = shutil.which("valgrind")
pytestmark = [pytest.mark.system, pytest.mark.skipif(CC is None, reason="needs a C compiler for the host")]
OK, ERROR, FATAL, SKIPPED = 0, 3, 4, -2
# The scenarios whose answer the Reference FMUs give too (theirs need no resources and hang on a
# NaN or infinite step, so those are checked against the standard's words below instead).
SAME_AS_REFERENCE = ("ok", "step-before-init", "get-before-init", "step-negative", "step-zero",
                     "unknown-vr", "set-output", "set-output-twice", "step-after-terminate", "after-error",
                     "reset-after-error", "guid-wrong")
# Scenario -> (status of the call under test, instance made, words of the first message).
EXPECTED = {
    "ok": (OK, True, ""),
    "resources-missing": (OK, True, "does not exist: using the FMU's own resources folder"),
    "resources-empty": (OK, True, "is empty: using the FMU's own resources folder"),
    "resources-null": (OK, True, "is not given: using the FMU's own resources folder"),
    "resources-not-a-file-uri": (OK, True, "is not a file URI or absolute path: using the FMU's own"),
    "guid-wrong": (ERROR, False, "is not this FMU's"),
    "guid-null": (ERROR, False, "is NULL"),
    "no-logger": (ERROR, True, ""),
    "no-callbacks": (OK, True, ""),
    "step-before-init": (ERROR, True, "DoStep: not allowed in Instantiated"),
    "get-before-init": (ERROR, True, "GetReal: not allowed in Instantiated"),
    "step-nan": (ERROR, True, "DoStep: the step from 0 by nan: the step size must be a positive finite"),
    "step-negative": (ERROR, True, "DoStep: the step from 0 by -0.001: the step size must be a positive"),
    "step-zero": (ERROR, True, "DoStep: the step from 0 by 0: the step size must be a positive"),
    "step-infinite": (ERROR, True, "DoStep: the step from 0 by inf: the step size must be a positive"),
    "unknown-vr": (ERROR, True, "no variable has the value reference 99999"),
    "set-output": (ERROR, True, "is an output: it cannot be set in Step Complete"),
    "set-output-twice": (ERROR, True, "is an output: it cannot be set in Step Complete"),
    "set-fixed-after-init": (ERROR, True, "is a fixed parameter: it cannot be set in Step Complete"),
    "step-after-terminate": (ERROR, True, "DoStep: not allowed in Terminated"),
    "after-error": (ERROR, True, "no variable has the value reference 99999"),
    "reset-after-error": (OK, True, "no variable has the value reference 99999"),
    "model-fails": (ERROR, True, "invalid parameters"),
    "fifty": (OK, True, ""),
    "two-threads": (OK, True, ""),
}
# Nonsense call -> what its one message says (a regular expression; FMI 2.0 | FMI 3.0 wording).
# Oracle: the standard's text, which makes each of them an error of the host (a NULL array where
# values are asked for, a stop time before the start, ...; a capability declared false: "the
# function must not be called").
NONSENSE_WORDS = {
    "debug-null-categories": "2 categories given, but the categories array is NULL",
    "debug-null-entry": r"categories\[1\] is NULL",
    "setup-stop-before-start": "the stop time 0.5 is before the start time 1",
    "setup-start-nan": "the start time nan is not a finite number",
    "setup-start-inf": "the start time inf is not a finite number",
    "setup-stop-inf": "the stop time inf is not a finite number",
    "setup-tolerance-nan": "the tolerance nan is not a positive finite number",
    "setup-tolerance-negative": "the tolerance -1e-06 is not a positive finite number",
    "get-null-vr": "1 values asked for, but the (value reference|valueReferences) array is NULL",
    "get-null-values": "1 values asked for, but the values? array is NULL",
    "set-null-values": "1 values asked for, but the values? array is NULL",
    "get-count-beyond": "1099511627776 value references, more than the model's [0-9]+ variables",
    "get-integer-null-vr": "array is NULL",
    "get-boolean-null-values": "array is NULL",
    "set-string-null-entry": r"value\[0\] is NULL, not a string",
    "get-state-null": "FMUstate pointer is NULL|FMUState is NULL",
    "set-state-null": "the FMUstate is NULL|FMUState is NULL",
    "get-state-undeclared-size": 'declares canSerializeFMU[Ss]tate="false"',
    "deserialize-null": 'declares canSerializeFMU[Ss]tate="false"|no state bytes',
    "directional-null": 'providesDirectionalDerivative="false"|directional derivatives are not provided',
    "output-derivatives-null": "maxOutputDerivativeOrder",
    "input-derivatives-null": 'canInterpolateInputs="false"',
    "status-null": "value is NULL",
    "real-status-null": "value is NULL",
}
FMI2_ONLY = ("input-derivatives-null", "status-null", "real-status-null")
CASES = [(version, model) for version in ("fmus", "fmus3") for model in MODELS]


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_host(tmp_path_factory.mktemp("hostile"))


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("unpacked")


@pytest.fixture(scope="module")
def container(built: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """example1 exported as one FMU (FMI 2.0), as `orchestrate export` writes it."""
    path, _ = export(built / "ssp" / "example1.ssp", tmp_path_factory.mktemp("container") / "example1.fmu")
    return path


def arguments(built: Path, version: str, model: str, unpacked: Path) -> list[str]:
    return unpack(built / version / f"{model}.fmu", unpacked)[1]


def reference_answers(host: Path, version: str, unpacked: Path) -> dict[str, Outcome]:
    fmu = REFERENCE_FMUS / ("2.0" if version == "fmus" else "3.0") / "Feedthrough.fmu"
    if not fmu.is_file():
        pytest.skip(f"no Reference FMU {fmu}")
    return run(host, unpack(fmu, unpacked)[1], SAME_AS_REFERENCE, timeout=120)[0]


@pytest.mark.parametrize(("version", "model"), CASES)
def test_no_call_crashes_the_host_and_each_refusal_says_why(host: Path, built: Path, unpacked: Path,
                                                          version: str, model: str) -> None:
    """Every scenario ends without a signal, no message has a NULL category, and each call under
    test answers as the standard says (and as the Reference FMUs do, where they answer it)."""
    outcomes, process = run(host, arguments(built, version, model, unpacked), SCENARIOS)
    for name, outcome in outcomes.items():
        status, made, words = EXPECTED[name]
        if name == "get-before-init" and version == "fmus3":  # FMI 3.0 allows getters in Instantiated
            status, words = OK, ""
        where = f"{version}/{model} {name}: {outcome}\n{process.stderr[-2000:]}"
        assert outcome.exit == "0", where
        assert outcome.null_categories == 0, where
        assert (outcome.status, outcome.instance) == (status, made), where
        assert words in outcome.message, where
    assert outcomes["model-fails"].extra == FATAL  # the model's own failure: pythonfmu's fmi2Fatal, latched
    assert outcomes["fifty"].extra == 50
    assert outcomes["two-threads"].extra == 1  # both threads end where a lone instance does
    reference = reference_answers(host, version, unpacked)
    for name in SAME_AS_REFERENCE:
        assert outcomes[name].status == reference[name].status, (name, outcomes[name], reference[name])


def other_fmu(built: Path, version: str, model: str, unpacked: Path) -> Path:
    """Another of the project's FMUs of the same FMI version, unpacked: its folder."""
    other = MODELS[(MODELS.index(model) + 1) % len(MODELS)]
    return Path(arguments(built, version, other, unpacked)[0])


@pytest.mark.parametrize(("version", "model"), CASES)
def test_another_fmus_resources_never_run_its_model(host: Path, built: Path, unpacked: Path, version: str,
                                                     model: str) -> None:
    """Given another of the project's FMUs' resources folder, the FMU uses its own (a warning says
    so, naming both identities) and runs its own model: the short run ends on the very output it
    gives with its own folder (the oracle: the FMU itself, given its own resources). Before (main
    633067d): the other folder was accepted without a word and the other FMU's model ran."""
    args = arguments(built, version, model, unpacked)
    other = resources_of(other_fmu(built, version, model, unpacked), args[1])
    outcomes, process = run(host, args, ["ok", f"resources-other={other}"])
    own, foreign = outcomes["ok"], outcomes[f"resources-other={other}"]
    where = f"{version}/{model}: {foreign}\n{process.stderr[-2000:]}"
    assert own.exit == foreign.exit == "0" and own.status == foreign.status == OK, where
    assert "is another FMU's resources folder" in foreign.message and args[3] in foreign.message, where
    assert "using the FMU's own resources folder" in foreign.message, where
    assert foreign.extra == own.extra, where  # the same model, the same inputs: the same output


def nonsense_answers(host: Path, args: list[str]) -> tuple[dict[str, Outcome], str]:
    outcomes, process = run(host, args, NONSENSE)
    return outcomes, process.stderr[-2000:]


@pytest.mark.parametrize(("version", "model"), CASES)
def test_nonsense_arguments_get_an_error_and_one_message(host: Path, built: Path, unpacked: Path,
                                                         version: str, model: str) -> None:
    """Every array, string and time argument checked: each nonsense call (a NULL array or entry, a
    count beyond any array, stop before start, a non-finite time or tolerance, a capability declared
    false) answers Error and logs exactly one message saying why, and nothing reaches pythonfmu.
    Before (main 633067d): NULL categories killed every FMU (SIGSEGV), a NULL entry the FMI 2.0 ones
    (SIGABRT), nonsense times were answered OK, a serialized state size Fatal with pythonfmu's message."""
    outcomes, stderr = nonsense_answers(host, arguments(built, version, model, unpacked))
    for name, outcome in outcomes.items():
        where = f"{version}/{model} {name}: {outcome}\n{stderr}"
        assert outcome.exit == "0" and outcome.null_categories == 0, where
        if version == "fmus3" and name in FMI2_ONLY:
            assert outcome.status == SKIPPED, where
            continue
        assert (outcome.status, outcome.instance, outcome.extra) == (ERROR, True, 1), where
        assert re.search(NONSENSE_WORDS[name], outcome.message), where


@pytest.mark.parametrize(("version", "model"), CASES)
def test_more_debug_categories_than_declared_are_refused(host: Path, built: Path, unpacked: Path,
                                                         version: str, model: str) -> None:
    """Issue 44: fmi2SetDebugLogging / fmi3SetDebugLogging with a count beyond the model's declared
    log categories (2^40 names in an array of two) answers Error with one message naming the
    count, and reads none of the names. Oracle: the LogCategories of the FMU's modelDescription.xml
    as fmpy reads them. Before: the count was not bounded (the shim walked the host's array)."""
    declared = len(fmpy.read_model_description(str(built / version / f"{model}.fmu")).logCategories)
    assert declared >= 1
    outcomes, process = run(host, arguments(built, version, model, unpacked), ["debug-categories-beyond"])
    outcome = outcomes["debug-categories-beyond"]
    where = f"{version}/{model}: {outcome}\n{process.stderr[-2000:]}"
    assert outcome.exit == "0" and outcome.null_categories == 0, where
    assert (outcome.status, outcome.instance, outcome.extra) == (ERROR, True, 1), where
    expected = f"1099511627776 categories given, more than the model's {declared} log categories"
    assert expected in outcome.message, where


@pytest.mark.parametrize("fmi", ["2", "3"])
def test_the_containers_refuse_nonsense_arguments(host: Path, built: Path, tmp_path: Path, fmi: str) -> None:
    """Both exported containers (their own guard, orchestrator/native/container_fmi2.c): each
    nonsense call answers Error with one message, none crashes; another FMU's resources folder
    changes nothing (the container always uses its own). Before (main 633067d): NULL categories
    killed the host (SIGSEGV, through the embedded FMUs' shims) and nonsense times were answered OK."""
    path, _ = export(built / "ssp" / "example1.ssp", tmp_path / "example1.fmu", fmi=fmi)
    args = unpack(path, tmp_path)[1]
    outcomes, stderr = nonsense_answers(host, args)
    for name, outcome in outcomes.items():
        where = f"container FMI {fmi} {name}: {outcome}\n{stderr}"
        assert outcome.exit == "0" and outcome.null_categories == 0, where
        if fmi == "3" and name in FMI2_ONLY:
            continue
        assert (outcome.status, outcome.extra) == (ERROR, 1), where
        if name.startswith("debug-"):  # the message names the host's function
            assert outcome.message.startswith(f"fmi{fmi}SetDebugLogging: "), where
        if name.startswith("setup-"):
            function = "fmi2SetupExperiment" if fmi == "2" else "fmi3EnterInitializationMode"
            assert outcome.message.startswith(f"{function}: "), where
    actuator = arguments(built, "fmus" if fmi == "2" else "fmus3", "Actuator", tmp_path)[0]
    other = resources_of(Path(actuator), fmi)
    answers = run(host, args, ["ok", f"resources-other={other}"])[0]
    assert answers["ok"].status == answers[f"resources-other={other}"].status == OK, answers
    assert answers["ok"].extra == answers[f"resources-other={other}"].extra, answers


@pytest.mark.parametrize("fmi", ["2", "3"] if EVERY_CASE else ["2"])
def test_the_container_never_crashes_and_latches_after_an_error(host: Path, built: Path, unpacked: Path,
                                                                tmp_path: Path, fmi: str) -> None:
    """The exported container (its own guard in orchestrator/native/container.c): every scenario
    ends without a signal; a NULL GUID is refused; after an error a step is refused (before: the
    container went on stepping)."""
    path, _ = export(built / "ssp" / "example1.ssp", tmp_path / "example1.fmu", fmi=fmi)
    outcomes, process = run(host, unpack(path, tmp_path)[1], SCENARIOS)
    for name, outcome in outcomes.items():
        assert outcome.exit == "0" and outcome.null_categories == 0, (name, outcome, process.stderr[-2000:])
    assert not outcomes["guid-null"].instance and not outcomes["guid-wrong"].instance
    for name in ("step-before-init", "step-nan", "step-zero", "step-negative", "step-infinite", "unknown-vr",
                 "set-output", "step-after-terminate", "after-error"):
        assert outcomes[name].status == ERROR, (name, outcomes[name])
    assert outcomes["reset-after-error"].status == OK
    assert outcomes["fifty"].extra == 50 and outcomes["two-threads"].extra == 1


# `make test`: one real case of each naming; `make hostile`: every FMU and both containers, each naming.
LEAK_CASES = ([(f"{v}/{m}", n) for v, m in CASES for n in NAMINGS] +
              [(c, n) for c in ("container", "container3") for n in NAMINGS]) if EVERY_CASE else [
    ("fmus3/FixedTimeController", "distinct"), ("fmus/Actuator", "alternating"), ("container", "distinct"),
    ("fmus/Example1Plant", "same")]


@pytest.mark.parametrize(("case", "naming"), LEAK_CASES, ids=[f"{c}-{n}" for c, n in LEAK_CASES])
def test_at_most_1_kb_per_instantiate_free_cycle(host: Path, built: Path, unpacked: Path, container: Path,
                                                 tmp_path: Path, case: str, naming: str) -> None:
    """1000 instantiate/free cycles (after 500 that fill Python's and the allocator's caches), the
    instances named the same, anew each time (run0, run1, ...) or two names in turn: the resident
    memory grows by at most 1 KB a cycle (before, one name: 19.7 KB for Actuator, 32.8 KB for
    FixedTimeController, 80 KB for the container; at main 633067d, new names: 7.4-18.8 KB on
    every FMU, the pool reusing a component only for the same name)."""
    if case == "container":
        args = unpack(container, unpacked)[1]
    elif case == "container3":
        exported = export(built / "ssp" / "example1.ssp", tmp_path / "example1.fmu", fmi="3")[0]
        args = unpack(exported, tmp_path)[1]
    else:
        version, model = case.split("/")
        args = arguments(built, version, model, unpacked)
    scenario = f"{NAMINGS[naming]}=1000"
    outcome = run(host, args, [scenario])[0][scenario]
    assert outcome.exit == "0" and outcome.status == OK, outcome
    print(f"{case}, {naming} names: {outcome.extra / 1024:.2f} KB per cycle")  # the figure (pytest -rP)
    assert outcome.extra <= 1024, f"{case}, {naming} names: {outcome.extra:.0f} bytes per cycle"


def test_a_component_reused_for_a_new_name_takes_that_name(built: Path, tmp_path: Path) -> None:
    """The pool hands a freed component to an instance of another name: its Python slave then
    bears the new name (what the model logs under), in FMPy as host. Oracle: the names FMPy gave."""
    folder = Path(fmpy.extract(str(built / "fmus" / "Actuator.fmu"), str(tmp_path / "fmu")))
    md = fmpy.read_model_description(str(folder))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=str(folder), instanceName="run0",
                    modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate()
    for name in ("run1", "run2"):
        fmu.fmi2FreeInstance(fmu.component)
        fmu.instanceName = name
        fmu.instantiate()
        gc.collect()
        slaves = [o for o in gc.get_objects() if type(o).__name__ == "Actuator"]
        names = {o.instance_name for o in slaves if isinstance(getattr(o, "instance_name", None), str)}
        # pythonfmu constructs the reused component's slave as "run0" (the name it was first
        # instantiated with); the shim renames it (an older slave may await the collector)
        assert name in names and "run0" not in names, (name, names)
    fmu.freeInstance()


FEW = ("ok", "resources-null", "guid-null", "no-logger", "unknown-vr", "after-error", "model-fails",
       "debug-null-entry", "get-count-beyond", "set-string-null-entry", "get-state-undeclared-size")
VALGRIND_CASES = [("fmus/Actuator", SCENARIOS + NONSENSE if EVERY_CASE else FEW),
                  ("fmus3/Reference", ("ok", "resources-null", "unknown-vr", "after-error", "model-fails",
                                       "set-output-twice", *NONSENSE)),
                  ("container", ("ok", "after-error", *NONSENSE))][: 3 if EVERY_CASE else 1]


@pytest.mark.skipif(VALGRIND is None, reason="valgrind is not installed")
@pytest.mark.parametrize(("case", "scenarios"), VALGRIND_CASES, ids=[c[0] for c in VALGRIND_CASES])
def test_valgrind_finds_no_error(host: Path, built: Path, unpacked: Path, container: Path, case: str,
                                 scenarios: tuple[str, ...]) -> None:
    """memcheck over every process of the scenarios (the host and each child): 0 errors (leaks are
    the leak test's business: Python keeps its interpreter to the end)."""
    if case == "container":
        args = unpack(container, unpacked)[1]
    else:
        version, model = case.split("/")
        args = arguments(built, version, model, unpacked)
    assert VALGRIND is not None
    wrapper = (VALGRIND, "--error-exitcode=99", "--errors-for-leak-kinds=none", "--leak-check=no")
    outcomes, process = run(host, args, scenarios, wrapper=wrapper, timeout=900)
    summaries = [line for line in process.stderr.splitlines() if "ERROR SUMMARY" in line]
    assert process.returncode == 0, process.stderr[-3000:]
    assert len(summaries) == len(scenarios) + 1  # the host and one child per scenario
    assert all(" 0 errors from 0 contexts" in line for line in summaries), summaries
    assert all(o.exit == "0" for o in outcomes.values()), outcomes


def test_the_host_sees_the_crash_it_is_there_for(host: Path, tmp_path: Path) -> None:
    """The host itself: a child that dies by a signal is reported as a crash (a library whose
    fmi2Instantiate dereferences NULL when given the zero GUID, compiled here)."""
    assert CC is not None
    fmu = tmp_path / "crash"
    (fmu / "binaries" / "linux64").mkdir(parents=True)
    source = tmp_path / "crash.c"
    source.write_text("void *fmi2Instantiate(const char *n, int t, const char *guid) {\n"
                      "    return guid[1] == '0' ? *(void **)0 : (void *)1;\n}\n"
                      "void fmi2FreeInstance(void *c) { (void)c; }\n")
    subprocess.run([CC, "-shared", "-fPIC", "-O0", "-o", str(fmu / "binaries" / "linux64" / "crash.so"),
                    str(source)], check=True)
    outcome = run(host, [str(fmu), "2", "crash", "{x}", "-1", "-1", "-1"], ["guid-wrong"])[0]["guid-wrong"]
    assert outcome.crashed and outcome.exit == "signal 11", outcome
