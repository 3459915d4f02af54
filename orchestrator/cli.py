"""The ``orchestrate`` command: run, build, metrics and plot for SSP co-simulation scenarios."""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Sequence
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from . import MASTERS, load, run
from .errors import ScenarioError, SimulationError
from .results import plot_result

__all__ = ["main"]

DESCRIPTION = """\
Run SSP co-simulation scenarios (controller + actuator + plant FMUs) with fmpy.

  orchestrate build                    build the FMUs and pack ssp/<name>/ into build/ssp/<name>.ssp
  orchestrate run example1             simulate; writes results/example1.csv and .png
  orchestrate metrics results/example1.csv   tracking metrics (RAE, MSE, RMSE, MAE, ...)
  orchestrate plot results/example1.csv      plot a result file
  orchestrate compare RESULT.csv BASELINE.csv  regression check against a baseline
  orchestrate baseline / orchestrate report  rewrite baselines / write the paper report

Run 'orchestrate COMMAND --help' for the options of a command.
"""

RUN_HELP = """\
SCENARIO is a .ssp archive, a folder holding SystemStructure.ssd, or the name of a built
scenario (build/ssp/NAME.ssp). Stop time and step come from the scenario unless given.
Results go to results/<name>.csv (and .png), written as the run goes: a failed run keeps every
row up to the failure.

masters:
  gauss-seidel  (default) all FMUs step, then outputs are propagated through direct-feedthrough
                components in dependency order: the controller's v at t_k uses the plant at t_k.
  jacobi        libcosim's algorithm: every connection delays its value by one step.

exit status: 0 success, 1 scenario error or simulation failure, 2 usage error, 130 interrupted.
"""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="orchestrate", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("run", help="simulate a scenario", description=RUN_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", metavar="SCENARIO", help=".ssp file, scenario folder or built scenario name")
    p.add_argument("--stop-time", type=float, metavar="T", help="stop time in s (default: from the SSD)")
    p.add_argument("--step", type=float, metavar="H", help="communication step in s (default: from the SSD)")
    p.add_argument("--parameter-set", action="append", default=[], metavar="FILE.ssv",
                   help="parameter values named COMPONENT.VARIABLE, applied after the SSD's own (repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="COMPONENT.VARIABLE=VALUE",
                   help="set one parameter or start value, applied last (repeatable)")
    p.add_argument("--output", type=Path, metavar="FILE.csv", help="result CSV (default: results/<name>.csv)")
    p.add_argument("--plot", type=Path, metavar="FILE.png", help="plot file (default: results/<name>.png)")
    p.add_argument("--no-plot", action="store_true", help="do not plot")
    p.add_argument("--master", choices=list(MASTERS), default="gauss-seidel", help="master algorithm")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    p.add_argument("--verbose", action="store_true", help="show the FMUs' log messages as they come")

    p = sub.add_parser("build", help="build the FMUs and pack the scenarios into .ssp archives")
    p.add_argument("scenarios", nargs="*", metavar="NAME", help="scenarios to pack (default: all in ssp/)")
    p.add_argument("--sources", type=Path, default=Path("ssp"), help="scenario sources (default: ssp/)")
    p.add_argument("--dest", type=Path, default=Path("build"), help="output folder (default: build/)")

    p = sub.add_parser("metrics", help="tracking metrics of result files (SPEC section 4)")
    p.add_argument("results", nargs="+", type=Path, metavar="RESULT.csv")
    p.add_argument("--band", type=float, default=0.05, help="settling band on |y - yd| (default 0.05)")

    for name, text in (("compare", "compare a result CSV with a baseline (regression tubes)"),
                       ("baseline", "run the scenarios and rewrite the regression baselines"),
                       ("report", "the paper's examples by co-simulation, as a report")):
        sub.add_parser(name, help=text)  # listed here; main() hands the options to the delegate

    p = sub.add_parser("plot", help="plot a result file")
    p.add_argument("result", type=Path, metavar="RESULT.csv")
    p.add_argument("--output", type=Path, metavar="FILE.png", help="default: RESULT with .png")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``orchestrate``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in ("compare", "baseline"):  # the regression tool parses its own options
        from .regression import main as regression_main

        return regression_main(argv)
    if argv and argv[0] == "report":
        from .report import main as report_main

        return report_main(argv[1:])
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        return {"run": _run, "build": _build, "metrics": _metrics, "plot": _plot}[args.command](args, parser)
    except ScenarioError as exc:
        print(f"orchestrate: error: {exc}", file=sys.stderr)
        return 1


def _resolve(scenario: str) -> Path:
    path = Path(scenario)
    if path.exists():
        return path
    built = Path("build") / "ssp" / f"{scenario}.ssp"
    if built.is_file():
        return built
    raise ScenarioError(f"no scenario '{scenario}': not a file or folder, and {built} does not exist "
                        "(run 'orchestrate build' first)")


class _Progress:
    """A one-line progress bar on stderr."""

    def __init__(self, label: str) -> None:
        self.label = label

    def __call__(self, done: int, total: int) -> None:
        width = 30
        filled = width * done // total
        bar = "#" * filled + "." * (width - filled)
        sys.stderr.write(f"\r{self.label} [{bar}] {100 * done // total:3d} %")
        if done == total:
            sys.stderr.write("\n")
        sys.stderr.flush()


class _LastMessage(logging.Handler):
    """Keeps the last warning or error logged (FMUs written in Python log in our process), so a
    failure is reported on one line with the FMU's own explanation; prints them with --verbose."""

    def __init__(self, verbose: bool) -> None:
        super().__init__(logging.INFO if verbose else logging.WARNING)
        self.verbose = verbose
        self.last = ""

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:
            self.last = record.getMessage().strip().splitlines()[-1] if record.getMessage().strip() else ""
        if self.verbose:
            print(f"{record.name}: {record.getMessage()}", file=sys.stderr)


def _run(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    overrides = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            parser.error(f"--set expects COMPONENT.VARIABLE=VALUE (got '{item}')")
        overrides[key.strip()] = value.strip()
    if args.step is not None and not (math.isfinite(args.step) and args.step > 0):
        parser.error(f"--step must be positive and finite (got {args.step!r})")
    if args.stop_time is not None and not math.isfinite(args.stop_time):
        parser.error(f"--stop-time must be finite (got {args.stop_time!r})")
    scenario = _resolve(args.scenario)
    name = scenario.stem if scenario.is_file() else scenario.resolve().name
    output = args.output or Path("results") / f"{name}.csv"
    plot = None if args.no_plot else args.plot or output.with_suffix(".png")
    progress = None if args.quiet or not sys.stderr.isatty() else _Progress(name)
    messages = _LastMessage(args.verbose)
    logging.getLogger().addHandler(messages)
    if args.verbose:
        logging.getLogger().setLevel(logging.INFO)
    try:
        result = run(scenario, args.stop_time, args.step, args.parameter_set, overrides, args.master,
                     output, progress)
    except SimulationError as exc:
        rows = len(getattr(exc, "result", ()))
        detail = f" ({messages.last})" if messages.last and "(" not in str(exc) else ""
        print(f"orchestrate: error: {exc}{detail}; {rows} rows kept in {output}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"orchestrate: interrupted; rows computed so far kept in {output}", file=sys.stderr)
        return 130
    except OSError as exc:
        print(f"orchestrate: error: cannot write the results: {exc}", file=sys.stderr)
        return 1
    finally:
        logging.getLogger().removeHandler(messages)
    if plot is not None:
        try:
            plot_result(result, plot, f"{name} ({args.master})")
        except OSError as exc:
            print(f"orchestrate: error: cannot write the plot: {exc}; results kept in {output}",
                  file=sys.stderr)
            return 1
    if not args.quiet:
        extra = f" and {plot}" if plot is not None else ""
        span = f"t = {result['time'][0]:g} .. {result['time'][-1]:g} s"
        print(f"{name}: {len(result)} rows, {span} -> {output}{extra}")
    return 0


def _build(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from fmu_src.build import build_all

    from .sspwriter import pack_ssp

    sources: Path = args.sources
    names = args.scenarios or sorted(p.parent.name for p in sources.glob("*/SystemStructure.ssd"))
    if not names:
        parser.error(f"no scenarios found in {sources}/")
    fmus = {p.name: p for p in build_all(args.dest / "fmus")}
    for name in names:
        folder = sources / name
        if not (folder / "SystemStructure.ssd").is_file():
            raise ScenarioError(f"{folder}: no SystemStructure.ssd")
        needed = {}
        for component in _component_sources(folder):
            if component not in fmus:
                raise ScenarioError(f"{folder}/SystemStructure.ssd: FMU '{component}' is not built by "
                                    f"fmu_src.build (built: {', '.join(sorted(fmus))})")
            needed[component] = fmus[component]
        target = pack_ssp(folder, needed, args.dest / "ssp" / f"{name}.ssp")
        with ExitStack() as stack:
            load(target, stack)  # validate the packed archive against the FMUs
        print(f"{target}")
    return 0


def _component_sources(folder: Path) -> list[str]:
    """FMU file names the SSD refers to (``resources/X.fmu`` -> ``X.fmu``), read without the FMUs."""
    from lxml import etree

    from .ssp import NS

    root = etree.parse(str(folder / "SystemStructure.ssd")).getroot()
    return [Path(c.get("source")).name for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)]


def _read_result(path: Path, parser: argparse.ArgumentParser) -> np.ndarray:
    """A result CSV read with fmpy's reader; a missing or unreadable file is a usage error naming it."""
    from .regression import RegressionError, read_result

    try:
        return read_result(path)
    except RegressionError as exc:
        parser.error(str(exc))


def _metrics(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from controller.metrics import format_table, tracking_metrics

    rows = []
    for path in args.results:
        data = _read_result(path, parser)
        names = data.dtype.names
        missing = [c for c in ("plant.y", "reference.yd") if c not in names]
        if missing:
            raise ScenarioError(f"{path}: no column {', '.join(missing)} (needs plant.y and reference.yd)")
        try:
            m = tracking_metrics(data["time"], data["plant.y"], data["reference.yd"],
                                 data["controller.v"] if "controller.v" in names else None,
                                 data["actuator.uf"] if "actuator.uf" in names else None, band=args.band)
        except ValueError as exc:
            raise ScenarioError(f"{path}: {exc}") from exc
        rows.append((path.stem, m))
    print(format_table(rows))
    return 0


def _plot(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    data = _read_result(args.result, parser)
    target = args.output or args.result.with_suffix(".png")
    plot_result(data, target, args.result.stem)
    print(target)
    return 0
