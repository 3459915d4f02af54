"""The ``orchestrate`` command: the engine's own subcommands (run, validate, plot) and those of every
application (experiments, crosscheck, campaigns, ...), which register themselves.

An application lists a ``register(subparsers)`` function under the entry-point group
``orchestrate.commands`` (pyproject.toml); it adds its subcommands with :func:`add_command`. A
handler returns the exit status; an :class:`~orchestrator.errors.OrchestratorError` it raises is
printed as one line (``orchestrate: error: ...``) and its ``exit_status`` returned; a
:class:`~orchestrator.errors.UsageError` goes through ``parser.error`` (usage, one line, exit 2).
"""

from __future__ import annotations

import argparse
import logging
import math
import platform
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from importlib.metadata import PackageNotFoundError, entry_points, version
from pathlib import Path
from typing import TypedDict, Unpack

from . import MASTERS, run
from .errors import (
    Interrupted,
    OrchestratorError,
    OutputError,
    ScenarioError,
    ScenarioWarning,
    SimulationError,
    UsageError,
    terminate,
)
from .formats import Selection, check_output
from .plots import check_plot, plot_run
from .provenance import overrides_text, read_provenance
from .results import read_result
from .ssp import DEFAULT_LIMITS, Limits
from .validate import validate

__all__ = ["COMMAND_GROUP", "add_archive_limits", "add_command", "archive_limits", "fmu_dirs", "main",
           "plot_title", "resolve_scenario", "stale_build", "version_line"]

COMMAND_GROUP = "orchestrate.commands"

DESCRIPTION = """\
Run SSP co-simulation scenarios (controller + actuator + plant FMUs) with fmpy.

  orchestrate build                    build the FMUs and pack ssp/<name>/ into build/ssp/<name>.ssp
  orchestrate run example1             simulate; writes results/example1.csv and .png
  orchestrate validate example1        every check before a simulation, all problems at once
  orchestrate metrics results/example1.csv   tracking metrics (RAE, MSE, RMSE, MAE, ...)
  orchestrate plot results/example1.csv      plot a result file
  orchestrate compare RESULT.csv BASELINE.csv  regression check against a baseline
  orchestrate baseline / orchestrate report  rewrite baselines / write the paper report

Run 'orchestrate COMMAND --help' for the options of a command.
"""
RUN_HELP = """\
SCENARIO is a .ssp archive, a folder holding SystemStructure.ssd, or the name of a built
scenario (build/ssp/NAME.ssp). A built scenario whose sources (ssp/NAME/, fmu_src/, controller/)
changed after the build is refused, naming the changed file. A scenario source folder (ssp/NAME)
runs directly, with the FMUs of build/fmus/. Start, stop time and step come from the scenario
unless given; the step must divide the run. An input no connection feeds is a warning.
Results go to results/<name>.csv (and .png), written as the run goes: a failed run keeps every
row up to the failure.

masters:
  gauss-seidel  (default) all FMUs step, then outputs are propagated through direct-feedthrough
                components in dependency order: the controller's v at t_k uses the plant at t_k.
  jacobi        libcosim's algorithm: every connection delays its value by one step.

Faults: an FMU call that fails, a NaN or infinite value, or the --timeout end the run with one
line and the rows before the fault kept; Ctrl-C (SIGINT) or SIGTERM stop it at the next
communication point, keep every row computed and write the plot of them. The CSV is written to a
temporary file and renamed, so its name never holds a half-written file.

exit status: 0 success, 1 scenario error, simulation failure or --timeout, 2 usage error,
130 interrupted (SIGINT), 143 terminated (SIGTERM).
"""
VALIDATE_HELP = """\
Check SCENARIO (as for 'run') without simulating: the archive, the SSD and SSV files against the
SSP schemas, every FMU (fmpy's validate_fmu), connections (components, connectors, direction,
types, units), parameter values (names, types, ranges), unconnected inputs and algebraic loops.
Each stage goes as far as it can, and every problem is printed on its own line naming the file,
component and connector or variable:
  error:   'run' would refuse the scenario
  warning: FMI non-compliance that 'run' tolerates (fmpy's full FMU validation), no stop time, or
           an input that no connection feeds (it keeps the FMU's start value; 'run --strict' refuses)

exit status: 0 no error (warnings allowed), 1 errors found, 2 usage error.
"""


Handler = Callable[[argparse.Namespace], int]


class CommandOptions(TypedDict, total=False):
    """Keyword arguments of :func:`add_command`, passed on to ``add_parser``."""

    help: str
    description: str | None
    epilog: str | None
    formatter_class: type[argparse.HelpFormatter]


def add_command(subparsers: argparse._SubParsersAction, name: str, handler: Handler,
                **kwargs: Unpack[CommandOptions]) -> argparse.ArgumentParser:
    """Add subcommand ``name`` run by ``handler(args) -> exit status``; returns its parser."""
    parser = subparsers.add_parser(name, **kwargs)
    parser.set_defaults(handler=handler)
    return parser


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="orchestrate", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=version_line())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = add_command(sub, "run", _run, help="simulate a scenario", description=RUN_HELP,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)
    p.add_argument("--start-time", type=float, metavar="T", help="start time in s (default: from the SSD)")
    p.add_argument("--stop-time", type=float, metavar="T", help="stop time in s (default: from the SSD)")
    p.add_argument("--step", type=float, metavar="H",
                   help="communication step in s (default: from the SSD); must divide the run")
    p.add_argument("--output", type=Path, metavar="FILE",
                   help="result file, format by extension: .csv, .parquet, .mat (Dymola/OpenModelica "
                        "trajectory) (default: results/<name>.csv)")
    p.add_argument("--output-variables", action="append", default=[], metavar="PATTERN",
                   help="columns to write, shell patterns such as 'plant.*' (repeatable; default: all)")
    p.add_argument("--output-interval", type=float, metavar="S",
                   help="write every row at t0 + k S only (a multiple of the step; default: every step)")
    p.add_argument("--no-inputs", action="store_true",
                   help="leave out input columns that only repeat the output connected to them")
    p.add_argument("--plot", type=Path, metavar="FILE.png", help="plot file (default: results/<name>.png)")
    p.add_argument("--no-plot", action="store_true", help="do not plot")
    p.add_argument("--master", choices=list(MASTERS), default="gauss-seidel", help="master algorithm")
    p.add_argument("--allow-stale", action="store_true",
                   help="run a built scenario even when its sources changed after the build")
    p.add_argument("--strict", action="store_true",
                   help="refuse the scenario when an input is not connected (default: a warning)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary")
    p.add_argument("--verbose", action="store_true", help="show the FMUs' log messages as they come")
    p.add_argument("--timeout", type=float, metavar="SECONDS",
                   help="wall-clock limit of the run: stop at the next communication point (a step that "
                        "does not return is aborted 2 s later); exit status 1, rows kept")

    p = add_command(sub, "validate", _validate, help="check a scenario without simulating",
                    description=VALIDATE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)

    p = add_command(sub, "plot", _plot, help="plot a result file")
    p.add_argument("result", type=Path, metavar="RESULT.csv")
    p.add_argument("--output", type=Path, metavar="FILE.png", help="default: RESULT with .png")

    for entry in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        entry.load()(sub)
    return parser


def _scenario_arguments(p: argparse.ArgumentParser) -> None:
    """SCENARIO, --parameter-set and --set, as 'run' and 'validate' take them."""
    p.add_argument("scenario", metavar="SCENARIO", help=".ssp file, scenario folder or built scenario name")
    p.add_argument("--parameter-set", action="append", default=[], metavar="FILE.ssv",
                   help="parameter values named COMPONENT.VARIABLE, applied after the SSD's own (repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="COMPONENT.VARIABLE=VALUE",
                   help="set one parameter or start value, applied last (repeatable)")
    add_archive_limits(p)


def add_archive_limits(p: argparse.ArgumentParser) -> None:
    """The options of :class:`~orchestrator.ssp.Limits`, for every command that reads an archive
    (read back with :func:`archive_limits`)."""
    group = p.add_argument_group("archive limits", "what an .ssp archive and each FMU in it may unpack to "
                                 "(sizes in bytes; K, M, G suffixes)")
    for field, option, what in (("total", "--max-total-size", "all members extracted together"),
                                ("member", "--max-member-size", "one member"),
                                ("ratio", "--max-ratio", "compression ratio of a member of 1 MiB or more"),
                                ("members", "--max-members", "number of members"),
                                ("xml", "--max-xml-size", "one SSD, SSV, SSM or modelDescription.xml")):
        default = getattr(DEFAULT_LIMITS, field)
        group.add_argument(option, dest=f"limit_{field}", type=_ratio if field == "ratio" else _bytes,
                           default=default, metavar="N", help=f"{what} (default {default:g})")


def _overrides(items: Sequence[str]) -> dict[str, str]:
    """``--set COMPONENT.VARIABLE=VALUE`` options as a mapping (values converted by the engine)."""
    overrides = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            raise UsageError(f"--set expects COMPONENT.VARIABLE=VALUE (got '{item}')")
        overrides[key.strip()] = value.strip()
    return overrides


def _ratio(text: str) -> float:
    """A compression ratio: a positive finite number (NaN would disable the check without a word)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a ratio: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"not a ratio: {text!r}")
    return value


def _bytes(text: str) -> int:
    """``512M`` -> 536870912: a size in bytes with an optional K, M or G (powers of 1024)."""
    factor = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}.get(text[-1:].upper(), 1)
    try:
        value = float(text[:-1] if factor > 1 else text) * factor
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a size: {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"not a size: {text!r}")
    return int(value)


def archive_limits(args: argparse.Namespace) -> Limits:
    """The archive limits of the command line (:func:`add_archive_limits`)."""
    return Limits(**{f: getattr(args, f"limit_{f}") for f in ("total", "member", "ratio", "members", "xml")})


def version_line() -> str:
    """``orchestrate X.Y.Z (fmpy A, numpy B, Python C)``: what ``--version`` prints."""
    def installed(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    return (f"orchestrate {installed('fixed-time-cosim')} (fmpy {installed('fmpy')}, "
            f"numpy {installed('numpy')}, Python {platform.python_version()})")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``orchestrate``; returns the exit status."""
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:  # SIGINT, SIGTERM at any moment: cleanup runs, one line, 130 or 143 (an ignored
        previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)  # one stays so)
        for signum, handler in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, terminate)):
            if signal.getsignal(signum) is not signal.SIG_IGN:
                signal.signal(signum, handler)
    try:
        parser = _parser()
        args = parser.parse_args(argv)
        try:
            return args.handler(args)
        except UsageError as exc:
            parser.error(str(exc))  # usage, one line "orchestrate: error: ...", exit status 2
        except OrchestratorError as exc:
            what = "cannot write the results: " if isinstance(exc, OutputError) else ""
            print(f"orchestrate: error: {what}{exc}", file=sys.stderr)
            return exc.exit_status
    except KeyboardInterrupt as exc:
        print(f"orchestrate: {str(exc) or 'interrupted by SIGINT'}", file=sys.stderr)
        return getattr(exc, "exit_status", 130)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous[0])
            signal.signal(signal.SIGTERM, previous[1])


BUILD_DIR = Path("build")
SOURCE_DIR = Path("ssp")
FMU_SOURCES = (Path("fmu_src"), Path("controller"))  # what 'orchestrate build' makes the FMUs from


def resolve_scenario(scenario: str) -> Path:
    """A scenario given as a file, a folder, or the name of a built scenario (build/ssp/NAME.ssp)."""
    path = Path(scenario)
    if path.exists():
        return path
    built = BUILD_DIR / "ssp" / f"{scenario}.ssp"
    if built.is_file():
        return built
    raise ScenarioError(f"no scenario '{scenario}': not a file or folder, and {built} does not exist "
                        "(run 'orchestrate build' first)")


def fmu_dirs(scenario: Path) -> list[Path]:
    """Where a scenario source folder (no FMUs under resources/) takes its FMUs: build/fmus/."""
    return [BUILD_DIR / "fmus"] if scenario.is_dir() and (BUILD_DIR / "fmus").is_dir() else []


def _files(folder: Path) -> list[Path]:
    return [f for f in folder.rglob("*") if f.is_file() and "__pycache__" not in f.parts
            and not f.name.startswith(".")]


def _newer(target: Path, sources: list[Path]) -> Path | None:
    """The most recently modified file of ``sources`` (folders, walked) modified after ``target``."""
    files = [f for folder in sources if folder.is_dir() for f in _files(folder)]
    newest = max(files, key=lambda f: f.stat().st_mtime, default=None)
    return newest if newest is not None and newest.stat().st_mtime > target.stat().st_mtime else None


def stale_build(scenario: Path) -> str:
    """Why the build that ``scenario`` runs from is older than its sources ('' when it is not): a
    built archive build/ssp/NAME.ssp against ssp/NAME/ and the FMU sources, a source folder's
    FMUs in build/fmus/ against the FMU sources (paths relative to the working directory, as
    'orchestrate build' writes them)."""
    if scenario.is_file() and scenario.suffix == ".ssp":
        archive = BUILD_DIR / "ssp" / scenario.name
        if not (archive.is_file() and archive.resolve() == scenario.resolve()):
            return ""
        folder = SOURCE_DIR / scenario.stem
        changed = _newer(archive, [folder, *FMU_SOURCES])
        if changed is None:
            return ""
        other = (f", or run the source folder {folder} (with the FMUs of {BUILD_DIR / 'fmus'})"
                 if changed.is_relative_to(folder) else "")
        return (f"{archive} is older than {changed} (changed after the build): run 'orchestrate build' "
                f"again{other}, or give --allow-stale")
    dirs = fmu_dirs(scenario)
    if dirs and not any((scenario / "resources").glob("*.fmu")):
        fmus = sorted(dirs[0].glob("*.fmu"), key=lambda f: f.stat().st_mtime)
        changed = _newer(fmus[0], list(FMU_SOURCES)) if fmus else None
        if changed is not None:
            return (f"{fmus[0]} is older than {changed} (changed after the build): run 'orchestrate build' "
                    "again, or give --allow-stale")
    return ""


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


def _run(args: argparse.Namespace) -> int:
    overrides = _overrides(args.set)
    if args.step is not None and not (math.isfinite(args.step) and args.step > 0):
        raise UsageError(f"--step must be positive and finite (got {args.step!r})")
    for option, value in (("--stop-time", args.stop_time), ("--start-time", args.start_time)):
        if value is not None and not math.isfinite(value):
            raise UsageError(f"{option} must be finite (got {value!r})")
    if args.timeout is not None and not (math.isfinite(args.timeout) and args.timeout > 0):
        raise UsageError(f"--timeout must be positive and finite (got {args.timeout!r})")
    scenario = resolve_scenario(args.scenario)
    stale = stale_build(scenario)
    if stale and not args.allow_stale:
        raise ScenarioError(stale)
    name = scenario.stem if scenario.is_file() else scenario.resolve().name
    output = args.output or Path("results") / f"{name}.csv"
    check_output(output, selection=Selection(tuple(args.output_variables), args.output_interval))
    plot = None if args.no_plot else args.plot or output.with_suffix(".png")
    if plot is not None:
        check_plot(plot)
    progress = None if args.quiet or not sys.stderr.isatty() else _Progress(name)
    messages = _LastMessage(args.verbose)
    logging.getLogger().addHandler(messages)
    if args.verbose:
        logging.getLogger().setLevel(logging.INFO)
    status = 0  # 130/143 when interrupted: the rows kept are plotted, then that status returned
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ScenarioWarning)
            result = run(scenario, stop_time=args.stop_time, step=args.step,
                         parameter_sets=args.parameter_set, overrides=overrides, master=args.master,
                         output=output, progress=progress, start_time=args.start_time, strict=args.strict,
                         fmu_dirs=fmu_dirs(scenario), keep=False, timeout=args.timeout,
                         limits=archive_limits(args),
                         output_variables=args.output_variables, output_interval=args.output_interval,
                         no_inputs=args.no_inputs)
        _print_warnings(caught)
    except SimulationError as exc:
        rows = getattr(exc, "rows", len(getattr(exc, "result", ())))
        detail = f" ({messages.last})" if messages.last and "(" not in str(exc) else ""
        print(f"orchestrate: error: {exc}{detail}; {rows} rows kept in {output}", file=sys.stderr)
        return 1
    except Interrupted as exc:
        stopped = f"orchestrate: {exc}; {exc.rows} rows kept in {output}"
        if plot is None or exc.rows < 2:
            print(stopped, file=sys.stderr)
            return exc.exit_status
        result, status = exc.result, exc.exit_status  # plot the rows kept, then say so
    except OSError as exc:  # OutputError: writing the results; else reading (a full TMPDIR, ...)
        what = "cannot write the results: " if isinstance(exc, OutputError) else ""
        print(f"orchestrate: error: {what}{exc}", file=sys.stderr)
        return 1
    finally:
        logging.getLogger().removeHandler(messages)
    if plot is not None:
        try:
            record = read_provenance(output)
            plot_run(result, plot, plot_title(name, record, args.master), *_plot_context(record))
        except OSError as exc:
            print(f"orchestrate: error: cannot write the plot: {exc}; results kept in {output}",
                  file=sys.stderr)
            return status or 1
    if status:
        print(f"{stopped} (plot: {plot})", file=sys.stderr)
        return status
    if not args.quiet:
        extra = f" and {plot}" if plot is not None else ""
        record = read_provenance(output) or {}
        span = f"t = {result['time'][0]:g} .. {result['time'][-1]:g} s"
        print(f"{name}: {record.get('rows', len(result))} rows, {span} -> {output}{extra}")
    return 0


def _print_warnings(caught: Sequence[warnings.WarningMessage]) -> None:
    """Scenario warnings on stderr, one line each (every run, also with --quiet); others re-issued."""
    for w in caught:
        if issubclass(w.category, ScenarioWarning):
            print(f"orchestrate: warning: {w.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def plot_title(name: str, record: dict | None, master: object = None) -> str:
    """``name (master)`` and, on a second line, the overrides and parameter sets of the run, so a
    plot of a changed run never looks like the default one."""
    title = f"{name} ({master})" if master else name
    changed = overrides_text(record)
    return f"{title}\n{changed}" if changed else title


def _plot_context(record: dict | None) -> tuple[dict, float | None]:
    """Column units and the fault time (``actuator.t_fault``) from a result's provenance."""
    if record is None:
        return {}, None
    fault = (record.get("start_values") or {}).get("actuator.t_fault")
    return record.get("units") or {}, float(fault) if isinstance(fault, (int, float)) else None


def _validate(args: argparse.Namespace) -> int:
    overrides = _overrides(args.set)
    scenario = resolve_scenario(args.scenario)
    report = validate(scenario, parameter_sets=args.parameter_set, overrides=overrides,
                      fmu_dirs=fmu_dirs(scenario), limits=archive_limits(args))
    stale = stale_build(scenario)
    if stale:
        print(f"warning: {stale}")
    for problem in report.problems:
        print(problem)
    if not report.ok:
        warnings = len(report.problems) - len(report.errors)
        print(f"failed: {scenario}: {len(report.errors)} error(s), {warnings} warning(s)")
        return 1
    print(f"ok: {scenario}: {report.components} components, {report.connections} connections, "
          f"{report.parameters} parameters checked")
    return 0


def _plot(args: argparse.Namespace) -> int:
    data = read_result(args.result)
    target = args.output or args.result.with_suffix(".png")
    record = read_provenance(args.result)
    plot_run(data, target, plot_title(args.result.stem, record, record.get("master") if record else None),
             *_plot_context(record))
    print(target)
    return 0
