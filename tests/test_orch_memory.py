# SPDX-License-Identifier: BSD-2-Clause
"""Long runs: the results are streamed, so the resident size of ``orchestrate run`` does not grow
with the run length (it held every row before: 182 MB for 300 s of example1).

Oracle: the peak resident size the kernel reports for the process (``wait4``), for a 30 s and a
300 s run of the same cheap scenario at 2 ms (15 001 and 150 001 rows: keeping the rows, as
before, would add about 11 MB), and the CSV's line count and last time.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from orch_helpers import loop_scenario

pytestmark = pytest.mark.system

ORCHESTRATE = Path(sys.executable).with_name("orchestrate")


def _peak_kib(*args: str) -> int:
    """Run ``orchestrate ARGS`` and return its peak resident size in KiB."""
    process = subprocess.Popen([str(ORCHESTRATE), *args], stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    assert process.returncode == 0
    return usage.ru_maxrss


def test_resident_size_does_not_grow_with_the_run_length(test_fmus, tmp_path):
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=1.0, step=0.002)
    peaks = {}
    for stop in (30, 300):
        csv = tmp_path / f"r{stop}.csv"
        peaks[stop] = _peak_kib("run", str(ssp), "--stop-time", str(stop), "--output", str(csv), "--quiet",
                                "--no-plot")
        with csv.open() as f:
            lines = sum(1 for _ in f)
        assert lines == 1 + 500 * stop + 1  # header and every row
        assert float(csv.read_bytes()[-200:].splitlines()[-1].split(b",")[0]) == stop
    # 135 000 more rows held (6 values and a time each) would be 11 MB; allow 4 MB of noise
    assert peaks[300] - peaks[30] < 4096, peaks


# Modules a run does not use, each measured as part of every run's peak resident size (issue 46:
# multiprocessing with concurrent.futures 1.0 MB, html 0.5 MB), with who imported them before.
NOT_IMPORTED_BY_RUN = {
    "multiprocessing": "the project's build (orchestrator.experiments.scenarios, for the stale-build check)",
    "concurrent": "the project's build (orchestrator.experiments.scenarios, for the stale-build check)",
    "html": "RunResult's Jupyter table (orchestrator.result)",
    "matplotlib": "the plot, with --no-plot",
    "pyarrow": "Parquet output, with a CSV",
    "importlib.metadata": "entry points and versions (orchestrator.installed reads them: 2.0 MB with email)",
    "email": "importlib.metadata, to parse each distribution's METADATA",
}


@pytest.mark.parametrize("output", ["r.csv", os.devnull])
def test_a_run_imports_nothing_it_does_not_use(test_fmus, tmp_path, output):
    """Oracle: the interpreter's own list of what it imported (``-X importtime``), for a run that
    passes the stale-build check of this checkout's application and writes a CSV, or nothing
    (then the CSV's formatter, orjson with uuid, 0.36 MB, is not imported either)."""
    ssp = loop_scenario(tmp_path / "loop", test_fmus, stop=0.1, step=0.01)
    command = [sys.executable, "-X", "importtime", "-m", "orchestrator", "run", str(ssp), "--quiet",
               "--no-plot", "--output", str(tmp_path / output)]
    done = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, check=True)
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines()
                if line.startswith("import time:")}
    assert "orchestrator" in imported and "fmpy" in imported  # the list is the run's
    not_used = NOT_IMPORTED_BY_RUN | ({"orjson": "the CSV's formatter"} if output == os.devnull else {})
    unused = {m for m in not_used if m in imported or any(i.startswith(f"{m}.") for i in imported)}
    assert not unused, {m: not_used[m] for m in unused}
    assert output == os.devnull or "orjson" in imported  # the formatter of the rows written


# OpenBLAS's own count of its threads, and the variable as the processes the command starts see it.
BLAS_PROBE = """
import ctypes, glob, os, sys
sys.argv = [sys.argv[1]]  # 'orchestrate': the command's own process, as orchestrator._startup tells
import orchestrator
import numpy
libs = glob.glob(os.path.join(os.path.dirname(numpy.__file__), os.pardir, "numpy.libs", "libscipy_openblas*"))
threads = ctypes.CDLL(libs[0]).scipy_openblas_get_num_threads64_() if libs else 0
print(threads, os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.parametrize(("argv0", "chosen", "expected"), [
    ("/somewhere/bin/orchestrate", {}, ("1", "None")),  # the command: one thread, environment as it was
    ("/somewhere/bin/orchestrate", {"OPENBLAS_NUM_THREADS": "2"}, ("2", "2")),  # the user's number stands
    ("/somewhere/bin/orchestrate", {"OMP_NUM_THREADS": "2"}, ("2", "None")),  # in any variable OpenBLAS reads
    ("notebook.py", {}, (str(os.cpu_count()), "None")),  # a library user's process: NumPy's default
])
def test_the_command_loads_openblas_with_one_thread(argv0: str, chosen: dict[str, str],
                                                    expected: tuple[str, str]) -> None:
    """OpenBLAS's idle threads spin: 0.12 s of CPU in every ``orchestrate run`` on 2 cores (issue
    46). Oracle: OpenBLAS's own thread count, read from the library NumPy loaded. (The variables
    are cleared first: a Dask nanny started by an earlier test sets OMP_NUM_THREADS in its own
    process.)"""
    if os.cpu_count() == 1 and argv0 == "notebook.py":
        pytest.skip("one core: NumPy's default is one thread too")
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS",
                                                            "OMP_NUM_THREADS")}
    env.update(chosen)
    done = subprocess.run([sys.executable, "-c", BLAS_PROBE, argv0], capture_output=True, text=True, env=env,
                          check=True)
    threads, variable = done.stdout.split()
    if threads == "0":
        pytest.skip("this NumPy does not load scipy-openblas")
    assert (threads, variable) == expected
