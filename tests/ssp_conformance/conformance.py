# SPDX-License-Identifier: BSD-2-Clause
"""The SSP conformance set: SSPs that other tools wrote, run by orchestrate and compared with the
values those tools print and with OMSimulator 3 and libcosim where they run the file.

The cases (:data:`CASES`) are copies of OMSimulator's SSP test resources (``omsimulator/``: SSD
folders packed into ``.ssp`` archives as OMSimulator's CMake packs them, and one archive
OMSimulator 3 wrote) and of libcosim's SSP test data (``libcosim/``: SSD folders that reference
their FMUs in a sibling folder, run with ``--root``); their licences are in ``licenses/`` and
README.md says where each file comes from. Each case carries the values the other tool's own test
script prints (its "oracle") and says where OMSimulator 3 (the build in ``../shared/tools``) or
libcosim disagree, and why.

``python tests/ssp_conformance/conformance.py --omsimulator DIR --libcosim DIR --demo-cases DIR``
(``make conformance``) measures the whole of the tools' test resources (``DIR``: OMSimulator's
``testsuite/tests/resources``, libcosim's ``tests/data``, the OSP ``demo-cases``): each file
validated and run by the engine before this work (main at ``BEFORE``) and now, and compared with
OMSimulator 3 and libcosim; the table goes to ``docs/ssp-conformance.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
BEFORE = "633067d"  # main before issue 43 (issue 32's table was against 5287c35)
MAIN = "725f1cb"  # main before issue 43's second part (Integer connections, proxy FMUs, Vico, Ecos)
OMSIMULATOR = Path(os.environ.get("OMSIMULATOR_HOME", REPO.parent / "shared" / "tools" / "omsimulator"))


@dataclass(frozen=True)
class Case:
    """One SSP of another tool, how to run it and what it must give.

    ``path``: an SSD folder (packed into an archive unless ``root``) or an ``.ssp``, relative to
    this folder; ``root``: run the folder with ``--root`` (libcosim's layout); ``oracle``: column
    -> the value at the stop time that the tool's own test prints; ``omsimulator``: why OMSimulator
    3 does not run the file ('' when it does: then it must agree, but for ``oms_differs``, the
    values it gives instead, which ``oms_why`` explains);
    ``libcosim``: whether libcosim runs it and must agree; ``master``; ``warnings``: texts every
    one of which a warning of ``validate`` must contain."""

    name: str
    path: str
    origin: str
    oracle: dict[str, float]
    stop: float = 1.0
    step: float = 0.01
    root: str | None = None
    omsimulator: str = ""
    oms_differs: dict[str, float] = field(default_factory=dict)
    oms_why: str = ""
    libcosim: bool = False
    master: str | None = None  # None: the master the SSD's algorithm annotation implies (issue 43)
    warnings: tuple[str, ...] = ()
    features: str = ""
    notes: dict[str, str] = field(default_factory=dict)


OMS = "OpenModelica/OMSimulator testsuite/tests/resources"
EMBRACE_WHY = ("why: the file's relativeTolerance, passed to the FMUs as OMSimulator passes it, makes the "
               "first step agree; then two choices of OMSimulator's move these Dymola FMUs' own solvers: "
               "its result writer reads every variable of every FMU at every step, and its time is "
               "summed step by step (t = 0.010000000000000002 after 10 steps); with both, every value "
               "agrees at every step (tests/test_ssp_embrace.py)")
# survey label -> why OMSimulator 3's values differ
KNOWN = {"OMSimulator embrace": EMBRACE_WHY, "OMSimulator embrace_TwoConf": EMBRACE_WHY}
SYSTEM_BINDING_IGNORED = ("OMSimulator 3's Python package applies the component's own values (10, 20) and "
                          "ignores the system's binding, which SSP 1.0 puts first and which OMSimulator's "
                          "Lua API applied (the values its test printed)")
OMS_SCRIPT = "OpenModelica/OMSimulator testsuite/tests/simulation"
CASES = [
    Case("LinearTransformation", "omsimulator/LinearTransformation", f"{OMS}/LinearTransformation",
         {"Gain1.y": 0.0, "Add1.u1": 3.0},
         oms_differs={"Add1.u1": 0.0, "Add1.y": 0.0},
         oms_why="OMSimulator 3 (b3cd4589) drops the connection's LinearTransformation offset (Add1.u1 = 0 "
                 "for Gain1.y = 0); the SSP formula factor * value + offset gives 3, as the newer "
                 "OMSimulator prints",
         features="SSD version 2.0, LinearTransformation on a connection",
         notes={"oracle": f"{OMS_SCRIPT}/LinearTransformation1.py"}),
    Case("LinearTransformation3", "omsimulator/LinearTransformation3", f"{OMS}/LinearTransformation3",
         {"Gain1.k": 13.0, "Gain1.u": 14.0, "Gain1.y": 182.0, "Add1.u1": 182.0},
         oms_differs={"Gain1.k": 2.0, "Gain1.u": 2.0, "Gain1.y": 4.0, "Add1.u1": 4.0, "Add1.y": 4.0},
         oms_why="OMSimulator 3 (b3cd4589, Nov 2025) predates LinearTransformation in parameter mappings "
                 "(added 2026) and applies the mapped values untransformed (Gain1.k = 2, Gain1.u = 2); the "
                 "newer OMSimulator's printed values and the SSP formula give 13 and 14",
         features="system-level .ssv with an .ssm ParameterMapping with LinearTransformation",
         notes={"oracle": f"{OMS_SCRIPT}/LinearTransformation3.py"}),
    Case("toplevelparameter1", "omsimulator/toplevelparameter1", f"{OMS}/toplevelparameter1",
         {"addP.k1": -200.0, "addP.k2": -300.0},
         oms_differs={"addP.k1": 10.0, "addP.k2": 20.0},
         oms_why=SYSTEM_BINDING_IGNORED,
         features="system-level .ssv over a component's .ssv (higher level wins), a system connector value",
         notes={"oracle": "toplevelparameter1.lua (OMSimulator, before its Lua tests were removed)"}),
    Case("toplevelparameter2", "omsimulator/toplevelparameter2", f"{OMS}/toplevelparameter2",
         {"addP.k1": -200.0, "addP.k2": -400.0},
         oms_differs={"addP.k1": 10.0, "addP.k2": 20.0},
         oms_why=SYSTEM_BINDING_IGNORED,
         features="inline ParameterValues on the system and on the component",
         notes={"oracle": "toplevelparameter2.lua"}),
    Case("import_export_parameters1", "omsimulator/import_export_parameters1",
         f"{OMS}/import_export_parameters1",
         {"addP.k1": 30.0, "addP.k2": -1.0, "addP.u1": -20.0, "addP.y": -600.0, "addI.k2": 20.0},
         stop=4.0, step=0.1,
         omsimulator="OMSimulator 3's Python package stops on the empty nested system ('Failed to get "
                     "variable type for model.root.foo.F_cref')",
         features="system parameter connectors connected to component parameters (k_cref -> addP.k1), "
                  "an empty nested system",
         notes={"oracle": "import_export_parameters1.lua: addP.k1 = 30 from k_cref over the 10 bound "
                          "directly, addI.k2 = 20 from T_cref; its overrides left out: y = 30 * -20"}),
    Case("import_export_parameters2", "omsimulator/import_export_parameters2",
         f"{OMS}/import_export_parameters2", {}, stop=4.0, step=0.1,
         omsimulator="OMSimulator 3's Python package stops on the empty nested system (KeyError: 'Missing "
                     "required key: co_sim.foo')",
         features="several .ssv bindings on the system and components"),
    Case("import_export_parameters3", "omsimulator/import_export_parameters3",
         f"{OMS}/import_export_parameters3", {}, stop=4.0, step=0.1,
         omsimulator="OMSimulator 3's Python package stops on the empty nested system (KeyError: 'Missing "
                     "required key: co_sim.foo')",
         features="inline values on the system and components"),
    Case("NestedSystemSimulation1", "omsimulator/NestedSystemSimulation1.ssp",
         f"written by OMSimulator 3 (b3cd4589) from {OMS_SCRIPT}/NestedSystemSimulation1.py",
         {"Gain1.u": 3.0, "Gain1.y": 3.0, "Add1.u1": 3.0, "sub-system1.Gain1.u": 10.0,
          "sub-system1.Gain1.y": 10.0, "sub-system1.Add1.u1": 10.0},
         omsimulator="OMSimulator 3 (b3cd4589) wrote this archive but cannot run it (\"model.root.Add1 "
                     "already exists in the scope\": it flattens nested names without the system's); the "
                     "newer OMSimulator's printed values are the oracle",
         features="nested system with its own connectors, inline values on both systems"),
    Case("libcosim_linear_transformation", "libcosim/ssp/linear_transformation",
         "open-simulation-platform/libcosim tests/data/ssp/linear_transformation",
         {"identity1.realOut": 4.0, "identity2.realIn": 1.3 * 4.0 + 50.0}, root="libcosim",
         omsimulator="the SSD references its FMU in a sibling folder, which an archive cannot hold",
         libcosim=True,
         features="FMI 1.0 Co-Simulation FMU, FMUs in a sibling folder (--root), LinearTransformation, "
                  "two bindings on one component",
         notes={"oracle": "libcosim's ssp_loader_unittest: realIn = 1.3 * realOut + 50; with both "
                          "bindings applied (SSP 1.0: the later wins) realOut = 4, as libcosim gives "
                          "with its parameter set 'initialValues2'",
                "libcosim": "libcosimpy 0.11 ends with a segmentation fault loading this FMI 1.0 file; "
                            "libcosim's unit test applies one named parameter set, by default the first "
                            "(realIn = 2), where SSP 1.0 applies both, the later winning"}),
    Case("libcosim_demo", "libcosim/ssp/demo", "open-simulation-platform/libcosim tests/data/ssp/demo",
         {}, root="libcosim", stop=0.02, step=1e-4, libcosim=True,
         omsimulator="the SSD references its FMUs in a sibling folder, which an archive cannot hold",
         warnings=("algebraic loop: CraneController.Act_Limits[1]",),
         features="a cycle of connections (an algebraic loop under gauss-seidel) run under jacobi"),
    Case("osp_dp_ship", "osp-demo-cases/dp-ship", "open-simulation-platform/demo-cases dp-ship",
         {"Thrust Allocation.Fxg": 0.2}, stop=1.0, step=0.04, libcosim=True,
         omsimulator="OMSimulator 3's Python package stops on these FMI 1.0 FMUs (TypeError: float() "
                     "argument must be a string or a real number, not 'NoneType')",
         warnings=("algebraic loop: DP Controller.ControlMz",),
         features="libcosim's osp:FixedStepAlgorithm choosing the master (jacobi), five FMI 1.0 FMUs, FMUs "
                  "beside the SSD, a loop through the thrust allocation",
         notes={"libcosim": "agrees at every step with our master, jacobi, which the file's "
                            "osp:FixedStepAlgorithm chooses (tests/test_ssp_algorithm.py; Fxg = 0.2 is "
                            "libcosim's value; gauss-seidel gives 0)"}),
    Case("osp_dp_ship_proxyfmu", "osp-demo-cases/dp-ship/proxyfmu",
         "open-simulation-platform/demo-cases dp-ship/proxyfmu", {"Thrust Allocation.Fxg": 0.2}, stop=1.0,
         step=0.04, root="osp-demo-cases/dp-ship", libcosim=False,
         omsimulator="the SSD references its FMUs in a sibling folder, which an archive cannot hold",
         warnings=("is a libcosim proxy FMU on this host",),
         features="libcosim proxy FMUs (proxyfmu://localhost?file=../<fmu>), run in process",
         notes={"libcosim": "libcosimpy 0.11 cannot start libcosim's proxy server here (it ends with signal "
                            "6); the same SSD with the FMUs referenced directly (osp_dp_ship) agrees with "
                            "libcosim at every step"}),
]


def pack(case: Case, dest: Path) -> Path:
    """The scenario to run: an ``.ssp`` as is, a folder packed as OMSimulator's CMake packs it
    (``zip -r``), a libcosim folder as it is (run with ``--root``)."""
    source = HERE / case.path
    if source.is_file() or case.root is not None:
        return source
    archive = dest / f"{case.name}.ssp"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(source.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(source).as_posix())
    return archive


def columns_of(system: object) -> list[tuple[str, str]]:
    """(component, variable) of every input, output and parameter of a system, for another tool to read."""
    found = []
    for name, comp in system.components.items():  # type: ignore[attr-defined]
        for v in comp.model.modelVariables:
            if v.causality in ("input", "output", "parameter") and v.type == "Real":
                found.append((name, v.name))
    return found


def ours(scenario: Path, case: Case) -> dict[str, float]:
    """The engine's values at the stop time of every input, output and parameter (parameters as
    applied at the start: they do not change)."""
    import orchestrator
    from orchestrator import RunOptions

    root = HERE / case.root if case.root else None
    options = RunOptions(stop_time=case.stop, step=case.step, master=case.master, root=root)
    result = orchestrator.run(scenario, options)
    values = {name: float(result.rows[name][-1]) for name in result.rows.dtype.names if name != "time"}
    with orchestrator.open_system(scenario, root=root) as system:
        for name, comp in system.components.items():
            for variable, value in comp.start_values.items():
                if isinstance(value, float):
                    values.setdefault(f"{name}.{variable}", value)
            for v in comp.model.modelVariables:
                key = f"{name}.{v.name}"
                if v.causality == "parameter" and v.type == "Real" and v.start is not None:
                    values.setdefault(key, float(v.start))
    return values


def omsimulator(scenario: Path, case: Case, names: list[tuple[str, str]],
                system: str) -> dict[str, float | str]:
    """OMSimulator 3's values at the stop time (its Python package, in a child process: a crash of
    it ends only that process); a value it cannot give is the error text."""
    package = OMSIMULATOR / "lib" / "x86_64-linux-gnu"
    crefs = [[system, [*component.split("."), variable]] for component, variable in names]
    with tempfile.TemporaryDirectory() as tmp:
        done = subprocess.run([sys.executable, str(HERE / "oms_probe.py"), str(package), str(scenario),
                               repr(case.stop), repr(case.step), tmp, json.dumps(crefs)],
                              capture_output=True, text=True, timeout=600, cwd=tmp,
                              env={**os.environ, "TMPDIR": tmp})  # what it unpacks, removed with tmp
        log = Path(tmp, "omsimulator.log")
        logged = log.read_text(errors="replace").splitlines() if log.is_file() else []
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")), None)
    if line is None:
        error = [ln for ln in logged if ln.startswith("error:")]
        error += [ln for ln in (done.stdout + done.stderr).splitlines()
                  if "Error" in ln and "raise" not in ln]
        raise RuntimeError(f"OMSimulator failed: {(error or ['no result'])[0].strip()}")
    return json.loads(line[len("RESULT "):])


def libcosim(scenario: Path, case: Case, names: list[str]) -> dict[str, list[float]]:
    """libcosim's series of ``names`` up to the case's stop time (:func:`libcosim_series`)."""
    return libcosim_series(scenario, case.stop, names)


def libcosim_series(scenario: Path, stop: float, names: list[str]) -> dict[str, list[float]]:
    """libcosim's series of ``names`` up to ``stop`` (libcosimpy, in a child process: it crashes
    on some files, e.g. with a segmentation fault on an FMI 1.0 FMU); RuntimeError when it stops."""
    code = ("import json, sys\n"
            "from orchestrator.crosscheck.libcosim import run_libcosim\n"
            "rows, _ = run_libcosim(sys.argv[1], float(sys.argv[2]), ['time', *json.loads(sys.argv[3])])\n"
            "print('RESULT ' + json.dumps({n: rows[n].tolist() for n in rows.dtype.names}))\n")
    with tempfile.TemporaryDirectory() as tmp:  # libcosim leaves its unpacked archive in TMPDIR
        done = subprocess.run([sys.executable, "-c", code, str(scenario), repr(stop), json.dumps(names)],
                              capture_output=True, text=True, timeout=600, env={**os.environ, "TMPDIR": tmp})
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")), None)
    if line is None:
        why = f"signal {-done.returncode}" if done.returncode < 0 else (done.stderr.strip().splitlines()
                                                                       or ["no result"])[-1]
        raise RuntimeError(f"libcosim failed: {why}")
    return json.loads(line[len("RESULT "):])


def differences(mine: dict[str, float], theirs: dict[str, float | str]) -> dict[str, tuple[float, float]]:
    """The columns both have whose values differ by more than 1e-9 relative (ours, theirs)."""
    return {k: (mine[k], float(v)) for k, v in theirs.items()
            if k in mine and isinstance(v, float)
            and not math.isclose(mine[k], v, rel_tol=1e-9, abs_tol=1e-9)}


# -- the survey of both tools' whole test resources (make conformance) ------------------------------
def _validate_line(engine: Path | None, scenario: Path, root: Path | None) -> tuple[bool, str]:
    """``orchestrate validate`` of ``scenario`` by the engine in ``engine`` (None: this one), in a
    child process: whether it is ok, and its first error."""
    return _command(engine, ["validate", str(scenario)], root)


def _run_line(engine: Path | None, scenario: Path, root: Path | None, stop: float, step: float,
              output: Path) -> tuple[bool, str]:
    """``orchestrate run`` of ``scenario`` by the engine in ``engine`` (None: this one) as the
    survey runs it: whether it completes, and its first error."""
    return _command(engine, ["run", str(scenario), "--stop-time", repr(stop), "--step", repr(step),
                             "--output", str(output), "--no-plot"], root)


def _command(engine: Path | None, args: list[str], root: Path | None) -> tuple[bool, str]:
    """An ``orchestrate`` command in a child process, outside this checkout (its working directory
    would come first on sys.path, and its build's staleness check apply to other files)."""
    env = dict(os.environ)
    if engine is not None:
        env["PYTHONPATH"] = str(engine)
    argv = [sys.executable, "-m", "orchestrator", *args, *(["--root", str(root)] if root is not None else [])]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=600, env=env,
                          cwd=engine or tempfile.gettempdir())
    errors = [ln for ln in (done.stdout + done.stderr).splitlines()
              if ln.startswith(("error:", "orchestrate: error:"))]
    lines = [ln for ln in (done.stdout + done.stderr).splitlines() if ln.strip()]
    first = (errors or lines or [""])[0]
    return done.returncode == 0, first.removeprefix("orchestrate: ").removeprefix("error: ")


def _short(text: str, scenario: Path | None = None) -> str:
    """One table cell: no folder of this machine (a temporary one changes every run), no '|', short."""
    if scenario is not None:
        text = text.replace(str(scenario.parent) + "/", "")
    text = re.sub(r"/tmp/[^ ']*/", "", text).replace("|", "/")
    return text if len(text) < 160 else text[:157] + "..."


def survey(oms_resources: Path | None, libcosim_data: Path | None, output: Path,
           demo_cases: Path | None = None, others: Mapping[str, Path] | None = None) -> Path:
    """Validate and run every SSD of OMSimulator's test resources, libcosim's test data, the OSP
    demo cases and ``others`` (tool name -> an SSP test-data folder: Vico's, Ecos'), before (main at
    BEFORE and at MAIN) and now, compare with OMSimulator 3 and libcosim, and write the table."""
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        engines = {}
        for commit in (BEFORE, MAIN):
            engines[commit] = tmp / commit
            engines[commit].mkdir()
            archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, "orchestrator"],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", str(engines[commit])], input=archive, check=True)
        rows = [_row(label, scenario, root, engines[BEFORE], engines[MAIN], tmp)
                for label, scenario, root in _targets(oms_resources, libcosim_data, demo_cases, others, tmp)]
    lines = ["# SSP conformance: other tools' test files, before and after issue 43", "",
             f"Generated by `make conformance` (tests/ssp_conformance/conformance.py): every SSD of "
             f"OMSimulator's `testsuite/tests/resources` (packed into an archive as its CMake does), "
             f"of libcosim's `tests/data/ssp`, of the OSP `demo-cases`, of Vico's `test-data/data/ssp` "
             f"and of Ecos' `data/ssp/1.0`, validated and run by the engine of main at {BEFORE} (before "
             f"issue 43), at {MAIN} (before its second part) and by this one (after), run for 1 s "
             f"(the SSD's stop time when shorter) at a 10 ms step (the SSD's when given) under the master "
             f"the SSD's algorithm annotation implies, and compared at the stop time with OMSimulator 3 (its "
             f"Python package) and at every step with libcosim (libcosimpy) on every Real input, output "
             f"and parameter both give. Do not edit by hand.", "",
             f"Files that run: {sum(r[5].startswith('ok') for r in rows)} of {len(rows)} (main at {MAIN}: "
             f"{sum(r[3] == 'runs' for r in rows)}; before issue 43: {sum(r[2] == 'ok' for r in rows)}).", "",
             "| file | validate before | run before | main at " + MAIN + " | validate after | run after "
             "| OMSimulator 3 | libcosim |",
             "|---|---|---|---|---|---|---|---|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    lines += ["", "## The conformance set in `make test`", "",
              "Copied into `tests/ssp_conformance/` and checked by `tests/test_ssp_conformance.py` against "
              "the values the tool's own test prints (oracle), OMSimulator 3 and libcosim.", "",
              "| case | what it exercises | oracle | OMSimulator 3 | libcosim |", "|---|---|---|---|---|"]
    for case in CASES:
        oracle = ", ".join(f"{k} = {v:g}" for k, v in case.oracle.items()) or "(none printed)"
        oms = (case.omsimulator or (f"agrees but for {', '.join(case.oms_differs)}: {case.oms_why}"
                                    if case.oms_differs else "agrees on every value"))
        cosim = (case.notes.get("libcosim", "agrees at every step with our jacobi master (inputs one step "
                                            "apart: libcosim reports the input used in the step ending at t)")
                 if case.libcosim else case.notes.get("libcosim", ""))
        lines.append(f"| {case.name} | {case.features} | {oracle} | {oms} | {cosim} |")
    output.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return output


def _targets(oms_resources: Path | None, libcosim_data: Path | None, demo_cases: Path | None,
             others: Mapping[str, Path] | None, tmp: Path) -> list[tuple[str, Path, Path | None]]:
    """(label, scenario, --root) of every file the survey measures (OMSimulator's folders packed into
    archives in ``tmp`` as its CMake packs them)."""
    targets: list[tuple[str, Path, Path | None]] = []
    if oms_resources is not None:
        for ssd in sorted(oms_resources.glob("*/SystemStructure.ssd")):
            folder = ssd.parent
            archive_path = tmp / f"{folder.name}.ssp"
            with zipfile.ZipFile(archive_path, "w", zipfile.ZIP_DEFLATED) as zf:
                for path in sorted(folder.rglob("*")):
                    if path.is_file():
                        zf.write(path, path.relative_to(folder).as_posix())
            targets.append((f"OMSimulator {folder.name}", archive_path, None))
    if libcosim_data is not None:
        for ssd in sorted(libcosim_data.glob("ssp/**/SystemStructure.ssd")):
            targets.append((f"libcosim {ssd.parent.relative_to(libcosim_data / 'ssp')}", ssd.parent,
                            libcosim_data))
        for ssp in sorted(libcosim_data.glob("ssp/**/*.ssp")):
            targets.append((f"libcosim {ssp.relative_to(libcosim_data / 'ssp')}", ssp, None))
    if demo_cases is not None:
        for ssd in sorted(demo_cases.glob("**/SystemStructure.ssd")):  # proxyfmu variants: '../<fmu>'
            targets.append((f"OSP demo-cases {ssd.parent.relative_to(demo_cases)}", ssd.parent, demo_cases))
    for tool, folder in (others or {}).items():  # as libcosim's: FMUs may be in a sibling of ssp/
        base = folder / "ssp" if (folder / "ssp").is_dir() else folder
        for ssd in sorted(base.glob("**/SystemStructure.ssd")):
            targets.append((f"{tool} {ssd.parent.relative_to(base)}", ssd.parent, folder))
        for ssp in sorted(base.glob("**/*.ssp")):
            targets.append((f"{tool} {ssp.relative_to(base)}", ssp, None))
    return targets


def _row(label: str, scenario: Path, root: Path | None, before: Path, main: Path,
         tmp: Path) -> tuple[str, ...]:
    """One row of the table: validated and run by the engines ``before`` and ``main``, then by this
    one and compared with the other tools."""
    print(label, file=sys.stderr)
    ok_before, why_before = _validate_line(before, scenario, root)
    ok_now, why_now = _validate_line(None, scenario, root)
    run, run_before, agree_oms, agree_cosim = "", "", "", ""
    stop, step = _span(scenario, root)
    before_csv = tmp / "before.csv"
    before_csv.unlink(missing_ok=True)
    if ok_before and stop is not None:
        done, why = _run_line(before, scenario, root, stop, step, before_csv)
        run_before = "ok" if done else f"fails: {_short(why, scenario)}"
    ok_main, why_main = _validate_line(main, scenario, root)
    if ok_main and stop is not None:
        ok_main, why_main = _run_line(main, scenario, root, stop, step, tmp / "main.csv")
        why_main = "" if ok_main else f"fails: {_short(why_main, scenario)}"
    elif not ok_main:
        why_main = f"refused: {_short(why_main, scenario)}"
    if ok_now:
        run, agree_oms, agree_cosim = _measure(scenario, root, label, before_csv)
    return (label, "ok" if ok_before else f"refused: {_short(why_before, scenario)}", run_before,
            "runs" if ok_main else why_main, "ok" if ok_now else f"refused: {_short(why_now, scenario)}", run,
            agree_oms, agree_cosim)


def _span(scenario: Path, root: Path | None) -> tuple[float | None, float]:
    """The stop time and step the survey runs ``scenario`` at (None: the SSD cannot be read)."""
    import orchestrator

    try:
        with orchestrator.open_system(scenario, root=root) as system:
            ex = system.structure.experiment
    except Exception:  # noqa: BLE001 - refused: validate's line says why
        return None, 0.01
    step = ex.step or 0.01
    span = (ex.stop_time - ex.start_time) if ex.stop_time is not None else 1.0
    return ex.start_time + min(span, 1.0, 1000 * step), step


def _measure(scenario: Path, root: Path | None, label: str,
             before: Path | None = None) -> tuple[str, str, str]:
    """Run now; agreement with OMSimulator 3 and libcosim (each '' when not applicable); ``before``:
    the result file of the engine before, also compared with libcosim."""
    import orchestrator

    try:
        with orchestrator.open_system(scenario, root=root) as system:
            ex = system.structure.experiment
            step = ex.step or 0.01
            span = (ex.stop_time - ex.start_time) if ex.stop_time is not None else 1.0
            stop = ex.start_time + min(span, 1.0, 1000 * step)
            names = columns_of(system)
            name = system.structure.name
            components = len(system.components)
        case = Case(label, str(scenario), label, {}, stop=stop, step=step, root=str(root) if root else None)
        mine = ours(scenario, case)
    except Exception as exc:  # noqa: BLE001 - the table records whatever stops a run
        return f"fails: {' '.join(str(exc).split())[:150]}", "", ""
    run = f"ok ({len(mine)} values)" if components else "ok (no component: nothing to simulate)"
    agree_oms = agree_cosim = ""
    if scenario.is_file() and OMSIMULATOR.is_dir():
        try:
            theirs = omsimulator(scenario, case, names, name)
            wrong = differences(mine, theirs)
            common = sum(isinstance(v, float) and k in mine for k, v in theirs.items())
            agree_oms = (f"agrees ({common} values)" if not wrong else
                         f"differs in {len(wrong)} of {common}: " + ", ".join(
                             f"{k} {a:g} vs {b:g}" for k, (a, b) in list(wrong.items())[:3]))
            if wrong and label in KNOWN:
                worst = max(abs(a - b) / max(abs(a), abs(b)) for a, b in wrong.values())
                agree_oms += f" (up to {worst:.2g} relative; {KNOWN[label]})"
        except Exception as exc:  # noqa: BLE001
            agree_oms = f"does not run it: {_short(' '.join(str(exc).split()))[:120]}"
    if label.startswith(("libcosim", "OSP", "Vico", "Ecos")):  # files written for libcosim (or its heirs)
        try:
            agree_cosim = _libcosim_agreement(scenario, case, [f"{c}.{v}" for c, v in names], before)
        except Exception as exc:  # noqa: BLE001
            agree_cosim = f"does not run it: {' '.join(str(exc).split())[:120]}"
    return run, agree_oms, agree_cosim


def _libcosim_agreement(scenario: Path, case: Case, names: list[str], before: Path | None = None) -> str:
    """libcosim's series against our run under the master the SSD implies (jacobi for libcosim's
    osp:FixedStepAlgorithm, its algorithm) at every communication point: outputs at the same time;
    inputs one step apart under jacobi (libcosim reports at t the input an FMU used in the step
    ending at t, our row at t the input transferred at t for the next step). The largest deviation
    relative to 1 + the column's size; with ``before`` (the CSV the engine before wrote, under
    gauss-seidel, its default) that one's too."""
    import csv

    import orchestrator
    from orchestrator import RunOptions

    root = HERE / case.root if case.root else None
    theirs = libcosim(scenario, case, names)
    with orchestrator.open_system(scenario, root=root) as system:
        if system.structure.experiment.step is None:
            return "runs it; not compared: the SSD gives no step, and libcosim takes its own default"
        inputs = {f"{n}.{v.name}" for n, c in system.components.items() for v in c.model.modelVariables
                  if v.causality == "input"}
    result = orchestrator.run(scenario, RunOptions(stop_time=case.stop, step=case.step, root=root))
    master = str(result.provenance["master"])
    rows = {n: result.rows[n] for n in result.rows.dtype.names or ()}
    delayed = inputs if master == "jacobi" else set()
    text = _against(theirs, rows, delayed, f"our {master} master (the file's)")
    if before is not None and before.is_file():
        with before.open(newline="") as file:
            table = list(csv.reader(file))
        old = {name: [float(r[i]) for r in table[1:]] for i, name in enumerate(table[0])}
        text += "; before: " + _against(theirs, old, set(), "the gauss-seidel master")
    return text


def _against(theirs: dict[str, list[float]], rows: dict[str, object], delayed: set[str], what: str) -> str:
    """How far ``rows`` are from libcosim's series (``delayed``: input columns one step apart)."""
    import numpy as np

    common = [n for n in theirs if n != "time" and n in rows]
    n = min(len(theirs["time"]), len(rows["time"])) - 1  # type: ignore[arg-type]
    worst = 0.0
    for c in common:
        mine, other = np.asarray(rows[c]), np.array(theirs[c])
        gap = other[2:n + 1] - mine[1:n] if c in delayed else other[1:n + 1] - mine[1:n + 1]
        worst = max(worst, float(np.max(np.abs(gap)) / (1 + np.max(np.abs(mine)))))
    where = f"{len(common)} columns x {n} steps against {what}" + (
        ", inputs one step apart" if delayed else "")
    return f"agrees ({where})" if worst <= 1e-9 else f"differs by up to {worst:.2g} relative ({where})"


def main(argv: list[str] | None = None) -> int:
    """``conformance.py --omsimulator DIR --libcosim DIR [--output FILE]``: write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--omsimulator", type=Path, help="OMSimulator's testsuite/tests/resources")
    parser.add_argument("--libcosim", type=Path, help="libcosim's tests/data")
    parser.add_argument("--demo-cases", type=Path, help="the OSP demo-cases repository")
    parser.add_argument("--vico", type=Path, help="Vico's test-data/data")
    parser.add_argument("--ecos", type=Path, help="Ecos' data/ssp/1.0")
    parser.add_argument("--output", type=Path, default=REPO / "docs" / "ssp-conformance.md")
    args = parser.parse_args(argv)
    if args.omsimulator is None and args.libcosim is None:
        parser.error("give --omsimulator and/or --libcosim (folders of the fetched repositories)")
    others = {tool: folder for tool, folder in (("Vico", args.vico), ("Ecos", args.ecos)) if folder}
    print(survey(args.omsimulator, args.libcosim, args.output, args.demo_cases, others))
    return 0


if __name__ == "__main__":
    sys.exit(main())
