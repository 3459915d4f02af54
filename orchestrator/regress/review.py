# SPDX-License-Identifier: BSD-2-Clause
"""Baseline updates as a reviewer sees them: what each new run moves (by how much, beyond which
tube), one line per signal, and new baselines written only for what the user accepts.

``orchestrate baseline`` runs the scenarios and compares each new run with the baseline it would
replace; a scenario without a baseline gets one, every other baseline changes only when named
(``--accept NAME`` for the whole scenario, ``--accept NAME:SIGNAL`` for one column, ``--accept-all``),
the way BuildingsPy's regression tests and csv-compare's reports are used.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import UsageError
from ..results import read_result
from .suite import Case, Outcome
from .tubes import SignalCheck, tube_text

__all__ = ["Acceptance", "accepted", "moved", "parse_accept", "review_message", "signal_lines"]


@dataclass(frozen=True)
class Acceptance:
    """What the user accepts: whole scenarios, single signals of scenarios, or everything."""

    scenarios: frozenset[str] = frozenset()
    signals: Mapping[str, frozenset[str]] | None = None
    everything: bool = False

    def of(self, name: str) -> tuple[bool, frozenset[str]]:
        """(whole scenario accepted, signals accepted) for scenario ``name``."""
        whole = self.everything or name in self.scenarios
        return whole, (self.signals or {}).get(name, frozenset())


def parse_accept(items: Iterable[str], cases: Sequence[Case], everything: bool = False) -> Acceptance:
    """``--accept NAME`` / ``--accept NAME:SIGNAL`` options, checked against the scenarios given."""
    names = {c.name for c in cases}
    whole: set[str] = set()
    signals: dict[str, set[str]] = {}
    for item in items:
        name, sep, signal = item.partition(":")
        if name not in names:
            raise UsageError(f"--accept {item}: no scenario '{name}' among those given "
                             f"({', '.join(sorted(names))})")
        if sep and not signal:
            raise UsageError(f"--accept {item}: name a signal after ':' or accept the whole scenario")
        if sep:
            signals.setdefault(name, set()).add(signal)
        else:
            whole.add(name)
    return Acceptance(frozenset(whole), {k: frozenset(v) for k, v in signals.items()}, everything)


def moved(o: Outcome) -> bool:
    """Whether the new run differs from the baseline at all (values, signals or times)."""
    c = o.comparison
    return c is None or bool(c.missing or c.extra or c.problems) or any(s.max_deviation > 0 for s in c.checks)


def signal_lines(o: Outcome) -> list[str]:
    """One line per signal that moved (``outside its tube``, ``inside its tube``, ``new``,
    ``removed``) and one for those that did not."""
    c = o.comparison
    if c is None:
        return []
    lines = []
    width = max((len(n) for n in [*(s.name for s in c.checks), *c.missing, *c.extra]), default=0)
    for s in sorted(c.checks, key=lambda s: (s.passed, -s.severity, -s.max_deviation, s.name)):
        if s.max_deviation != 0:
            lines.append(_moved_line(s, width))
    lines += [f"  {n:<{width}}  removed (in the baseline, not in this run)" for n in c.missing]
    lines += [f"  {n:<{width}}  new (not in the baseline)" for n in c.extra]
    lines += [f"  problem: {p}" for p in c.problems]
    same = sum(s.max_deviation == 0 for s in c.checks)
    if same:
        lines.append(f"  {same} signal(s) unchanged")
    return lines


def _moved_line(s: SignalCheck, width: int) -> str:
    """:func:`signal_lines`' line of a signal that moved: by how much, inside or outside its tube."""
    where = f"max change {s.max_deviation:.3g}"
    if s.passed:
        return f"  {s.name:<{width}}  {where}, inside its tube +-{tube_text(s)}"
    return (f"  {s.name:<{width}}  {where}, outside its tube +-{tube_text(s)} from t = "
            f"{s.first_out:.3f} s ({s.n_out} of {len(s.time)} samples, worst "
            f"{s.worst_excess:.3g} beyond at t = {s.worst_time:.3f} s)")


def review_message(o: Outcome) -> str:
    """The scenario's line in a review: new, unchanged, moved inside its tubes, or beyond them."""
    c = o.comparison
    if o.candidate is None or c is None:
        return o.message
    if not moved(o):
        return f"unchanged ({len(c.checks)} signals identical)"
    count = sum(s.max_deviation > 0 for s in c.checks)
    if c.passed:
        return f"{count} of {len(c.checks)} signals moved, all inside their tubes"
    return o.message


def accepted(o: Outcome, acceptance: Acceptance) -> tuple[np.ndarray | None, str]:
    """What of ``o``'s new run is accepted into its baseline: the table to write (None: nothing)
    and what it is, in words. A scenario without a baseline always gets one. Nothing is written
    here, so that every ``--accept`` is checked before any baseline changes.

    Raises
    ------
    UsageError
        An accepted signal the run does not have, or one signal accepted from a run whose times
        differ from the baseline's.
    """
    case, candidate = o.case, o.candidate
    if candidate is None:
        return None, ""
    if not case.baseline.is_file():
        return candidate, f"written {case.baseline} (new)"
    whole, signals = acceptance.of(case.name)
    if whole:
        return (candidate, f"written {case.baseline}") if moved(o) else (None, "")
    if not signals:
        return None, ""
    merged = _merged(case, candidate, signals)
    return merged, f"written {case.baseline} ({', '.join(sorted(signals))} accepted)"


def _check_accepted(case: Case, candidate: np.ndarray, signals: frozenset[str]) -> None:
    """UsageError naming the first accepted signal the new run does not have."""
    have = set(candidate.dtype.names or ())
    unknown = sorted(signals - have)
    if unknown:
        signals_text = ", ".join(n for n in candidate.dtype.names or () if n != "time")
        raise UsageError(f"--accept {case.name}:{unknown[0]}: no signal '{unknown[0]}' in this run of "
                         f"{case.name} (signals: {signals_text})")


def _merged(case: Case, candidate: np.ndarray, signals: frozenset[str]) -> np.ndarray:
    """The baseline of ``case`` with the accepted ``signals`` taken from the new run ``candidate``;
    UsageError for a signal the run lacks or times that differ from the baseline's."""
    old = read_result(case.baseline)
    _check_accepted(case, candidate, signals)
    if len(old) != len(candidate) or not np.array_equal(old["time"], candidate["time"]):
        raise UsageError(f"--accept {case.name}:SIGNAL: the new run's times differ from those of "
                         f"{case.baseline} ({len(candidate)} rows against {len(old)}): accept the whole "
                         f"scenario (--accept {case.name})")
    names = list(old.dtype.names or ())
    names += [n for n in sorted(signals) if n not in names]
    merged = np.zeros(len(old), dtype=[(n, np.float64) for n in names])
    for n in names:
        merged[n] = candidate[n] if n in signals else old[n]
    return merged
