# SPDX-License-Identifier: BSD-2-Clause
"""Run your own SSP built from the Modelica Reference FMUs with ``orchestrate``, and check it.

    python examples/reference_fmus/run.py [REFERENCE_FMUS_FOLDER] [OUT_FOLDER]

REFERENCE_FMUS_FOLDER holds the FMI 2.0 ``Dahlquist.fmu`` and ``Feedthrough.fmu`` (default:
``../shared/tools/reference-fmus/2.0``; get them from github.com/modelica/Reference-FMUs). The
scenario folder (this folder's ``SystemStructure.ssd``) is copied to OUT_FOLDER with the FMUs in
``resources/``, validated, run, and its result compared with x(t) = exp(-k t): Dahlquist
integrates with forward Euler at a fixed step of 0.1 s, the communication step here, so
x_n = (1 - k h)^n exactly, and Feedthrough's output is 2 x through the connection's
LinearTransformation, one step late: the SSD declares libcosim's fixed-step algorithm
(``osp:FixedStepAlgorithm``), which exchanges every connection at the end of a step, and
``orchestrate`` runs the file's own algorithm (Jacobi), so feedthrough_n = 2 x_(n-1) after the
initial exchange (``--master gauss-seidel`` would give 2 x_n).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
from fmpy.util import read_csv

HERE = Path(__file__).resolve().parent
K, H = 0.5, 0.1  # the SSD's k and step: Dahlquist's own solver step is 0.1 too


def main(argv: list[str]) -> int:
    fmus = Path(argv[1]) if len(argv) > 1 else Path("../shared/tools/reference-fmus/2.0")
    out = Path(argv[2]) if len(argv) > 2 else Path("results/examples/decay")
    scenario = out / "decay"
    shutil.rmtree(scenario, ignore_errors=True)
    (scenario / "resources").mkdir(parents=True)
    shutil.copy(HERE / "SystemStructure.ssd", scenario)
    for name in ("Dahlquist.fmu", "Feedthrough.fmu"):
        shutil.copy(fmus / name, scenario / "resources" / name)
    result = out / "decay.csv"
    for command in (["validate", str(scenario)],
                    ["run", str(scenario), "--output", str(result), "--no-plot", "--quiet"]):
        subprocess.run([sys.executable, "-m", "orchestrator", *command], check=True)
    rows = read_csv(str(result))
    euler = (1.0 - K * H) ** np.arange(len(rows))
    error = np.max(np.abs(rows["dahlquist.x"] - euler))
    x, out_ = rows["dahlquist.x"], rows["feedthrough.Float64_continuous_output"]
    delayed = np.concatenate(([x[0]], x[:-1]))  # the value each step's exchange passed on
    through = np.max(np.abs(out_ - 2.0 * delayed))
    print(f"decay: {len(rows)} rows; max |x - (1 - k h)^n| = {error:.1e}; "
          f"max |feedthrough - 2 x(one step before)| = {through:.1e}; x(4) = {rows['dahlquist.x'][-1]:.6f} "
          f"(exp(-k t) = {np.exp(-K * 4.0):.6f})")
    return 0 if error < 1e-12 and through < 1e-12 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
