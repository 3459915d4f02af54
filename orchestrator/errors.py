# SPDX-License-Identifier: BSD-2-Clause
"""How ``orchestrate`` fails: a bad set-up, a failure while a scenario runs, or a usage mistake.

Every error derives from :class:`OrchestratorError`, whose ``exit_status`` is what the command
line returns after printing the one-line message.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

__all__ = ["FLAGS", "CacheWarning", "EngineNote", "Interrupted", "LoopError", "NonFiniteError",
           "OrchestratorError",
           "OrchestratorWarning", "OutputError", "ScenarioError", "ScenarioWarning", "SimulationError",
           "Terminated", "TimeLimitError", "UnpackError", "UsageError", "command_line", "is_option", "option",
           "terminate"]

# The option of ``orchestrate`` that sets each field of RunOptions (and of the other API calls): a
# message names the field to a caller of the Python API, the option to a user of the command line.
FLAGS = {"overrides": "--set", "parameter_sets": "--parameter-set", "start_time": "--start-time",
         "stop_time": "--stop-time", "step": "--step", "output": "--output",
         "output_variables": "--output-variables", "output_interval": "--output-interval",
         "input_file": "--input-file", "fmi_log": "--fmi-log", "timeout": "--timeout", "master": "--master",
         "plot": "--plot", "variables": "--plot-variables", "no_inputs": "--no-inputs",
         "executor": "--executor", "scheduler": "--scheduler", "dashboard": "--dashboard", "out": "--output",
         "workers": "--workers"}
_COMMAND_LINE: ContextVar[bool] = ContextVar("orchestrate_command_line", default=False)


def option(field: str) -> str:
    """How a message names ``field`` (a RunOptions field): ``output_variables`` to the Python API,
    ``--output-variables`` within :func:`command_line`."""
    return FLAGS.get(field, field) if _COMMAND_LINE.get() else field


def is_option(name: str) -> bool:
    """True when ``name`` is what :func:`option` gives for one of the fields."""
    return name in FLAGS or name in FLAGS.values()


@contextmanager
def command_line() -> Iterator[None]:
    """Within this block, messages name command-line options (``orchestrate``), not API fields."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


class OrchestratorError(Exception):
    """Base of every error the engine and its applications report as one line."""

    exit_status = 1


class UsageError(OrchestratorError):
    """The command was called wrongly (an option out of range, a file that is not a result)."""

    exit_status = 2


class ScenarioError(OrchestratorError, ValueError):
    """The scenario (archive, SSD, SSV, FMU interface) is unusable; nothing was simulated.

    ``problems`` lists every problem found, so one run reports them all at once.
    """

    def __init__(self, problems: str | list[str]) -> None:
        self.problems = [problems] if isinstance(problems, str) else list(problems)
        if len(self.problems) == 1:
            message = self.problems[0]
        else:
            message = f"{len(self.problems)} problems:\n" + "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(message)


class OutputError(OrchestratorError, OSError):
    """The results cannot be written (a full disk, a folder that is not writable); the message names
    the file. Distinct from an OSError of reading, which names what could not be read."""


class UnpackError(OrchestratorError, OSError):
    """An FMU cannot be unpacked for lack of space or permission, neither into the FMU cache nor
    into the run's own folder; the message names the FMU, the folder and the reason."""


class SimulationError(OrchestratorError, RuntimeError):
    """An FMU call failed while the scenario ran.

    Reads ``controller: fmi2DoStep returned fmi2Error at t=10.000 s``. Raised by
    :func:`orchestrator.run`, it carries the :class:`~orchestrator.result.RunResult` of the rows
    kept in ``result`` (raised by a bare master: their number ``rows`` and the array ``result``).
    """

    rows: int = 0
    result: Any = None
    detail: str = ""  # the FMU's own explanation (its last warning or error logged), '' when none

    STATUS_NAMES = ("fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending")

    def __init__(self, component: str, function: str, status: int | str, time: float,
                 detail: str = "") -> None:
        self.component = component
        self.function = function
        if isinstance(status, int):
            status = self.STATUS_NAMES[status] if 0 <= status < len(self.STATUS_NAMES) else f"status {status}"
        self.status = status
        self.time = time
        self.detail = detail
        message = f"{component}: {function} returned {status} at t={time:.3f} s"
        if detail:
            message += f" ({detail})"
        super().__init__(message)

    @property
    def explained(self) -> bool:
        """Whether the message says why already (the FMU's explanation, or the error's own): a
        caller adds what else it knows (a message the FMU logged elsewhere) only when it does not."""
        return bool(self.detail)


class NonFiniteError(SimulationError):
    """A value that is not finite (NaN, infinity) appeared in a row: the run stops there, and the
    rows before it are kept. Reads ``plant: output 'y' is nan at t=0.050 s``."""

    def __init__(self, component: str, variable: str, kind: str, value: float, time: float) -> None:
        RuntimeError.__init__(self, f"{component}: {kind} '{variable}' is {value!r} at t={time:.3f} s "
                                    "(not finite; the run stops at the first such value)")
        self.component, self.function, self.status, self.time = component, "fmi2GetReal", repr(value), time
        self.variable = variable

    @property
    def explained(self) -> bool:
        """The value and where it appeared are the explanation."""
        return True


class LoopError(SimulationError):
    """An algebraic loop did not converge at a communication point under gauss-seidel: the inputs on
    the loop still changed by more than the tolerance after the iteration limit. Reads
    ``algebraic loop through a, b did not converge at t=0.010 s: residual 3.2e-05 after 50
    iterations (--loop-tolerance 1e-10, --loop-iterations 50; or --master jacobi)``."""

    def __init__(self, components: list[str], time: float, residual: float, iterations: int,
                 tolerance: float) -> None:
        RuntimeError.__init__(self, f"algebraic loop through {', '.join(components)} did not converge at "
                                    f"t={time:.3f} s: residual {residual:.3g} after {iterations} iterations "
                                    f"(--loop-tolerance {tolerance:g}, --loop-iterations {iterations}; or "
                                    "--master jacobi)")
        self.component, self.function, self.status, self.time = components[0], "fixed point", "diverged", time
        self.residual = residual

    @property
    def explained(self) -> bool:
        """The residual and the limits are the explanation."""
        return True


class TimeLimitError(SimulationError):
    """The run reached its wall-clock limit (``--timeout``): stopped at the next communication point,
    or, when the step under way did not return within a grace period, that step was aborted."""

    def __init__(self, limit: float, time: float, component: str = "", grace: float = 0.0) -> None:
        if component:
            message = (f"{component}: fmi2DoStep did not return within {limit:g} s + {grace:g} s "
                       f"({option('timeout')}) at t={time:.3f} s; step aborted")
        else:
            message = f"wall-clock limit of {limit:g} s ({option('timeout')}) reached at t={time:.3f} s"
        RuntimeError.__init__(self, message)
        self.component, self.function, self.status, self.time = component, "fmi2DoStep", "timeout", time

    @property
    def explained(self) -> bool:
        """The limit is the explanation."""
        return True


class Interrupted(KeyboardInterrupt):
    """SIGINT (Ctrl-C) or SIGTERM stopped the run at a communication point; the rows computed are
    kept (``result`` as for SimulationError). ``exit_status`` is 128 + the signal number
    (130, 143), as a shell reports it."""

    rows: int = 0
    result: Any = None

    def __init__(self, signal_name: str, signal_number: int, time: float) -> None:
        super().__init__(f"interrupted by {signal_name} at t={time:.3f} s")
        self.signal_name, self.time = signal_name, time
        self.exit_status = 128 + signal_number


class Terminated(KeyboardInterrupt):
    """SIGTERM outside a run's stepping loop (reading the scenario, plotting, a campaign ...), raised
    by :func:`terminate`, so that cleanup runs as for Ctrl-C; ``exit_status`` 143."""

    exit_status = 143

    def __init__(self) -> None:
        super().__init__("terminated by SIGTERM")


def terminate(signum: int, frame: object) -> None:
    """SIGTERM handler of ``orchestrate``: raise :class:`Terminated` (the masters take it over while
    they step, as they do the default one)."""
    raise Terminated


class OrchestratorWarning(UserWarning):
    """Base of the warnings ``orchestrate`` prints as one line (``orchestrate: warning: ...``)."""


class CacheWarning(OrchestratorWarning):
    """The FMU cache could not be used (a full disk, a damaged entry): the run went on, unpacking
    the FMU into its own folder or again into the cache; the message says which and why."""


class ScenarioWarning(OrchestratorWarning):
    """A scenario that runs but is probably not what was meant (e.g. an input no connection feeds);
    ``run(strict=True)`` (``orchestrate run --strict``) makes it a ScenarioError."""


class EngineNote(UserWarning):
    """How the engine runs a scenario when that is not the default (the Python master instead of the
    compiled executor, and why); informative, never a problem of the scenario."""
