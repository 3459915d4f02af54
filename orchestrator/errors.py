"""The two ways a co-simulation can fail: a bad set-up, or a failure while it runs."""

from __future__ import annotations

__all__ = ["ScenarioError", "SimulationError"]


class ScenarioError(ValueError):
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


class SimulationError(RuntimeError):
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
