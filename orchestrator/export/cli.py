# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate export SCENARIO -o NAME.fmu``: the subcommand."""

from __future__ import annotations

import argparse
import sys

from .. import MASTERS
from ..cli import (
    _scenario_arguments,
    add_command,
    archive_limits,
    fmu_dirs,
    parse_overrides,
    resolve_scenario,
    scenario_checks,
)
from ..errors import ScenarioError
from .container import FMI_VERSIONS, export

__all__ = ["register"]

DESCRIPTION = """\
Export SCENARIO (as for 'run': a .ssp archive, a scenario folder or a built scenario's name) as one
Co-Simulation FMU (FMI 2.0; 3.0 with --fmi 3) for tools that take an FMU but no SSP (Simulink,
Dymola and other Modelica tools, fmusim, FMPy). The FMU holds the scenario's FMUs, connections,
parameter values (SSD, .ssv files, --parameter-set, --set; units converted as 'run' converts
them), step and DefaultExperiment, and runs the same master as 'orchestrate run' on the same grid:
plant.y equals 'run's. It needs no Python on the host (needsExecutionTool="false"), linux64 and win64.

Exposed (default): every output of every component and every input no connection feeds, named
COMPONENT.CONNECTOR; --expose PATTERN (repeatable, shell patterns) chooses among those and the
components' Real, Integer and Boolean parameters instead. The host's communication step must be
a multiple of the scenario's step.

exit status: 0 written, 1 scenario error, 2 usage error.
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``export`` to ``orchestrate``."""
    p = add_command(sub, "export", _export, help="export a scenario as one FMU (for tools without SSP)",
                    quiet=True, description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)
    p.add_argument("-o", "--output", required=True, metavar="NAME.fmu", help="the FMU to write")
    p.add_argument("--fmi", choices=FMI_VERSIONS, default="2", help="FMI version of the FMU (default 2)")
    p.add_argument("--master", choices=list(MASTERS), default="gauss-seidel",
                   help="master algorithm inside the FMU (default gauss-seidel, as 'run')")
    p.add_argument("--expose", action="append", default=[], metavar="PATTERN",
                   help="variables the FMU exposes, e.g. 'plant.*' or controller.k1 (repeatable; default: "
                        "every output and unconnected input)")
    p.add_argument("--start-time", type=float, metavar="T", help="DefaultExperiment start (default: SSD's)")
    p.add_argument("--stop-time", type=float, metavar="T", help="DefaultExperiment stop (default: the SSD's)")
    p.add_argument("--step", type=float, metavar="H",
                   help="communication step inside the FMU (default: the SSD's); must divide the run")
    p.add_argument("--allow-stale", action="store_true",
                   help="export a built scenario even when its sources changed after the build")


def _export(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    scenario = resolve_scenario(args.scenario)
    stale = scenario_checks(scenario)
    if stale and not args.allow_stale:
        raise ScenarioError(stale)
    try:
        path, exposed = export(scenario, args.output, fmi=args.fmi, master=args.master, expose=args.expose,
                               parameter_sets=args.parameter_set, overrides=overrides,
                               fmu_dirs=fmu_dirs(scenario), limits=archive_limits(args),
                               start_time=args.start_time,
                               stop_time=args.stop_time, step=args.step)
    except OSError as exc:  # the target's folder read-only, the disk full: the target is left as it was
        print(f"orchestrate: error: cannot write {args.output}: {exc}", file=sys.stderr)
        return 1
    kinds = {k: sum(e.kind == k for e in exposed) for k in ("input", "output", "parameter")}
    size = path.stat().st_size / 1e6
    if not args.quiet:
        print(f"{path}: {kinds['output']} outputs, {kinds['input']} inputs, {kinds['parameter']} parameters, "
              f"{size:.1f} MB")
    return 0
