# SPDX-License-Identifier: BSD-2-Clause
"""orchestrate regress and baseline on suites of small real FMUs: the C Ramp FMU of tests/c_fmu.py,
whose output is x(t) = n t exactly (the oracle of every baseline and excursion here), and one that
crashes its process on purpose; the layout's errors; the JUnit XML against Jenkins' schema; the
HTML report's links; Ctrl-C during a suite. Each command's exit status is the documented one.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
from c_fmu import CRASH, build_ramp, compiler, ramp_scenario
from lxml import etree, html

from fmu_src.toolchain import stamps
from orchestrator.cli import main
from orchestrator.regress import Tolerances, compare, thin
from orchestrator.regress.junit import junit_xml
from orchestrator.regress.report import report_html
from orchestrator.regress.suite import ERROR, FAIL, NOT_RUN, PASS, Case, Outcome
from orchestrator.results import read_result

REPO = Path(__file__).resolve().parent.parent
SCHEMA = etree.XMLSchema(etree.parse(str(REPO / "tests" / "schemas" / "junit-10.xsd")))

needs_cc = pytest.mark.skipif(compiler() is None, reason="no C compiler (cc) for the Ramp test FMU")


def exit_status(argv: list[str]) -> int:
    """``orchestrate ARGV``'s exit status, whether returned or raised by argparse (usage errors)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


@pytest.fixture(scope="module")
def ramp_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_ramp(tmp_path_factory.mktemp("ramp"))


def ramp(suite: Path, name: str, fmu: Path, n: int, stop: float = 1.0, step: float = 1e-3) -> Path:
    """``suite/name.ssp``: the Ramp FMU with n bound from an SSV (replacing an archive of that name)."""
    source = suite.parent / "sources" / name
    if source.exists():
        shutil.rmtree(source)
    archive = ramp_scenario(source, fmu, stop=stop, step=step, n=n)
    suite.mkdir(parents=True, exist_ok=True)
    return Path(shutil.move(archive, suite / f"{name}.ssp"))


def sigint_held(pid: int) -> bool:
    """Whether process ``pid`` blocks or ignores SIGINT now (``/proc/PID/status``)."""
    status = dict(line.split(":\t", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                  if ":\t" in line)
    bit = 1 << (signal.SIGINT - 1)
    return bool((int(status["SigBlk"], 16) | int(status["SigIgn"], 16)) & bit)


def junit_of(path: Path) -> etree._Element:
    tree = etree.parse(str(path)).getroot()
    assert SCHEMA.validate(tree), SCHEMA.error_log
    return tree


# -- the suite on real FMUs -------------------------------------------------------------------------
@pytest.mark.system
@needs_cc
def test_baseline_then_regress_then_a_changed_scenario(ramp_fmu: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    suite = tmp_path / "regression"
    ramp(suite, "ramp2", ramp_fmu, 2)
    ramp(suite, "ramp3", ramp_fmu, 3)
    assert main(["baseline", str(suite)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^new\s+ramp2\s+written .*ramp2.csv \(new\)", out, re.M), out
    for n in (2, 3):
        stored = read_result(suite / "baselines" / f"ramp{n}.csv")
        assert stored.dtype.names == ("time", "ramp.x")
        assert np.allclose(stored["time"], np.arange(51) * 0.02, rtol=0, atol=1e-12)  # 20 steps of 1 ms
        assert np.allclose(stored["ramp.x"], n * stored["time"], rtol=1e-9, atol=1e-12)

    junit = tmp_path / "out" / "junit.xml"
    assert main(["regress", str(suite), "--junit-xml", str(junit), "--html", str(tmp_path / "report")]) == 0
    out = capsys.readouterr().out
    assert "PASS: 2 scenarios: 2 passed, 0 regressed, 0 failed to run" in out
    assert junit_of(junit).get("failures") == "0"

    ramp(suite, "ramp3", ramp_fmu, 4)  # the user's change: n 3 -> 4
    assert main(["regress", str(suite), "--junit-xml", str(junit), "--jobs", "1"]) == 1
    out = capsys.readouterr().out
    # x = 4 t against 3 t: 1 beyond at t = 1 s, less the default tube (1 % of the baseline's range 3)
    assert re.search(r"^REGRESSION\s+ramp3\s+1 of 1 signals outside their tubes: ramp\.x \(0\.97 beyond at "
                     r"t = 1\.000 s\)", out, re.M), out
    assert re.search(r"^PASS\s+ramp2\s", out, re.M)
    tree = junit_of(junit)
    failed = {c.get("name"): c.find("failure") for c in tree.iter("testcase")}
    assert failed["ramp2"] is None and failed["ramp3"].get("type") == "regression"
    assert "| ramp.x | 0.03 | 0.040 | 1.000 | 0.97 |" in failed["ramp3"].text


@pytest.mark.system
@needs_cc
def test_a_crashing_fmu_fails_its_scenario_only(ramp_fmu: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture) -> None:
    """The first scenario's FMU kills its worker process (SIGSEGV); the one worker left (--jobs 1)
    is replaced and runs the others."""
    suite = tmp_path / "regression"
    ramp(suite, "a_crash", ramp_fmu, CRASH)
    ramp(suite, "ramp2", ramp_fmu, 2)
    ramp(suite, "ramp3", ramp_fmu, 3)
    assert main(["baseline", str(suite / "ramp2.ssp"), str(suite / "ramp3.ssp")]) == 0
    shutil.copy(suite / "baselines" / "ramp2.csv", suite / "baselines" / "a_crash.csv")
    junit = tmp_path / "junit.xml"
    assert main(["regress", str(suite), "--jobs", "1", "--junit-xml", str(junit)]) == 1
    out = capsys.readouterr().out
    died = r"^ERROR\s+a_crash\s+the process running it died \(signal 11 \(SIGSEGV\)\)"
    assert re.search(died, out, re.M), out
    assert len(re.findall(r"^PASS\s+ramp[23]\s", out, re.M)) == 2
    assert "1 passed" not in out and "2 passed, 0 regressed, 1 failed to run" in out
    tree = junit_of(junit)
    assert tree.get("errors") == "1"
    assert [c.get("name") for c in tree.iter("testcase") if c.find("error") is not None] == ["a_crash"]


@pytest.mark.system
@needs_cc
def test_review_then_accept_one_signal(ramp_fmu: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    suite = tmp_path / "regression"
    ramp(suite, "ramp3", ramp_fmu, 3)
    ramp(suite, "ramp5", ramp_fmu, 5)
    assert main(["baseline", str(suite)]) == 0
    stored = {p.name: p.read_bytes() for p in (suite / "baselines").iterdir()}
    ramp(suite, "ramp3", ramp_fmu, 4)
    capsys.readouterr()
    assert main(["baseline", str(suite), "--review", str(tmp_path / "review")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^CHANGED\s+ramp3\s+1 of 1 signals outside their tubes", out, re.M), out
    signal_line = r"^  ramp\.x\s+max change 1, outside its tube \+-0\.03 from t = 0\.040 s"
    assert re.search(signal_line, out, re.M), out
    assert re.search(r"^unchanged\s+ramp5\s", out, re.M)
    assert "not accepted: ramp3" in out
    assert {p.name: p.read_bytes() for p in (suite / "baselines").iterdir()} == stored
    review = html.fromstring((tmp_path / "review" / "index.html").read_bytes())
    badges = [b.text for b in review.xpath('//table[@id="scenarios"]//span[@class="badge"]')]
    assert badges == ["CHANGED", "OK"]

    # an unknown scenario or signal is refused before anything is written
    assert exit_status(["baseline", str(suite), "--accept", "nope"]) == 2
    assert "--accept nope: no scenario 'nope' among those given (ramp3, ramp5)" in capsys.readouterr().err
    assert exit_status(["baseline", str(suite), "--accept", "ramp3:ramp.y"]) == 2
    assert "no signal 'ramp.y' in this run of ramp3 (signals: ramp.x)" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in (suite / "baselines").iterdir()} == stored

    assert main(["baseline", str(suite), "--accept", "ramp3:ramp.x"]) == 0
    assert "(ramp.x accepted)" in capsys.readouterr().out
    accepted = read_result(suite / "baselines" / "ramp3.csv")
    assert np.allclose(accepted["ramp.x"], 4 * accepted["time"], rtol=1e-9, atol=1e-12)
    assert (suite / "baselines" / "ramp5.csv").read_bytes() == stored["ramp5.csv"]
    assert main(["regress", str(suite)]) == 0


@pytest.mark.system
@needs_cc
def test_layout_and_setup_errors_are_one_line_each(ramp_fmu: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    suite = tmp_path / "regression"
    archive = ramp(suite, "ramp2", ramp_fmu, 2)
    assert exit_status(["regress", str(suite)]) == 2
    err = capsys.readouterr().err
    assert f"{archive}: no baseline {suite / 'baselines' / 'ramp2.csv'} (write it with 'orchestrate " \
           f"baseline {archive}')" in err
    assert "Traceback" not in err, err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert exit_status(["regress", str(empty)]) == 2
    assert "no scenarios in it" in capsys.readouterr().err
    assert exit_status(["regress", str(tmp_path / "nowhere")]) == 2
    assert f"{tmp_path / 'nowhere'}: no such file or folder" in capsys.readouterr().err
    assert exit_status(["regress", "nowhere"]) == 2  # a name: a scenario built into build/ssp/
    err = capsys.readouterr().err
    assert "no scenario 'nowhere': not a file or folder, and no built scenario build/ssp/nowhere.ssp" in err
    assert "Traceback" not in err, err
    # two scenarios of one name sharing a baselines folder
    ramp(tmp_path / "two" / "a", "x", ramp_fmu, 1)
    ramp(tmp_path / "two" / "b", "x", ramp_fmu, 1)
    assert exit_status(["regress", str(tmp_path / "two"), "--baselines", str(tmp_path / "shared")]) == 2
    assert "would share the baseline" in capsys.readouterr().err
    # a tolerance file that cannot be read names itself
    assert main(["baseline", str(suite)]) == 0
    (suite / "baselines" / "tolerances.json").write_text(json.dumps({"signals": {"ramp.x": {"atol": -1}}}))
    assert exit_status(["regress", str(suite)]) == 2
    assert "tolerances.json: signal 'ramp.x': tolerance atol must be" in capsys.readouterr().err
    assert exit_status(["regress", str(suite), "--jobs", "0"]) == 2
    assert exit_status(["regress", str(suite), "--html", str(archive)]) == 2
    assert "not a folder" in capsys.readouterr().err


@pytest.mark.system
@needs_cc
def test_a_run_over_its_timeout_fails_its_scenario(ramp_fmu: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture) -> None:
    suite = tmp_path / "regression"
    slow = ramp(suite, "slow", ramp_fmu, 1, stop=1e4, step=1e-4)  # 1e8 steps: > 1 s in C too
    (suite / "baselines").mkdir()
    (suite / "baselines" / "slow.csv").write_text("time,ramp.x\n0,0\n1000,1000\n")
    assert main(["regress", str(slow), "--timeout", "1"]) == 1
    out = capsys.readouterr().out
    assert re.search(r"^ERROR\s+slow\s+the run failed: wall-clock limit of 1 s", out, re.M), out


def command_line(child: psutil.Process) -> str:
    """The child's command line, "" once it has ended (a zombie not reaped yet included): a short
    child of the command (a compiler, a resource tracker) may end between listing and reading."""
    try:
        return " ".join(child.cmdline())
    except psutil.NoSuchProcess:  # ZombieProcess is one
        return ""


@pytest.mark.system
@needs_cc
def test_ctrl_c_ends_the_workers_and_writes_the_reports(ramp_fmu: Path, tmp_path: Path) -> None:
    """SIGINT to the command's process group, as a terminal's Ctrl-C: exit 130 at once, no
    traceback, no worker left, and the JUnit XML says which scenarios did not run."""
    suite = tmp_path / "regression"
    for name in ("slow1", "slow2", "slow3"):
        ramp(suite, name, ramp_fmu, 1, stop=1e4, step=1e-4)  # 1e8 steps: > 1 s in C too
        (suite / "baselines").mkdir(exist_ok=True)
        (suite / "baselines" / f"{name}.csv").write_text("time,ramp.x\n0,0\n1000,1000\n")
    junit = tmp_path / "junit.xml"
    command = [sys.executable, "-m", "orchestrator", "regress", str(suite), "--jobs", "2",
               "--junit-xml", str(junit)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    held: dict[int, bool] = {}  # worker pid -> SIGINT blocked or ignored when first seen
    try:
        deadline = time.monotonic() + 60
        workers: list[psutil.Process] = []
        while len(workers) < 2 and time.monotonic() < deadline:  # both workers up and stepping
            time.sleep(0.05)
            workers = [c for c in psutil.Process(process.pid).children() if "spawn_main" in command_line(c)]
            for worker in workers:
                held.setdefault(worker.pid, sigint_held(worker.pid))
        time.sleep(1.0)
        os.killpg(process.pid, signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == 130, out + err
    assert "interrupted by SIGINT: 0 of 3 scenarios finished" in err
    assert "Traceback" not in err, err
    assert len(workers) == 2
    # A Ctrl-C while a worker still imports (a loaded machine) must find SIGINT held there too:
    # the first worker's was not (multiprocessing's resource tracker unblocked it in the parent)
    assert held == dict.fromkeys(held, True) and len(held) == 2, held
    assert not any(w.is_running() and w.status() != psutil.STATUS_ZOMBIE for w in workers)
    tree = junit_of(junit)
    assert [c.find("skipped").get("message") for c in tree.iter("testcase")] == \
        ["not run: the suite was interrupted"] * 3


# -- issue 36: compare's verdict and baseline's rebuild ---------------------------------------------
@pytest.mark.system
def test_compare_a_result_without_the_input_columns(built: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    """Issue 36 item 1: a result without the input copies (--no-inputs, as fmusim writes an exported
    scenario) against a full one: every shared signal agrees, the missing columns are listed, the
    verdict is PASS (main: REGRESSION, exit 1); --signal makes a chosen column required."""
    archive = built / "ssp" / "example1.ssp"
    full, outputs = tmp_path / "full.csv", tmp_path / "outputs.csv"
    for target, extra in ((full, []), (outputs, ["--no-inputs"])):
        assert main(["run", str(archive), "--stop-time", "0.2", "--output", str(target), "--no-plot",
                     "--quiet", *extra]) == 0
    assert main(["compare", str(outputs), str(full)]) == 0
    out = capsys.readouterr().out
    missing = re.search(r"^missing in .*outputs\.csv \(not compared\): (.*)$", out, re.M)
    assert missing is not None and len(missing.group(1).split(", ")) == 9, out
    assert "PASS: 16 of 16 signals inside their tubes" in out
    assert main(["compare", str(outputs), str(full), "--signal", "controller.*"]) == 1
    assert "missing in" in capsys.readouterr().out


def test_baseline_builds_nothing(tmp_path: Path) -> None:
    """Issue 36 item 7: 'orchestrate baseline' of this project's built scenario uses the build as it
    is (main rebuilt every FMU first, 4 min 38 s without a word); a build older than its sources is
    refused with the way out, before anything runs. The FMU builder is watched (called through)."""
    project = tmp_path / "project"
    (project / "build" / "ssp").mkdir(parents=True)
    archive = project / "build" / "ssp" / "example1.ssp"
    archive.write_bytes(b"an archive built from other sources")
    shutil.copytree(REPO / "ssp" / "example1", project / "ssp" / "example1")
    # its record (as 'orchestrate build' writes it) names a parameter file with other bytes than now
    stamps.record(archive, "key", {"ssp/example1/plant.ssv": "0" * 64}, project)
    script = ("import sys\nimport fmu_src.toolchain.build as builder\ncalls = []\nreal = builder.build_fmu\n"
              "def watched(*args, **kwargs):\n    calls.append(args)\n    return real(*args, **kwargs)\n"
              "builder.build_fmu = watched\nfrom orchestrator.cli import main\n"
              "try:\n    status = main(sys.argv[1:])\nexcept SystemExit as exc:\n    status = exc.code\n"
              "assert not calls, 'the FMUs were built'\nsys.exit(status)\n")
    done = subprocess.run([sys.executable, "-c", script, "baseline", "example1", "--baselines", "out"],
                          cwd=project, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    assert "build/ssp/example1.ssp is stale: ssp/example1/plant.ssv changed since it was built" in done.stderr
    assert "run 'orchestrate build example1'" in done.stderr
    assert not (project / "out").exists() and "Traceback" not in done.stderr


# -- the report and the JUnit XML, from outcomes made here (no FMU) ------------------------------------
def outcomes(tmp_path: Path) -> list[Outcome]:
    """One outcome of each kind; the failing one from a real comparison of x = 3 t with x = 4 t."""
    t = np.linspace(0.0, 1.0, 51)
    table = np.zeros(51, dtype=[("time", float), ("ramp.x", float)])
    table["time"] = t
    base, changed = table.copy(), table.copy()
    base["ramp.x"], changed["ramp.x"] = 3 * t, 4 * t
    comparison = compare(changed, base, Tolerances(), "x (this run)", "x.csv", signals=["ramp.x"])

    def case(name: str) -> Case:
        return Case(name, tmp_path / f"{name}.ssp", tmp_path / "baselines" / f"{name}.csv", "suite/sub")

    return [Outcome(case("fails"), FAIL, "1 of 1 signals outside", comparison, seconds=1.5),
            Outcome(case("passes <&>"), PASS, "1 signals inside", compare(base, base), seconds=0.25),
            Outcome(case("errs"), ERROR, "cannot run: FMU says \x01\x1b[31m", detail="Traceback ...\x00",
                    warnings=["unconnected \x07 input"]),
            Outcome(case("later"), NOT_RUN, "not run: the suite was interrupted")]


def test_junit_xml_is_valid_with_every_kind_of_outcome(tmp_path: Path) -> None:
    tree = etree.fromstring(junit_xml(outcomes(tmp_path), 1.75))
    assert SCHEMA.validate(tree), SCHEMA.error_log
    suite = tree.find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors"), suite.get("skipped")) == \
        ("4", "1", "1", "1")
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    assert cases["fails"].get("classname") == "suite/sub" and cases["fails"].get("time") == "1.500"
    assert "| ramp.x | 0.03 |" in cases["fails"].find("failure").text
    assert cases["errs"].find("error").get("message") == "cannot run: FMU says \ufffd\ufffd[31m"
    assert cases["errs"].find("system-err").text == "warning: unconnected \ufffd input\n"
    assert cases["later"].find("skipped") is not None and cases["passes <&>"].find("failure") is None


def test_report_ids_are_unique_and_every_link_resolves(tmp_path: Path) -> None:
    page = html.fromstring(report_html(outcomes(tmp_path), "title", "heading"))
    ids = [e.get("id") for e in page.iter() if e.get("id")]
    assert len(ids) == len(set(ids))
    targets = [a.get("href")[1:] for a in page.iter("a") if a.get("href", "").startswith("#")]
    assert targets and set(targets) <= set(ids)
    assert [i.get("src")[:22] for i in page.iter("img")] == ["data:image/png;base64,"]  # one failing signal
    fetched = [e for e in page.iter("link", "script")
               if e.get("src") or not e.get("href", "data:").startswith("data:")]
    assert not fetched  # self-contained: nothing loaded from a file or the network


def test_baseline_rows_are_the_runs_own() -> None:
    """thin keeps every k-th row of the run and its last (no interpolation), rounded as written."""
    t = np.arange(0, 1001) * 0.001
    rows = np.zeros(len(t), dtype=[("time", float), ("x", float), ("u", float)])
    rows["time"], rows["x"] = t, np.sin(t) / 3
    kept = thin(rows, 0.02, ["x"])
    assert kept.dtype.names == ("time", "x")
    assert np.array_equal(kept["time"], t[::20])
    assert np.array_equal(kept["x"], [float(f"{v:.9g}") for v in rows["x"][::20]])
    assert np.array_equal(thin(rows[:995], 0.02)["time"][-2:], [t[980], t[994]])  # and the last row
