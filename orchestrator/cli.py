# SPDX-License-Identifier: BSD-2-Clause
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
import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn, TypedDict, Unpack

from . import MASTERS, RunOptions, RunResult, run
from .errors import (
    EngineNote,
    Interrupted,
    OrchestratorError,
    OrchestratorWarning,
    OutputError,
    ScenarioError,
    SimulationError,
    UsageError,
    command_line,
    terminate,
)
from .fmi import CALLS
from .installed import entry_points, version
from .locate import BUILD_DIR, fmu_dirs, resolve_scenario
from .master import LOOP_ITERATIONS, LOOP_TOLERANCE
from .plots import check_plot, plot_run
from .provenance import overrides_text, read_provenance
from .result import EXECUTORS
from .results import read_result
from .ssp import DEFAULT_LIMITS, Limits
from .validate import validate

SHELLS = ("bash", "zsh", "fish", "tcsh", "powershell")  # what argcomplete writes scripts for

__all__ = ["BUILD_DIR", "CHECK_GROUP", "COMMAND_GROUP", "EXIT_STATUS", "add_archive_limits", "add_command",
           "add_output", "archive_limits", "fmu_dirs", "main", "parse_overrides", "plot_title", "quiet",
           "resolve_scenario", "scenario_checks", "size_text", "version_line", "warn"]

COMMAND_GROUP = "orchestrate.commands"
CHECK_GROUP = "orchestrate.checks"

DESCRIPTION = """\
Run SSP co-simulation scenarios of FMI 1.0, 2.0 and 3.0 Co-Simulation FMUs with fmpy.

  orchestrate build                    build the FMUs and pack ssp/<name>/ into build/ssp/<name>.ssp
  orchestrate run example1             simulate; writes results/example1.csv and .png
  orchestrate validate example1        every check before a simulation, all problems at once
  orchestrate inspect example1         components, variables (units, ranges, values), connections
  orchestrate metrics results/example1.csv   tracking metrics (RAE, MSE, RMSE, MAE, ...)
  orchestrate plot results/example1.csv      plot a result file
  orchestrate regress regression/      every scenario against its baseline (JUnit XML, HTML report)
  orchestrate compare RESULT.csv BASELINE.csv  one result against one baseline
  orchestrate baseline regression/     write baselines, review and accept their updates
  orchestrate report                   write the paper report
  eval "$(orchestrate completion bash)"     shell completion (also zsh, fish)

Run 'orchestrate COMMAND --help' for the options of a command.
"""
RUN_HELP = """\
SCENARIO is a .ssp archive, a folder holding SystemStructure.ssd, or the name of a built
scenario (build/ssp/NAME.ssp). A scenario an application's check finds stale is refused, naming
why (this project: a built scenario whose sources, ssp/NAME/, fmu_src/, controller/, changed after
the build). A scenario source folder (ssp/NAME) runs directly, with the FMUs of build/fmus/.
Start, stop time and step come from the scenario unless given; the step must divide the run. An
input no connection feeds is a warning.
Results go to results/<name>.csv (and .png), written as the run goes: a failed run keeps every
row up to the failure.

masters (the default: the one the SSD's algorithm annotation implies, libcosim's
osp:FixedStepAlgorithm jacobi, OMSimulator's oms:FixedStepMaster gauss-seidel; else gauss-seidel):
  gauss-seidel  all FMUs step, then outputs are propagated through direct-feedthrough
                components in dependency order: the controller's v at t_k uses the plant at t_k.
                An algebraic loop is iterated to a fixed point at each communication point
                (--loop-tolerance, --loop-iterations; no convergence ends the run with its residual).
  jacobi        libcosim's algorithm: every connection delays its value by one step (so a cycle of
                connections is no algebraic loop).

Faults: an FMU call that fails, a NaN or infinite value, or the --timeout end the run with one
line and the rows before the fault kept; Ctrl-C (SIGINT) or SIGTERM stop it at the next
communication point, keep every row computed and write the plot of them. The CSV is written to a
temporary file and renamed, so its name never holds a half-written file.

exit status: 0 success, 1 scenario error, simulation failure or --timeout, 2 usage error,
130 interrupted (SIGINT), 143 terminated (SIGTERM).
"""
EXIT_STATUS = """\
exit status: 0 success, 1 failure (named on one line), 2 usage error, 130 interrupted (SIGINT),
143 terminated (SIGTERM)."""
PLOT_HELP = """\
Plot a result file (.csv, .parquet or .mat, as 'run' writes them) with the figure 'run' draws:
an application's figure for the results it recognises (this project: the tracking figure), else
one panel per component; units from the result's provenance file (RESULT.json) when there is one.
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

INSPECT_HELP = """\
List what SCENARIO (as for 'run') holds, without running it: each component's FMU, FMI version
and generation tool; every input, output and parameter with type, unit, range, the FMU's start
value, the value a run applies and where it comes from (FMU, the SSD's parameter sets, a
--parameter-set file, --set); the connections; the start, stop time and step and where each comes
from. What cannot be read is listed at the end.

exit status: 0 read without problems, 1 problems listed, 2 usage error.
"""

Handler = Callable[[argparse.Namespace], int]
_quiet = threading.local()  # --quiet of the command running in this thread


class _CommandParser(argparse.ArgumentParser):
    """A subcommand's parser: its own usage, then the one line every error of orchestrate has
    (``orchestrate: error: ...``, not argparse's ``orchestrate run: error: ...``), exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(2, f"orchestrate: error: {message}\n")


class CommandOptions(TypedDict, total=False):
    """Keyword arguments of :func:`add_command`, passed on to ``add_parser``."""

    help: str
    description: str | None
    epilog: str | None
    formatter_class: type[argparse.HelpFormatter]


def add_command(subparsers: argparse._SubParsersAction, name: str, handler: Handler, *,
                quiet: bool = False, **kwargs: Unpack[CommandOptions]) -> argparse.ArgumentParser:
    """Add subcommand ``name`` run by ``handler(args) -> exit status``; returns its parser.

    A description or epilog that says nothing of the exit status gets :data:`EXIT_STATUS`.
    ``quiet``: the command takes ``-q``/``--quiet`` (no progress, no summary, no warnings: only
    errors and what the command is for; :func:`warn` and :func:`quiet` honour it).
    """
    told = " ".join(str(kwargs.get(k) or "") for k in ("description", "epilog")).lower()
    if "exit status" not in told:
        kwargs["epilog"] = f"{kwargs['epilog']}\n\n{EXIT_STATUS}" if kwargs.get("epilog") else EXIT_STATUS
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
    parser = subparsers.add_parser(name, **kwargs)
    parser.set_defaults(handler=handler, command_parser=parser)
    if quiet:
        parser.add_argument("-q", "--quiet", action="store_true",
                            help="no progress, no summary and no warnings: errors only")
    return parser


def add_output(parser: argparse.ArgumentParser, metavar: str, help: str, *, aliases: Sequence[str] = (),
               **kwargs: object) -> None:
    """The command's output as every command names it: ``-o``/``--output`` (older spellings in
    ``aliases`` are still accepted, not shown)."""
    parser.add_argument("-o", "--output", type=Path, metavar=metavar, help=help, **kwargs)  # type: ignore[arg-type]
    for alias in aliases:
        parser.add_argument(alias, dest="output", type=Path, help=argparse.SUPPRESS)


def quiet() -> bool:
    """True while a command given ``--quiet`` runs (in this thread)."""
    return bool(getattr(_quiet, "on", False))


def warn(text: str) -> None:
    """``orchestrate: warning: text`` on stderr, one line, unless the command is ``--quiet``."""
    if not quiet():
        print(f"orchestrate: warning: {' '.join(text.split())}", file=sys.stderr)


BUILTIN_COMMANDS = ("run", "validate", "inspect", "plot", "completion")
COMPLETION_HELP = """\
Print the script that makes SHELL complete orchestrate's subcommands, options, scenario names and
COMPONENT.VARIABLE names (argcomplete). Load it in the current shell, or from its start-up file:

  eval "$(orchestrate completion bash)"        # ~/.bashrc
  eval "$(orchestrate completion zsh)"         # ~/.zshrc
  orchestrate completion fish | source         # ~/.config/fish/config.fish

exit status: 0 printed, 2 usage error.
"""


def _parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line: the built-in commands, and the applications' commands (entry-point group
    ``orchestrate.commands``) unless ``command`` is a built-in one (importing the applications costs
    more than a short run)."""
    parser = argparse.ArgumentParser(prog="orchestrate", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=version_line())
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=_CommandParser)

    p = add_command(sub, "run", _run, help="simulate a scenario", description=RUN_HELP, quiet=True,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)
    p.add_argument("--start-time", type=float, metavar="T", help="start time in s (default: from the SSD)")
    p.add_argument("--stop-time", type=float, metavar="T", help="stop time in s (default: from the SSD)")
    p.add_argument("--step", type=float, metavar="H",
                   help="communication step in s (default: from the SSD); must divide the run")
    add_output(p, "FILE", "result file, format by extension: .csv, .parquet, .mat (Dymola/OpenModelica "
                          "trajectory) (default: results/<name>.csv)")
    p.add_argument("--output-variables", action="append", default=[], metavar="PATTERN",
                   help="columns to write, shell patterns such as 'plant.*' (repeatable; default: all)")
    p.add_argument("--output-interval", type=float, metavar="S",
                   help="write every row at t0 + k S only (a multiple of the step; default: every step)")
    p.add_argument("--input-file", type=Path, metavar="FILE.csv",
                   help="time series for inputs no connection feeds: 'time' then <component>.<input> columns "
                        "(FMPy's convention; continuous inputs interpolated linearly, discrete ones held)")
    p.add_argument("--no-inputs", action="store_true",
                   help="leave out input columns that only repeat the output connected to them")
    p.add_argument("--plot", type=Path, metavar="FILE.png", help="plot file (default: results/<name>.png)")
    _plot_variables(p)
    p.add_argument("--no-plot", action="store_true", help="do not plot")
    p.add_argument("--master", choices=list(MASTERS), default=None,
                   help="master algorithm (default: the one the SSD's algorithm annotation implies, else "
                        "gauss-seidel)")
    p.add_argument("--executor", choices=EXECUTORS, default="auto",
                   help="who steps the plan: the compiled executor (auto: where it can, else the Python "
                        "master, with a note), or always the Python master; the same rows bit for bit")
    p.add_argument("--allow-stale", action="store_true",
                   help="run a scenario even when an application's check finds it stale (e.g. a build older "
                        "than its sources)")
    p.add_argument("--strict", action="store_true",
                   help="refuse the scenario when an input is not connected (default: a warning)")
    p.add_argument("--verbose", action="store_true", help="show the FMUs' log messages as they come")
    p.add_argument("--fmi-log", action="append", default=[], metavar="COMPONENT",
                   help="print every FMI call of the components matching this shell pattern ('*': all) "
                        "on stderr (repeatable)")
    p.add_argument("--loop-tolerance", type=float, default=LOOP_TOLERANCE, metavar="TOL",
                   help="gauss-seidel: an algebraic loop has converged when no input on it moves by more "
                        f"than TOL relative to 1 + its size between two sweeps (default {LOOP_TOLERANCE:g})")
    p.add_argument("--loop-iterations", type=int, default=LOOP_ITERATIONS, metavar="N",
                   help=f"gauss-seidel: sweeps of an algebraic loop per communication point (default "
                        f"{LOOP_ITERATIONS})")
    p.add_argument("--timeout", type=float, metavar="SECONDS",
                   help="wall-clock limit of the run: stop at the next communication point (a step that "
                        "does not return is aborted 2 s later); exit status 1, rows kept")

    p = add_command(sub, "validate", _validate, help="check a scenario without simulating", quiet=True,
                    description=VALIDATE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)

    p = add_command(sub, "inspect", _inspect, help="list a scenario's components, variables, connections",
                    quiet=True, description=INSPECT_HELP,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    _scenario_arguments(p)

    p = add_command(sub, "plot", _plot, help="plot a result file", description=PLOT_HELP, quiet=True)
    p.add_argument("result", type=Path, metavar="RESULT.csv")
    add_output(p, "FILE.png", "image file, format by extension (default: RESULT with .png)")
    _plot_variables(p)

    p = add_command(sub, "completion", _completion, help="print the shell completion script",
                    description=COMPLETION_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("shell", choices=SHELLS, metavar="SHELL", help=f"one of {', '.join(SHELLS)}")

    if command not in BUILTIN_COMMANDS:
        for entry in entry_points(COMMAND_GROUP):
            entry.load()(sub)
    return parser


def _plot_variables(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plot-variables", action="append", default=[], metavar="PATTERN",
                   help="signals to plot, shell patterns such as 'plant.*' (repeatable; default: a figure "
                        "an application provides for the result, else every output, one panel per component)")


def _scenario_arguments(p: argparse.ArgumentParser) -> None:
    """SCENARIO, --parameter-set and --set, as 'run' and 'validate' take them."""
    p.add_argument("scenario", metavar="SCENARIO", help=".ssp file, scenario folder or built scenario name")
    p.add_argument("--parameter-set", action="append", default=[], metavar="FILE.ssv",
                   help="parameter values named COMPONENT.VARIABLE, applied after the SSD's own (repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="COMPONENT.VARIABLE=VALUE",
                   help="set one parameter or start value, applied last (repeatable)")
    p.add_argument("--root", type=Path, metavar="DIR",
                   help="a scenario folder may reference files below DIR with '..' (e.g. ../fmus/x.fmu; "
                        "never an archive)")
    p.add_argument("--strict-fmus", action="store_true",
                   help="what fmpy's checks of a model description find is an error, also where the FMU "
                        "still runs (default: a warning; for CI)")
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
                           default=default, metavar="N",
                           help=f"{what} (default {default:g})" if field in ("ratio", "members") else
                           f"{what} (default {size_text(default)})")


def size_text(size: float) -> str:
    """``1073741824`` -> ``1G``: a size in bytes as the size options take it (K, M, G: powers of 1024)."""
    for suffix, factor in (("G", 1 << 30), ("M", 1 << 20), ("K", 1 << 10)):
        if size >= factor and size % factor == 0:
            return f"{int(size) // factor}{suffix}"
    return f"{int(size)}"


def parse_overrides(items: Sequence[str], option: str = "--set") -> dict[str, str]:
    """``--set COMPONENT.VARIABLE=VALUE`` options as a mapping (values converted by the engine);
    UsageError for a malformed one, or a name given twice with different values (the last would
    win without a word)."""
    overrides: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or "." not in key:
            raise UsageError(f"{option} expects COMPONENT.VARIABLE=VALUE (got '{item}')")
        if key in overrides and overrides[key] != value:
            raise UsageError(f"{option} {key} is given twice ({overrides[key]!r} and {value!r}): "
                             "give it once")
        overrides[key] = value
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
        return version(name) or "not installed"

    return (f"orchestrate {installed('fixed-time-cosim')} (fmpy {installed('fmpy')}, "
            f"numpy {installed('numpy')}, Python {sys.version.split()[0]})")



def _interrupted(exc: KeyboardInterrupt) -> int:
    """The one line for an interruption, and its exit status. What the interruption left half made
    is not finalized aloud: a SIGTERM inside ``ZipFile.__init__`` (unpacking an SSP) left an object
    whose ``__del__`` printed 'Exception ignored ... no attribute _writing' and a traceback after
    the line (seen once in 1,637 tests)."""
    print(f"orchestrate: {_interrupt_text(exc)}", file=sys.stderr)
    sys.unraisablehook = lambda unraisable: None
    return getattr(exc, "exit_status", 130)


def _interrupt_text(exc: KeyboardInterrupt) -> str:
    """What stopped the command: our own interruptions say it; Python's plain KeyboardInterrupt is
    SIGINT, whatever its text (CPython rewrites it when it arrives inside a codec: "decoding with
    'cp437' codec failed (KeyboardInterrupt: )", seen unpacking an SSP)."""
    return "interrupted by SIGINT" if type(exc) is KeyboardInterrupt else str(exc) or "interrupted"

def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``orchestrate``; returns the exit status."""
    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:
        previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    # SIGINT, SIGTERM at any moment (while these handlers go in too): cleanup runs, one line, 130
    # or 143; an ignored one stays so
    try:
        if main_thread:
            for signum, handler in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, terminate)):
                if signal.getsignal(signum) is not signal.SIG_IGN:
                    signal.signal(signum, handler)
        words = sys.argv[1:] if argv is None else list(argv)
        parser = _parser(next((w for w in words if not w.startswith("-")), None))
        if "_ARGCOMPLETE" in os.environ:  # the shell asks for completions (docs/shell-completion.md)
            from .completion import complete

            complete(parser)
        args = parser.parse_args(words)
        _quiet.on = bool(getattr(args, "quiet", False))
        try:
            with command_line(), warnings.catch_warnings():
                warnings.showwarning = _show_warning
                warnings.simplefilter("always", OrchestratorWarning)  # each run's, deduplicated by text
                _shown_warnings.clear()
                return args.handler(args)
        except UsageError as exc:  # the command's own usage (not orchestrate's), then the one line
            command: _CommandParser = args.command_parser
            command.error(str(exc))
        except OrchestratorError as exc:
            what = "cannot write the results: " if isinstance(exc, OutputError) else ""
            print(f"orchestrate: error: {what}{exc}", file=sys.stderr)
            return exc.exit_status
        except BrokenPipeError:  # 'orchestrate inspect X | head': the reader left; no traceback
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
        finally:
            _quiet.on = False
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    finally:
        if main_thread:
            signal.signal(signal.SIGINT, previous[0])
            signal.signal(signal.SIGTERM, previous[1])


_shown_warnings: set[str] = set()


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: object = None, line: str | None = None) -> None:
    """A Python warning during a command as one line (no source file and line), each text once;
    none with --quiet."""
    text = " ".join(str(message).split())
    if text in _shown_warnings:
        return
    _shown_warnings.add(text)
    if issubclass(category, EngineNote):
        if not quiet():
            print(f"orchestrate: note: {text}", file=sys.stderr)
        return
    warn(text if issubclass(category, OrchestratorWarning) else f"{text} ({category.__name__})")


def scenario_checks(scenario: Path) -> list[str]:
    """What the applications' checks (entry-point group ``orchestrate.checks``: functions
    ``check(scenario) -> str``, '' when fine) find wrong with running ``scenario`` as it is, e.g.
    a build older than its sources (:mod:`orchestrator.experiments.builds`)."""
    found = []
    for entry in entry_points(CHECK_GROUP):
        problem = entry.load()(scenario)
        if problem:
            found.append(problem)
    return found


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
    failure is reported on one line with the FMU's own explanation. Warnings are printed as they
    come (each distinct one once, at most ``MAX_WARNINGS``; errors end up in the failure's line);
    --verbose prints every message."""

    MAX_WARNINGS = 10

    def __init__(self, verbose: bool, quiet: bool = False) -> None:
        super().__init__(logging.INFO if verbose else logging.WARNING)
        self.verbose = verbose
        self.quiet = quiet
        self.last = ""
        self.shown: set[str] = set()

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage().strip()
        if record.levelno >= logging.WARNING:
            self.last = text.splitlines()[-1] if text else ""
        if self.verbose:
            print(f"{record.name}: {record.getMessage()}", file=sys.stderr)
        elif record.levelno == logging.WARNING and text not in self.shown and not self.quiet:
            self.shown.add(text)
            if len(self.shown) <= self.MAX_WARNINGS:
                print(f"orchestrate: warning: {text}", file=sys.stderr)
            elif len(self.shown) == self.MAX_WARNINGS + 1:
                print("orchestrate: warning: more FMU warnings (--verbose shows them)", file=sys.stderr)


def _options(args: argparse.Namespace, scenario: Path, output: Path) -> RunOptions:
    """The :class:`RunOptions` of 'run' (a value out of range is a UsageError naming the field)."""
    return RunOptions(start_time=args.start_time, stop_time=args.stop_time, step=args.step,
                      parameter_sets=args.parameter_set, overrides=parse_overrides(args.set),
                      master=args.master,
                      output=output, output_variables=args.output_variables,
                      output_interval=args.output_interval, no_inputs=args.no_inputs, keep=False,
                      preview=not args.no_plot,
                      strict=args.strict, timeout=args.timeout, fmu_dirs=fmu_dirs(scenario),
                      limits=archive_limits(args), input_file=args.input_file, fmi_log=args.fmi_log,
                      root=args.root, strict_fmus=args.strict_fmus, loop_tolerance=args.loop_tolerance,
                      loop_iterations=args.loop_iterations, executor=args.executor)


def _run(args: argparse.Namespace) -> int:
    scenario = resolve_scenario(args.scenario)
    name = scenario.stem if scenario.is_file() else scenario.resolve().name
    output = args.output or Path("results") / f"{name}.csv"
    options = _options(args, scenario, output)
    stale = scenario_checks(scenario)
    if stale and not args.allow_stale:
        raise ScenarioError(stale)
    if args.no_plot and args.plot is not None:
        raise UsageError(f"--no-plot and --plot {args.plot}: choose one")
    # -o '' is Path('.'): no plot of its name (the run refuses the folder as its output)
    plot = None if args.no_plot or not (args.plot or output.name) else args.plot or output.with_suffix(".png")
    if plot is not None:
        check_plot(plot)
    progress = None if args.quiet or not sys.stderr.isatty() else _Progress(name)
    messages = _LastMessage(args.verbose, args.quiet)
    logging.getLogger().addHandler(messages)
    if args.verbose:
        logging.getLogger().setLevel(logging.INFO)
    calls = _call_log(args.fmi_log)
    try:
        result = run(scenario, options, progress=progress)  # warnings: one line each, as they come (main)
    except (SimulationError, Interrupted) as exc:
        return _stopped(exc, messages.last, output, plot, name, args)
    except KeyboardInterrupt as exc:  # outside the stepping loop (Terminated: SIGTERM), nothing kept
        return _interrupted(exc)
    except OSError as exc:  # OutputError: writing the results; else reading (a full TMPDIR, ...)
        what = "cannot write the results: " if isinstance(exc, OutputError) else ""
        print(f"orchestrate: error: {what}{exc}", file=sys.stderr)
        return 1
    finally:
        logging.getLogger().removeHandler(messages)
        CALLS.removeHandler(calls)
    if plot is not None and not _plot_result(result, plot, name, args):
        return 1
    if not args.quiet:
        extra = f" and {plot}" if plot is not None else ""
        span = f"t = {result.rows['time'][0]:g} .. {result.time:g} s"
        print(f"{name}: {_rows_text(result)}, {span} -> {output}{extra}")
    return 0


def _stopped(exc: SimulationError | Interrupted, last: str, output: Path, plot: Path | None, name: str,
             args: argparse.Namespace) -> int:
    """A run that failed or was stopped: one line saying why and where its rows are kept (the FMU's
    last message where the error does not say why), the plot of those rows; the exit status."""
    result = exc.result
    detail = f" ({last})" if last and not getattr(exc, "explained", False) else ""
    prefix = "orchestrate: " if isinstance(exc, Interrupted) else "orchestrate: error: "
    early = isinstance(exc, Interrupted) and not result.count  # while instantiating or initializing
    kept = " (before the first row)" if early else f"; {_rows_text(result)} kept in {output}"
    stopped = f"{prefix}{exc}{detail}{kept}"
    if plot is None or result.count < 2:
        print(stopped, file=sys.stderr)
        return exc.exit_status
    written = _plot_result(result, plot, name, args)
    print(f"{stopped} (plot: {plot})" if written else stopped, file=sys.stderr)
    return exc.exit_status


def _rows_text(result: RunResult) -> str:
    """``2001 rows``, or what the file holds of them: ``101 rows (every 0.05 s of 2001 computed)``."""
    written = result.provenance.get("rows")
    written = written if isinstance(written, int) else result.count
    if written == result.count:
        return f"{written} rows"
    interval = (result.provenance.get("output") or {}).get("interval")
    every = f"every {interval:g} s of " if isinstance(interval, (int, float)) else ""
    return f"{written} rows ({every}{result.count} computed)"


def _call_log(patterns: Sequence[str]) -> logging.Handler:
    """The handler that prints the traced FMI calls (``--fmi-log``) on stderr, one per line."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("fmi: %(message)s"))
    if patterns:
        CALLS.setLevel(logging.INFO)
        CALLS.propagate = False  # printed here only, also with --verbose
        CALLS.addHandler(handler)
    return handler


def _files_backend() -> None:
    """matplotlib's Agg: the command line writes image files and never opens a window."""
    import matplotlib

    matplotlib.use("Agg")


def _plot_result(result: RunResult, plot: Path, name: str, args: argparse.Namespace) -> bool:
    """Write the plot of a run; False (after one line on stderr) when it cannot be written."""
    _files_backend()
    try:
        plot_run(result.rows, plot, plot_title(name, result.provenance, result.provenance.get("master")),
                 result.units,
                 variables=args.plot_variables, record=result.provenance)
    except OSError as exc:
        kept = result.outputs.get("result", "the output file")
        print(f"orchestrate: error: cannot write the plot: {exc}; results kept in {kept}", file=sys.stderr)
        return False
    return True


def plot_title(name: str, record: dict | None, master: object = None) -> str:
    """``name (master)`` and, on a second line, the overrides and parameter sets of the run, so a
    plot of a changed run never looks like the default one."""
    title = f"{name} ({master})" if master else name
    changed = overrides_text(record)
    return f"{title}\n{changed}" if changed else title


def _validate(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    scenario = resolve_scenario(args.scenario)
    report = validate(scenario, parameter_sets=args.parameter_set, overrides=overrides,
                      fmu_dirs=fmu_dirs(scenario), limits=archive_limits(args), root=args.root,
                      strict_fmus=args.strict_fmus)
    if not args.quiet:  # --quiet: the errors only, the exit status says the rest
        for stale in scenario_checks(scenario):
            print(f"warning: {stale}")
    for problem in report.problems:
        if problem.severity == "error" or not args.quiet:
            print(problem)
    if not report.ok:
        warnings = len(report.problems) - len(report.errors)
        if not args.quiet:
            print(f"failed: {scenario}: {len(report.errors)} error(s), {warnings} warning(s)")
        return 1
    if not args.quiet:
        print(f"ok: {scenario}: {report.components} components, {report.connections} connections, "
              f"{report.parameters} parameters checked")
    return 0


def _inspect(args: argparse.Namespace) -> int:
    from .inspection import inspect_scenario  # here: a run does not need it

    scenario = resolve_scenario(args.scenario)
    report = inspect_scenario(scenario, parameter_sets=args.parameter_set,
                              overrides=parse_overrides(args.set), fmu_dirs=fmu_dirs(scenario),
                              limits=archive_limits(args), root=args.root, strict_fmus=args.strict_fmus)
    lines = [f"  {p}" for p in report.problems] if args.quiet else report.lines()  # --quiet: problems only
    if lines:
        print("\n".join(lines))
    return 1 if report.problems else 0


def _completion(args: argparse.Namespace) -> int:
    from .completion import shellcode

    print(shellcode(args.shell))
    return 0


def _plot(args: argparse.Namespace) -> int:
    _files_backend()
    data = read_result(args.result)
    target = args.output or args.result.with_suffix(".png")
    record = read_provenance(args.result)
    units = record.get("units") if record else None
    plot_run(data, target, plot_title(args.result.stem, record, record.get("master") if record else None),
             units if isinstance(units, dict) else None, variables=args.plot_variables, record=record)
    if not args.quiet:
        print(target)
    return 0
