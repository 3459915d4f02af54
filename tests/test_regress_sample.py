# SPDX-License-Identifier: BSD-2-Clause
"""A user's project regressed as their CI would: the sample project tests/sample_project (three
scenarios, one of them two Modelica Reference FMUs, i.e. third party) run with the commands of the
CI templates docs/ci/github-actions.yml and docs/ci/gitlab-ci.yml, verbatim, with the templates'
variables: the install of the orchestrator into a fresh virtual environment from a git clone of
this checkout (the templates' repository URL replaced by it), then the project clean, then with a
fault shifted 1 s and a controller gain changed 5 %. Both changes must be caught, the third scenario
must still pass; the JUnit XML is validated against the schema Jenkins reads; the HTML report is
opened in headless Chromium (no console error, every link and figure resolves, and the screenshot
shows the verdicts); the pytest plugin collects the same scenarios next to a project's own tests.

Oracles: the changes this test makes (which scenario must fail, which must pass), Jenkins' JUnit
schema (tests/schemas/junit-10.xsd, a third party's file), pytest's own JUnit writer, the browser.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from browser import Browser, chromium
from lxml import etree
from matplotlib.image import imread

from orchestrator.experiments.scenarios import component_sources

pytestmark = [pytest.mark.system, pytest.mark.xdist_group("regress-sample")]

REPO = Path(__file__).resolve().parent.parent
SAMPLE = REPO / "tests" / "sample_project"
TEMPLATES = [REPO / "docs" / "ci" / "github-actions.yml", REPO / "docs" / "ci" / "gitlab-ci.yml"]
SCHEMA = etree.XMLSchema(etree.parse(str(REPO / "tests" / "schemas" / "junit-10.xsd")))
REFERENCE_FMUS = REPO.parent / "shared" / "tools" / "reference-fmus" / "2.0"
OUTPUT = os.environ.get("REGRESS_SAMPLE_OUTPUT")  # make test: results/regress-sample (closing note)
BIN = Path(sys.executable).parent

needs_reference_fmus = pytest.mark.skipif(not (REFERENCE_FMUS / "VanDerPol.fmu").is_file(),
                                          reason=f"no Modelica Reference FMUs in {REFERENCE_FMUS}")


def template_commands(path: Path) -> list[str]:
    """Every shell command of a CI template: GitHub's ``run`` steps, GitLab's ``before_script`` and
    ``script`` lines, in order."""
    data = yaml.safe_load(path.read_text())
    commands: list[str] = []
    if "jobs" in data:  # GitHub Actions
        for job in data["jobs"].values():
            commands += [line for step in job["steps"] if "run" in step for line in step["run"].splitlines()]
    else:  # GitLab CI
        for job in data.values():
            if isinstance(job, dict):
                commands += [*job.get("before_script", []), *job.get("script", [])]
    return [c.strip() for c in commands if c.strip()]


def template_variables(path: Path) -> dict[str, str]:
    """The variables a CI template sets for every command: GitHub's workflow ``env``, GitLab's
    ``variables``."""
    data = yaml.safe_load(path.read_text())
    variables = data.get("env" if "jobs" in data else "variables", {})
    return {name: str(value) for name, value in variables.items()}


def test_templates_install_the_orchestrator_from_its_repository_then_run_it() -> None:
    """The orchestrator is not on PyPI (the templates installed a 'fixed-time-cosim==0.1.0' that
    does not exist): both install it from a git URL the user sets, at a ref; every other command is
    an 'orchestrate' one."""
    for path in TEMPLATES:
        commands = template_commands(path)
        installs = [c for c in commands if c.startswith("pip install")]
        assert installs == ['pip install "$ORCHESTRATOR_PACKAGE"'], path
        assert all(c.startswith("orchestrate ") for c in commands if c not in installs), commands
        assert any(c.startswith("orchestrate regress ") and "--junit-xml" in c for c in commands), path
        package = template_variables(path)["ORCHESTRATOR_PACKAGE"]
        assert re.fullmatch(r"git\+https://[^@\s]+/fixed-time-cosim\.git@[\w./-]+", package), package


def from_this_checkout(variables: dict[str, str]) -> dict[str, str]:
    """A template's variables with the orchestrator's git URL and ref replaced by this checkout's
    path and its HEAD commit (a clone at that commit: what is not committed is not installed)."""
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                          check=True).stdout.strip()
    package, count = re.subn(r"git\+https://[^@\s]+@[\w./-]+", f"git+{REPO.as_uri()}@{head}",
                             variables["ORCHESTRATOR_PACKAGE"])
    assert count == 1, variables
    return {**variables, "ORCHESTRATOR_PACKAGE": package}


def user_project(dest: Path, fmus: Path) -> Path:
    """A checkout of the sample project with each scenario's FMUs in its resources/: this project's
    from ``fmus``, the Reference FMUs from the shared tools (FMUs are built files, so a user's
    repository would hold them where ours cannot)."""
    shutil.copytree(SAMPLE, dest)
    for ssd in sorted(dest.glob("regression/*/SystemStructure.ssd")):
        resources = ssd.parent / "resources"
        resources.mkdir()
        for name in component_sources(ssd.parent):
            shutil.copy(fmus / name if (fmus / name).is_file() else REFERENCE_FMUS / name, resources / name)
    return dest


def run(command: str, cwd: Path, bindir: Path = BIN, variables: dict[str, str] | None = None
        ) -> subprocess.CompletedProcess:
    """A template's command as a CI runner runs it: a shell in the project with the template's
    variables, ``bindir`` (its 'pip', 'python', 'orchestrate') first on PATH."""
    env = {**os.environ, **(variables or {}), "CI": "true",
           "PATH": f"{bindir}{os.pathsep}{os.environ['PATH']}"}
    env.pop("VIRTUAL_ENV", None)
    env.pop("PYTEST_XDIST_WORKER", None)
    return subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def change(path: Path, parameter: str, old: str, new: str) -> None:
    """Set one parameter of an SSV file, as a user's edit would."""
    text = path.read_text()
    pattern = rf'(<ssv:Parameter name="{parameter}">\s*<ssv:Real value=")({re.escape(old)})(")'
    changed, count = re.subn(pattern, rf"\g<1>{new}\g<3>", text)
    assert count == 1, f"{path}: no {parameter} = {old}"
    path.write_text(changed)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """Each template's install commands, with its variables, in a fresh virtual environment (the
    runner's Python): pip clones this checkout and builds the package from the clone, its
    dependencies pinned by constraints.txt as 'make' pins them. The environment's bin folder and
    the variables the templates' commands run with."""
    venv = tmp_path_factory.mktemp("ci") / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    variables = [from_this_checkout(template_variables(path)) for path in TEMPLATES]
    assert all(v == variables[0] for v in variables), "the templates install different orchestrators"
    pins = {"PIP_CONSTRAINT": str(REPO / "constraints.txt"), "PIP_PROGRESS_BAR": "off"}
    for command in dict.fromkeys(c for path in TEMPLATES for c in template_commands(path)
                                 if c.startswith("pip install")):
        done = run(command, venv, venv / "bin", {**variables[0], **pins})
        assert done.returncode == 0, f"{command}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    where = run("python -c 'import orchestrator; print(orchestrator.__file__)'", venv, venv / "bin")
    assert Path(where.stdout.strip()).is_relative_to(venv), where.stdout + where.stderr  # not the checkout
    return venv / "bin", variables[0]


@pytest.fixture(scope="module")
def sample(tmp_path_factory: pytest.TempPathFactory, built: Path, installed: tuple[Path, dict[str, str]]
           ) -> dict:
    """The templates' commands (each distinct one once, the install done by ``installed``) on the
    clean project, then after the fault of example1_fault moved from t = 2 s to 3 s and the
    pendulum's gain k1 from 25 to 26.25 (+5 %)."""
    if not (REFERENCE_FMUS / "VanDerPol.fmu").is_file():
        pytest.skip(f"no Modelica Reference FMUs in {REFERENCE_FMUS}")
    project = user_project(tmp_path_factory.mktemp("user") / "project", built / "fmus")
    commands = list(dict.fromkeys(c for path in TEMPLATES for c in template_commands(path)
                                  if not c.startswith("pip install")))
    baselines = {p.name: p.read_bytes() for p in (project / "regression" / "baselines").iterdir()}
    record: dict = {"project": project, "baselines": baselines}
    bindir, variables = installed
    for state in ("clean", "changed"):
        if state == "changed":
            change(project / "regression" / "example1_fault" / "actuator.ssv", "t_fault", "2.0", "3.0")
            change(project / "regression" / "pendulum_start" / "controller.ssv", "k1", "25.0", "26.25")
        for command in commands:
            done = run(command, project, bindir, variables)
            record[state, shlex.split(command)[1]] = done
            if command.startswith("orchestrate regress "):
                record[state, "junit"] = (project / "results" / "regression.xml").read_bytes()
                record[state, "report"] = project / "results" / "regression-report" / "index.html"
        if OUTPUT:
            folder = Path(OUTPUT)
            folder.mkdir(parents=True, exist_ok=True)
            (folder / f"{state}-terminal.txt").write_text(record[state, "regress"].stdout)
            (folder / f"{state}-junit.xml").write_bytes(record[state, "junit"])
    return record


def junit(document: bytes) -> etree._Element:
    """The JUnit XML, validated against Jenkins' schema."""
    tree = etree.fromstring(document)
    assert SCHEMA.validate(tree), SCHEMA.error_log
    return tree


@needs_reference_fmus
def test_clean_project_passes(sample: dict) -> None:
    done = sample["clean", "regress"]
    assert done.returncode == 0, done.stdout + done.stderr
    assert re.search(r"^PASS: 3 scenarios: 3 passed, 0 regressed, 0 failed to run", done.stdout, re.M)
    suite = junit(sample["clean", "junit"])
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("3", "0", "0")
    assert sorted(c.get("name") for c in suite.iter("testcase")) == ["example1_fault", "pendulum_start",
                                                                     "vanderpol"]
    review = sample["clean", "baseline"]
    assert review.returncode == 0, review.stdout + review.stderr
    assert len(re.findall(r"^unchanged\s", review.stdout, re.M)) == 3, review.stdout


@needs_reference_fmus
def test_a_shifted_fault_and_a_changed_gain_are_caught(sample: dict) -> None:
    done = sample["changed", "regress"]
    assert done.returncode == 1, done.stdout + done.stderr
    verdict = re.compile(r"^(PASS|REGRESSION|ERROR)\s+(\w+)\s", re.M)
    lines = {m.group(2): m.group(1) for m in verdict.finditer(done.stdout)}
    assert lines == {"example1_fault": "REGRESSION", "pendulum_start": "REGRESSION", "vanderpol": "PASS"}
    assert re.search(r"^REGRESSION: 3 scenarios: 1 passed, 2 regressed, 0 failed to run", done.stdout, re.M)
    suite = junit(sample["changed", "junit"])
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("3", "2", "0")
    failures = {c.get("name"): c.find("failure") for c in suite.iter("testcase")}
    assert failures["vanderpol"] is None
    # the fault 1 s later: the adaptive estimate keeps its trace (tolerances.json); the gain: at once
    assert "| controller.eta1_hat |" in failures["example1_fault"].text
    assert "| plant.y |" in failures["pendulum_start"].text
    assert failures["pendulum_start"].get("message").startswith("13 of 16 signals outside their tubes")


@needs_reference_fmus
def test_baseline_review_shows_the_changes_and_accepts_nothing(sample: dict) -> None:
    review = sample["changed", "baseline"]
    assert review.returncode == 0, review.stdout + review.stderr
    assert re.search(r"^CHANGED\s+example1_fault\s", review.stdout, re.M)
    assert re.search(r"^CHANGED\s+pendulum_start\s", review.stdout, re.M)
    assert re.search(r"^unchanged\s+vanderpol\s", review.stdout, re.M)
    assert re.search(r"^  controller\.eta1_hat\s+max change .*, outside its tube", review.stdout, re.M)
    assert "not accepted: example1_fault, pendulum_start" in review.stdout
    after = {p.name: p.read_bytes() for p in (sample["project"] / "regression" / "baselines").iterdir()}
    assert after == sample["baselines"]
    assert (sample["project"] / "results" / "baseline-review" / "index.html").is_file()


def colour_share(image: np.ndarray, rgb: tuple[int, int, int], within: int = 0) -> float:
    """The share of pixels of this colour (each channel ``within`` of it: antialiased lines)."""
    pixels = np.round(image[..., :3] * 255).astype(int)
    return float(np.all(np.abs(pixels - rgb) <= within, axis=-1).mean())


LINKS_RESOLVE = """[...document.querySelectorAll('a[href^="#"]')]
    .filter(a => !document.getElementById(a.getAttribute('href').slice(1))).length"""
IMAGES = "[...document.images].map(i => i.complete && i.naturalWidth > 0)"
VISIBLE_ROWS = """[...document.querySelectorAll('#scenarios tbody tr')]
    .filter(r => getComputedStyle(r).display !== 'none').map(r => r.cells[0].textContent)"""


@needs_reference_fmus
def test_html_report_in_a_headless_browser(sample: dict, tmp_path: Path) -> None:
    executable = chromium()
    if executable is None:
        pytest.skip("no chromium: 'make test' installs Debian's package as root "
                    "(log: build/chromium-install.log)")
    shots = Path(OUTPUT) if OUTPUT else tmp_path
    with Browser(executable, tmp_path / "profile") as browser:
        browser.open(sample["changed", "report"].as_uri())
        assert browser.evaluate("document.title") == "Co-simulation regression"
        assert browser.evaluate(LINKS_RESOLVE) == 0
        images = browser.evaluate(IMAGES)
        assert len(images) == 2 + 12 and all(images)  # example1_fault's 2 signals, the 12 worst of 13
        verdicts = browser.evaluate("[...document.querySelectorAll('#scenarios .badge')]"
                                    ".map(b => b.textContent)")
        assert verdicts == ["REGRESSION", "REGRESSION", "PASS"]
        top = imread(browser.screenshot(shots / "regression-report.png"))
        assert top.shape[:2] == (900, 1280)
        assert colour_share(top, (198, 40, 40)) > 0.002  # the red REGRESSION badges (#c62828)
        assert colour_share(top, (46, 125, 50)) > 0.0003  # the green PASS badge (#2e7d32)
        browser.evaluate("document.getElementById('only-failing').click()")
        assert browser.evaluate(VISIBLE_ROWS) == ["example1_fault", "pendulum_start"]
        browser.evaluate("document.querySelector('#scenarios tbody tr a[href*=\"eta1_hat\"]').click()")
        assert browser.evaluate("location.hash") == "#example1_fault-controller.eta1_hat"
        top_of_figure = browser.evaluate("document.getElementById('example1_fault-controller.eta1_hat')"
                                         ".getBoundingClientRect().top")
        assert 0 <= top_of_figure < 100
        figure = imread(browser.screenshot(shots / "regression-report-figure.png"))
        assert colour_share(figure, (31, 119, 180), 40) > 0.002  # the result's line (matplotlib tab:blue)
        assert browser.problems() == []


@needs_reference_fmus
def test_pytest_plugin_runs_the_scenarios_with_the_projects_own_tests(sample: dict) -> None:
    """'pytest tests --ssp-regress regression': the project's own test and one item per scenario in
    one run and one JUnit file (pytest's writer, validated against the same schema)."""
    project = sample["project"]
    (project / "tests").mkdir(exist_ok=True)
    (project / "tests" / "test_own.py").write_text("def test_own():\n    assert 1 + 1 == 2\n")
    done = run("python -m pytest tests --ssp-regress regression --junitxml=results/pytest.xml "
               "-p no:cacheprovider", project)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "2 failed, 2 passed" in done.stdout
    assert "FAILED regression::example1_fault" in done.stdout
    assert "FAILED regression::pendulum_start" in done.stdout
    suite = junit((project / "results" / "pytest.xml").read_bytes())
    cases = {c.get("name"): c for c in suite.iter("testcase")}
    assert set(cases) == {"test_own", "example1_fault", "pendulum_start", "vanderpol"}
    assert "| controller.eta1_hat |" in cases["example1_fault"].find("failure").text
    assert cases["vanderpol"].find("failure") is None
    selected = run("python -m pytest --ssp-regress regression -k vanderpol -p no:cacheprovider -q", project)
    assert selected.returncode == 0 and "1 passed, 3 deselected" in selected.stdout, selected.stdout
