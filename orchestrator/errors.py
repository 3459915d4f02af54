"""How ``orchestrate`` fails: a bad set-up, a failure while a scenario runs, or a usage mistake.

Every error derives from :class:`OrchestratorError`, whose ``exit_status`` is what the command
line returns after printing the one-line message.
"""

from __future__ import annotations

__all__ = ["OrchestratorError", "ScenarioError", "ScenarioWarning", "SimulationError", "UsageError"]


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


class SimulationError(OrchestratorError, RuntimeError):
    """An FMU call failed while the scenario ran.

    Reads ``controller: fmi2DoStep returned fmi2Error at t=10.000 s``.
    """

    STATUS_NAMES = ("fmi2OK", "fmi2Warning", "fmi2Discard", "fmi2Error", "fmi2Fatal", "fmi2Pending")

    def __init__(self, component: str, function: str, status: int | str, time: float,
                 detail: str = "") -> None:
        self.component = component
        self.function = function
        if isinstance(status, int):
            status = self.STATUS_NAMES[status] if 0 <= status < len(self.STATUS_NAMES) else f"status {status}"
        self.status = status
        self.time = time
        message = f"{component}: {function} returned {status} at t={time:.3f} s"
        if detail:
            message += f" ({detail})"
        super().__init__(message)


class ScenarioWarning(UserWarning):
    """A scenario that runs but is probably not what was meant (e.g. an input no connection feeds);
    ``run(strict=True)`` (``orchestrate run --strict``) makes it a ScenarioError."""
