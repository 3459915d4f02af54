# SPDX-License-Identifier: BSD-2-Clause
"""Tubes: every signal of a baseline checked against a result on the baseline's time grid.

The tube is that of the FMI cross-check practice (:func:`fmpy.util.validate_signal`): a band of
half-width ``max(atol, rtol * range)`` around the baseline, widened by ``dt`` seconds horizontally
(the band's min/max over neighbouring samples). The tolerances live in ``tolerances.json`` beside
the baselines, with the measurement behind each one; ``quiet_atol`` (if given) replaces a tube up
to ``quiet_until`` seconds, where a loop's trajectories still agree closely.

Why two tolerances per signal, in this project's sampled loop (1 ms zero-order hold, high gains,
``sig(z)^(2 beta - 1)`` terms): up to the first chattering burst (``quiet_until``) nearby
trajectories contract and two correct integrators agree to 1e-8, so the tube is tight there
(``quiet_atol``); during bursts any difference, even round-off, is amplified to a bounded level
(about 5e-4 in y, several units in v), so afterwards the tube (``atol``) must be that wide.

The verdict rests on the signals both files have (or on a chosen set): a baseline column missing
from the result is reported, and fails the comparison only when it was chosen (issue 36).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from fmpy.util import validate_signal
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from .. import files, open_system
from ..errors import UsageError
from ..master import time_grid
from ..results import Columns, read_result

__all__ = [
    "BASELINE_GRID",
    "TOLERANCES_NAME",
    "Comparison",
    "RegressionError",
    "SignalCheck",
    "Tolerance",
    "Tolerances",
    "compare",
    "compare_files",
    "format_comparison",
    "load_tolerances",
    "output_columns",
    "parse_tolerance",
    "resample",
    "write_baseline",
]

TOLERANCES_NAME = "tolerances.json"
BASELINE_GRID = 0.02  # s: 1501 rows per 30 s scenario; the loop's features last longer than 20 ms
DIGITS = 9  # significant digits in baselines: rounding stays far below every tube (even quiet ones)


class RegressionError(UsageError, ValueError):
    """An input of the comparison is unusable (unreadable file, no time column, bad tolerance)."""


# -- tolerances -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Tolerance:
    """Tube of one signal: half-width ``max(atol, rtol * range of the baseline)``, widened by ``dt``
    seconds in time; ``quiet_atol`` (if given) replaces it for ``t <= quiet_until``."""

    atol: float = 0.0
    rtol: float = 0.0
    dt: float = 0.0
    quiet_atol: float | None = None

    def __post_init__(self) -> None:
        for name in ("atol", "rtol", "dt", "quiet_atol"):
            value = getattr(self, name)
            valid = isinstance(value, (int, float)) and math.isfinite(value) and value >= 0
            if value is not None and not valid:
                raise RegressionError(f"tolerance {name} must be a finite number >= 0 (got {value!r})")


@dataclass(frozen=True)
class Tolerances:
    """Per-signal tubes (column name -> Tolerance), the tube of unlisted signals, and the end of
    the quiet phase in which the ``quiet_atol`` tubes apply."""

    signals: Mapping[str, Tolerance] = field(default_factory=dict)
    default: Tolerance = Tolerance(rtol=0.01)
    quiet_until: float = 0.0
    source: str = "built-in defaults"
    scenarios: Mapping[str, Mapping[str, Tolerance]] = field(default_factory=dict)

    def for_scenario(self, name: str) -> Tolerances:
        """The tubes for the baseline of scenario ``name``: its own tubes (``scenarios``) replace the
        common ones for the signals they list."""
        return replace(self, signals={**self.signals, **self.scenarios.get(name, {})})

    def of(self, name: str) -> Tolerance:
        """The tube of column ``name``."""
        return self.signals.get(name, self.default)

    def with_overrides(self, overrides: Mapping[str, Tolerance]) -> Tolerances:
        """A copy with some signals' tubes replaced."""
        return replace(self, signals={**self.signals, **overrides})


_TOLERANCE_KEYS = {"atol", "rtol", "dt", "quiet_atol"}


def _tolerance(entry: object, where: str) -> Tolerance:
    if not isinstance(entry, Mapping):
        raise RegressionError(f"{where}: expected an object with {', '.join(sorted(_TOLERANCE_KEYS))}")
    values = {k: v for k, v in entry.items() if k in _TOLERANCE_KEYS}
    unknown = set(entry) - _TOLERANCE_KEYS - {"reason"}
    if unknown:
        raise RegressionError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
    try:
        return Tolerance(**values)
    except RegressionError as exc:
        raise RegressionError(f"{where}: {exc}") from exc


def load_tolerances(path: str | os.PathLike) -> Tolerances:
    """Read a tolerance file: ``{"quiet_until": s, "default": {...}, "signals": {"plant.y": {"atol":
    ..., "quiet_atol": ..., "reason": "..."}}, "scenarios": {"pendulum": {"plant.y": {...}}}}``
    (``reason`` is for the reader; a scenario's own tubes apply to the baseline of that name)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise RegressionError(f"{path}: cannot read tolerances ({exc})") from exc
    if not isinstance(data, Mapping):
        raise RegressionError(f"{path}: expected a JSON object")
    signals = data.get("signals", {})
    if not isinstance(signals, Mapping):
        raise RegressionError(f"{path}: 'signals' must be an object")
    quiet_until = data.get("quiet_until", 0.0)
    if not isinstance(quiet_until, (int, float)) or not math.isfinite(quiet_until):
        raise RegressionError(f"{path}: quiet_until must be a number of seconds (got {quiet_until!r})")
    default = _tolerance(data["default"], f"{path}: default") if "default" in data else Tolerance(rtol=0.01)
    tubes = {name: _tolerance(entry, f"{path}: signal '{name}'") for name, entry in signals.items()}
    own = _scenario_tubes(path, data.get("scenarios", {}))
    return Tolerances(tubes, default, float(quiet_until), str(path), own)


def _scenario_tubes(path: Path, scenarios: object) -> dict[str, dict[str, Tolerance]]:
    """The tolerance file's ``scenarios``: each scenario's own tubes by signal (its ``about`` is text)."""
    if not isinstance(scenarios, Mapping) or not all(isinstance(v, Mapping) for v in scenarios.values()):
        raise RegressionError(f"{path}: 'scenarios' must map scenario names to objects of signals")
    return {scenario: {name: _tolerance(entry, f"{path}: scenario '{scenario}', signal '{name}'")
                       for name, entry in entries.items() if name != "about"}
            for scenario, entries in scenarios.items()}


def parse_tolerance(text: str, base: Tolerances) -> tuple[str, Tolerance]:
    """``plant.y=1e-3`` -> (name, a tube of exactly +-1e-3 over the whole run, tighter or wider than
    the file's), or ``plant.y=atol:1e-3,quiet_atol:1e-6`` -> the signal's tube from ``base`` with
    those keys replaced."""
    name, sep, spec = text.partition("=")
    if not sep or not name or not spec:
        raise RegressionError(f"--tol expects SIGNAL=ATOL or SIGNAL=KEY:VALUE[,KEY:VALUE] (got '{text}')")
    if ":" not in spec:
        try:
            return name, Tolerance(atol=float(spec))
        except ValueError:
            raise RegressionError(f"--tol {text}: '{spec}' is not a number") from None
    values: dict[str, float] = {}
    for item in spec.split(","):
        key, colon, value = item.partition(":")
        if not colon:
            key, value = "atol", key
        if key not in _TOLERANCE_KEYS:
            keys = ", ".join(sorted(_TOLERANCE_KEYS))
            raise RegressionError(f"--tol {text}: unknown key '{key}' (use {keys})")
        try:
            values[key] = float(value)
        except ValueError:
            raise RegressionError(f"--tol {text}: '{value}' is not a number") from None
    return name, replace(base.of(name), **values)


# -- results and baselines ----------------------------------------------------------------------
def _fields(data: np.ndarray | Columns) -> tuple[str, ...]:
    """The column names of a result or baseline (a structured array, one field per column)."""
    names = data.dtype.names
    if names is None:
        raise TypeError(f"expected a structured array with one field per column, got dtype {data.dtype}")
    return names


def resample(result: np.ndarray, grid: float, columns: Sequence[str] | None = None) -> np.ndarray:
    """The result on the grid ``t0 + k*grid`` (computed like the master's grid, so points shared
    with the result's own grid take its values exactly), keeping ``columns`` (default all)."""
    t = result["time"]
    times = time_grid(float(t[0]), float(t[-1]), grid)
    names = ["time", *[c for c in (columns or _fields(result)) if c != "time"]]
    out = np.zeros(len(times), dtype=[(n, np.float64) for n in names])
    out["time"] = times
    for n in names[1:]:
        out[n] = np.interp(times, t, result[n])
    return out


def thin(result: np.ndarray, grid: float, columns: Sequence[str] | None = None) -> np.ndarray:
    """Every k-th row of a result on a uniform grid (k: the number of steps nearest to ``grid``, at
    least 1) and its last row, keeping ``columns`` (default all), values rounded to the digits of a
    baseline file: the baseline of a run, whose times and values are the run's own rows (nothing
    interpolated, so a rerun compares exactly)."""
    t = result["time"]
    step = float(t[1] - t[0]) if len(t) > 1 else grid
    every = max(1, round(grid / step))
    rows = np.arange(0, len(t), every)
    if rows[-1] != len(t) - 1:
        rows = np.append(rows, len(t) - 1)
    names = ["time", *[c for c in (columns or _fields(result)) if c != "time"]]
    out = structured_copy(result[rows], names)
    for n in names[1:]:  # the values a baseline file holds, so that a new one compares as written
        out[n] = [float(f"{v:.{DIGITS}g}") for v in out[n].tolist()]
    return out


def structured_copy(data: np.ndarray | Columns, names: Sequence[str]) -> np.ndarray:
    """A float64 structured array of ``data``'s fields ``names`` (a new array, not a view)."""
    out = np.zeros(len(data), dtype=[(n, np.float64) for n in names])
    for n in names:
        out[n] = data[n]
    return out


def write_baseline(data: np.ndarray, path: str | os.PathLike) -> Path:
    """Write a baseline CSV readable by ``fmpy.util.read_csv``: exact time, values to 9 significant
    digits (a reviewable, stable text diff)."""
    names = _fields(data)
    lines = [",".join(names)]
    for row in data.tolist():
        lines.append(",".join([repr(row[0]), *(f"{v:.{DIGITS}g}" for v in row[1:])]))
    return files.write_text(path, "\n".join(lines) + "\n")


# -- the comparison -----------------------------------------------------------------------------
@dataclass
class SignalCheck:
    """Outcome for one signal: samples outside the tube, first time out, and the worst excess
    (distance beyond the tube) with its time; arrays kept for plots."""

    name: str
    tolerance: Tolerance
    width: float  # half-width of the tube after the quiet phase
    n_out: int
    first_out: float | None
    worst_time: float | None
    worst_excess: float
    max_deviation: float
    time: np.ndarray
    value: np.ndarray
    reference: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    samples: int = 0  # a check without arrays (streamed): the samples compared
    worst_half: float = math.nan  # ... and the tube's half-width at the worst sample

    @property
    def count(self) -> int:
        """The number of samples compared."""
        return len(self.time) or self.samples

    @property
    def passed(self) -> bool:
        """True if every sample lies inside the tube."""
        return self.n_out == 0

    @property
    def severity(self) -> float:
        """How far the worst sample lies beyond the tube, in half-widths of the tube there (0 inside;
        infinite for a non-finite value or a tube of width 0): signals of any unit ranked alike."""
        if not self.n_out or self.worst_time is None:
            return 0.0
        half = self.worst_half
        if len(self.time):
            at = int(np.searchsorted(self.time, self.worst_time))
            half = float(self.upper[at] - self.lower[at]) / 2
        return self.worst_excess / half if half > 0 else math.inf


@dataclass
class Comparison:
    """All signal checks plus what fails a comparison without a tube.

    ``missing`` lists the baseline's columns the result does not have: reported, and part of the
    verdict only for those in ``required`` (the signals chosen, or every baseline column of a
    scenario's regression). ``problems`` (a result that does not cover the baseline, non-finite
    baseline values, nothing in common) always fail.
    """

    result: str
    baseline: str
    tolerances: Tolerances
    checks: list[SignalCheck]
    missing: list[str]
    extra: list[str]
    problems: list[str]
    grid: str = ""  # where the signals were compared
    required: list[str] = field(default_factory=list)

    @property
    def failed(self) -> list[SignalCheck]:
        """Signals outside their tubes."""
        return [c for c in self.checks if not c.passed]

    @property
    def lost(self) -> list[str]:
        """Required signals the result does not have (each fails the comparison)."""
        return [n for n in self.missing if n in self.required]

    @property
    def passed(self) -> bool:
        """No signal outside its tube, no required signal missing, no coverage problem."""
        return not self.failed and not self.lost and not self.problems


def _tube(t: np.ndarray, y: np.ndarray, y_ref: np.ndarray, width: float,
          dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper tube limits at the samples ``t`` (signal and reference on the same grid),
    computed by ``fmpy.util.validate_signal``."""
    if len(t) == 1:
        return y_ref - width, y_ref + width
    h = float(np.median(np.diff(t)))
    # validate_signal skips the band's end points; one padded sample on each side covers them
    t_pad = np.concatenate(([t[0] - h], t, [t[-1] + h]))
    y_pad = np.concatenate(([y_ref[0]], y_ref, [y_ref[-1]]))
    span = float(np.ptp(y_pad))
    shift = 0.0
    if span == 0.0:  # validate_signal uses |y| * dy for a flat band (0.5 if zero): move it to 1
        shift = 1.0 - float(y_pad[0])
        dy = width
    else:
        dy = width / span
    dx = 2 * int(round(dt / h)) + 1
    t_band, y_min, y_max, _ = validate_signal(t, y + shift, t_pad.copy(), y_pad + shift,
                                              num=len(t_pad), dx=dx, dy=dy)
    return np.interp(t, t_band, y_min) - shift, np.interp(t, t_band, y_max) - shift


def _check(name: str, t: np.ndarray, y: np.ndarray, y_ref: np.ndarray, tol: Tolerance,
           quiet_until: float) -> SignalCheck:
    quiet = t <= quiet_until if tol.quiet_atol is not None else np.zeros(len(t), dtype=bool)
    lower = np.empty(len(t))
    upper = np.empty(len(t))
    width = max(tol.atol, tol.rtol * float(np.ptp(y_ref[~quiet]))) if (~quiet).any() else 0.0
    bands = [(~quiet, width)] if tol.quiet_atol is None else [(quiet, tol.quiet_atol), (~quiet, width)]
    for part, w in bands:
        if part.any():
            lower[part], upper[part] = _tube(t[part], y[part], y_ref[part], w, tol.dt)
    finite = np.isfinite(y)
    excess = np.where(finite, np.maximum(lower - y, y - upper), np.inf)
    out = excess > 0
    n_out = int(out.sum())
    worst = int(np.argmax(excess)) if n_out else None
    deviation = np.where(finite, np.abs(y - y_ref), np.inf)
    return SignalCheck(name, tol, width, n_out,
                       float(t[np.argmax(out)]) if n_out else None,
                       float(t[worst]) if worst is not None else None,
                       float(excess[worst]) if worst is not None else 0.0,
                       float(deviation.max()), t, y, y_ref, lower, upper)


def compare(result: np.ndarray | Columns, baseline: np.ndarray | Columns,
            tolerances: Tolerances | None = None,
            result_name: str = "result", baseline_name: str = "baseline", *,
            signals: Sequence[str] | None = None, keep_passed: bool = True) -> Comparison:
    """Compare baseline columns with the result's columns of the same name on the baseline's time
    grid (the result is interpolated linearly onto it where it has no row there).

    Parameters
    ----------
    result, baseline : numpy.ndarray or Columns
        Structured arrays, ``time`` first (:func:`orchestrator.results.read_result`), or files read
        a column at a time (:func:`orchestrator.results.open_columns`).
    tolerances : Tolerances, optional
        The tubes (default: 1 % of each signal's range).
    result_name, baseline_name : str
        How messages name the two.
    signals : sequence of str, optional
        The baseline columns the verdict rests on, each required of the result (a missing one
        fails). Default: every column both have; baseline columns the result lacks are listed in
        ``missing`` but do not fail.
    keep_passed : bool
        False: a signal inside its tube keeps no arrays (``time`` ... ``upper`` empty), only its
        figures, so that memory holds the failed signals' arrays alone (``orchestrate compare``
        of long files, with :func:`orchestrator.results.open_columns`).

    Returns
    -------
    Comparison
        One :class:`SignalCheck` per compared signal and what else was found.
    """
    tolerances = tolerances or Tolerances()
    if not keep_passed and isinstance(result, Columns) and isinstance(baseline, Columns) \
            and _same_uniform_grid(result, baseline):
        return _compare_streamed(result, baseline, tolerances, result_name, baseline_name, signals)
    names, missing, extra = _signal_names(result, baseline, signals, baseline_name)
    required = list(signals) if signals is not None else []
    have = set(_fields(result))
    t_ref, t_res = baseline["time"], result["time"]
    eps = 1e-9 * max(1.0, abs(float(t_ref[-1])))
    problems = _coverage_problems(any(n in have for n in names), len(names), t_res, t_ref, eps,
                                  result_name, baseline_name)
    at_ref, at_res, grid = _points(t_ref, t_res, eps)
    if len(at_ref) < 2:
        problems.append(f"{result_name} and {baseline_name} have fewer than two times in common")
        return Comparison(result_name, baseline_name, tolerances, [], missing, extra, problems,
                          required=required)
    t = t_ref[at_ref]
    checks = []
    for n in (n for n in names if n in have):
        y_ref = np.asarray(baseline[n], dtype=float)[at_ref]
        if not np.isfinite(y_ref).all():
            problems.append(f"{baseline_name}: column '{n}' has non-finite values")
            continue
        y = result[n][at_res] if at_res is not None else np.interp(t, t_res, result[n])
        checks.append(_check_column(n, y, y_ref, t, tolerances, keep_passed))
    return Comparison(result_name, baseline_name, tolerances, checks, missing, extra, problems, grid,
                      required)


def _signal_names(result: np.ndarray | Columns, baseline: np.ndarray | Columns, signals: Sequence[str] | None,
                  baseline_name: str) -> tuple[list[str], list[str], list[str]]:
    """The signals to compare (``signals``, each a baseline column, or every baseline column), the
    baseline's columns the result lacks and the result's the baseline lacks."""
    columns = [n for n in _fields(baseline) if n != "time"]
    unknown = [n for n in signals or () if n not in columns]
    if unknown:
        raise RegressionError(f"{baseline_name}: no column {', '.join(unknown)} "
                              f"(columns: {', '.join(columns)})")
    names = list(signals) if signals is not None else columns
    return (names, *_unshared(_fields(result), columns))


def _unshared(result: Sequence[str], baseline: Sequence[str]) -> tuple[list[str], list[str]]:
    """The baseline's signals the result lacks, and the result's (besides time) the baseline lacks."""
    have = set(result)
    missing = [n for n in baseline if n not in have]
    extra = [n for n in result if n != "time" and n not in set(baseline)]
    return missing, extra


def _coverage_problems(any_signal: bool, signals: int, t_res: np.ndarray, t_ref: np.ndarray, eps: float,
                       result_name: str, baseline_name: str) -> list[str]:
    """What the result lacks as a whole: every one of the ``signals`` signals (``any_signal`` False),
    part of the baseline's time span."""
    problems = []
    if not any_signal:
        problems.append(f"{result_name} has none of the {signals} signal(s) of {baseline_name}: "
                        "nothing compared")
    if t_res[0] > t_ref[0] + eps or t_res[-1] < t_ref[-1] - eps:
        problems.append(f"{result_name} covers t = {t_res[0]:g} .. {t_res[-1]:g} s but {baseline_name} "
                        f"runs over t = {t_ref[0]:g} .. {t_ref[-1]:g} s (compared where both have rows)")
    return problems


def _check_column(name: str, y: np.ndarray, y_ref: np.ndarray, t: np.ndarray, tolerances: Tolerances,
                  keep_passed: bool) -> SignalCheck:
    """The check of the result's ``y`` against the baseline's ``y_ref`` at times ``t``; without its
    arrays when it passes and ``keep_passed`` is False."""
    check = _check(name, t, y, y_ref, tolerances.of(name), tolerances.quiet_until)
    if check.passed and not keep_passed:
        none = np.empty(0)
        check = replace(check, time=none, value=none, reference=none, lower=none, upper=none)
    return check


def _signals(result: Columns, baseline: Columns, signals: Sequence[str] | None, result_name: str,
             baseline_name: str) -> tuple[list[str], set[str], list[str], list[str], list[str]]:
    """:func:`_signal_names`, the result's columns and the problem of a result with none of the
    signals (a streamed comparison's: the grids are the same, so the time span is)."""
    names, missing, extra = _signal_names(result, baseline, signals, baseline_name)
    have = set(_fields(result))
    first = result.part("time", 0, 1)  # the same times: only the first is read, for the span check
    problems = _coverage_problems(any(n in have for n in names), len(names), first, first, 0.0, result_name,
                                  baseline_name)
    return names, have, missing, extra, problems


CHUNK = 1 << 16  # rows of each array a streamed comparison holds at once


def _same_uniform_grid(result: Columns, baseline: Columns) -> bool:
    """Both files have the same times, on a uniform grid (every step within 1e-6 of the first): then
    :func:`_tube` is a running minimum and maximum, which :func:`_compare_streamed` computes a chunk
    at a time."""
    n = len(baseline)
    if len(result) != n or n < 3:
        return False
    t0, t1 = baseline.part("time", 0, 2)
    h = t1 - t0
    for start in range(0, n, CHUNK):
        t = baseline.part("time", start, CHUNK + 1)  # one row more: the step across chunks
        if not np.array_equal(t, result.part("time", start, CHUNK + 1)) or \
                not (np.abs(np.diff(t) - h) <= 1e-6 * h).all():
            return False
    return True


def _compare_streamed(result: Columns, baseline: Columns, tolerances: Tolerances, result_name: str,
                      baseline_name: str, signals: Sequence[str] | None,
                      failed_arrays: bool = True) -> Comparison:
    """:func:`compare` of two column files on the same uniform grid, ``CHUNK`` rows at a time
    (memory: a few chunks, whatever the length). With ``failed_arrays``, a signal outside its tube
    is checked again by :func:`_check` on whole arrays, for plots."""
    names, have, missing, extra, problems = _signals(result, baseline, signals, result_name, baseline_name)
    checks = []
    for name in (n for n in names if n in have):
        check = _check_streamed(name, result, baseline, tolerances.of(name), tolerances.quiet_until)
        if check is None:
            problems.append(f"{baseline_name}: column '{name}' has non-finite values")
        elif check.passed or not failed_arrays:
            checks.append(check)
        else:
            t = baseline["time"]
            checks.append(_check(name, t, result[name], baseline[name], tolerances.of(name),
                                 tolerances.quiet_until))
    return Comparison(result_name, baseline_name, tolerances, checks, missing, extra, problems,
                      f"the baseline's {len(baseline)} times", list(signals) if signals is not None else [])


def _check_streamed(name: str, result: Columns, baseline: Columns, tol: Tolerance,
                    quiet_until: float) -> SignalCheck | None:
    """:func:`_check` a chunk at a time, without arrays (None: the baseline has non-finite values).
    On a uniform grid of step h, :func:`_tube`'s band (fmpy's ``validate_signal`` on the reference
    padded with its end values, resampled onto its own grid) is the running minimum and maximum of
    the padded reference over 2 round(dt / h) + 1 samples, minus and plus the width."""
    n = len(baseline)
    quiet = 0
    low, high = math.inf, -math.inf
    for start in range(0, n, CHUNK):
        t, y_ref = baseline.part("time", start, CHUNK), baseline.part(name, start, CHUNK)
        if not np.isfinite(y_ref).all():
            return None
        if tol.quiet_atol is not None:
            quiet += int(np.count_nonzero(t <= quiet_until))
        rest = y_ref[t > quiet_until] if tol.quiet_atol is not None else y_ref
        if len(rest):
            low, high = min(low, float(rest.min())), max(high, float(rest.max()))
    width = max(tol.atol, tol.rtol * (high - low)) if quiet < n else 0.0
    t0, t1 = baseline.part("time", 0, 2)
    half = int(round(tol.dt / (t1 - t0)))
    stats = _Out()
    for first, end, w in ((0, quiet, tol.quiet_atol or 0.0), (quiet, n, width)):
        if end > first:
            _band_out(result, baseline, name, first, end, w, half, stats)
    return SignalCheck(name, tol, width, stats.n_out, stats.first_out, stats.worst_time,
                       stats.worst_excess if stats.n_out else 0.0, stats.deviation, *(np.empty(0),) * 5,
                       samples=stats.samples, worst_half=stats.worst_half)


@dataclass
class _Out:
    """What a streamed check gathers: samples out, the first time out, the worst excess (the first
    of equal ones), its time and the tube's half-width there, the largest deviation, the samples."""

    n_out: int = 0
    first_out: float | None = None
    worst_time: float | None = None
    worst_excess: float = -math.inf
    deviation: float = 0.0
    worst_half: float = math.nan
    samples: int = 0


def _band_out(result: Columns, baseline: Columns, name: str, first: int, end: int, width: float,
              half: int, out: _Out) -> None:
    """Samples ``first`` to ``end`` (one band) against the tube of half-width ``width``: the padded
    reference (its end values once more on each side, as :func:`_tube` pads it) filtered in chunks
    with ``half`` samples of overlap on each side ('reflect' at the padded ends, as scipy there)."""
    m = end - first
    for a in range(0, m, CHUNK):
        b = min(a + CHUNK, m)
        t = baseline.part("time", first + a, b - a)
        y, y_ref = result.part(name, first + a, b - a), baseline.part(name, first + a, b - a)
        if m == 1:
            lower, upper = y_ref - width, y_ref + width
        else:
            lo, hi = max(0, a + 1 - half), min(m + 2, b + 1 + half)  # padded indices p = sample + 1
            inner = baseline.part(name, first + max(lo - 1, 0), min(hi - 1, m) - max(lo - 1, 0))
            padded = np.concatenate((inner[:1] if lo == 0 else inner[:0], inner,
                                     inner[-1:] if hi == m + 2 else inner[:0]))
            size = 2 * half + 1
            lower = minimum_filter1d(padded, size, mode="reflect")[a + 1 - lo:b + 1 - lo] - width
            upper = maximum_filter1d(padded, size, mode="reflect")[a + 1 - lo:b + 1 - lo] + width
        _gather(t, y, y_ref, lower, upper, out)


def _gather(t: np.ndarray, y: np.ndarray, y_ref: np.ndarray, lower: np.ndarray, upper: np.ndarray,
            out: _Out) -> None:
    """The samples of one chunk outside their tube (``lower`` to ``upper``), and its largest
    deviation, into ``out`` (the chunks in time order)."""
    finite = np.isfinite(y)
    excess = np.where(finite, np.maximum(lower - y, y - upper), np.inf)
    outside = excess > 0
    count = int(np.count_nonzero(outside))
    if count:
        if out.first_out is None:
            out.first_out = float(t[np.argmax(outside)])
        worst = int(np.argmax(excess))
        if excess[worst] > out.worst_excess:
            out.worst_excess, out.worst_time = float(excess[worst]), float(t[worst])
            out.worst_half = float(upper[worst] - lower[worst]) / 2
        out.n_out += count
    out.samples += len(t)
    deviation = np.where(finite, np.abs(y - y_ref), np.inf)
    out.deviation = max(out.deviation, float(deviation.max()))


def _points(t_ref: np.ndarray, t_res: np.ndarray,
            eps: float) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Where to compare: the baseline's times within the result's span, the result's own rows there
    when it has a row at each (else None: it is interpolated linearly), and a note on the grid. A
    result on a coarser grid than the baseline (``--output-interval``) is compared at its own
    rows where the baseline has one too, not interpolated between them."""
    inside = np.flatnonzero((t_ref >= t_res[0] - eps) & (t_ref <= t_res[-1] + eps))
    common, at_ref, at_res = np.intersect1d(t_ref[inside], t_res, return_indices=True)
    if len(common) == len(inside):
        return inside, at_res, f"the baseline's {len(inside)} times"
    coarser = len(common) >= 2 and float(np.min(np.diff(t_res))) > float(np.min(np.diff(t_ref))) * (1 + 1e-9)
    if coarser:
        return inside[at_ref], at_res, f"the {len(common)} times both have (the result's grid is coarser)"
    return inside, None, f"the baseline's {len(inside)} times (the result interpolated)"


def compare_files(result: str | os.PathLike, baseline: str | os.PathLike,
                  tolerances: Tolerances | None = None, *,
                  signals: Sequence[str] | None = None) -> Comparison:
    """:func:`compare` on two result files; tolerances default to ``tolerances.json`` beside the
    baseline (with the tubes of the scenario named as the baseline's file)."""
    baseline = Path(baseline)
    if tolerances is None:
        tolerances = tolerances_beside(baseline)
    return compare(read_result(result), read_result(baseline), tolerances, str(result), str(baseline),
                   signals=signals)


def tolerances_beside(baseline: str | os.PathLike) -> Tolerances:
    """The tubes of baseline ``DIR/NAME.csv``: ``DIR/tolerances.json`` with scenario NAME's own
    tubes (built-in defaults, 1 % of each signal's range, where there is no such file)."""
    baseline = Path(baseline)
    beside = baseline.parent / TOLERANCES_NAME
    tolerances = load_tolerances(beside) if beside.is_file() else Tolerances()
    return tolerances.for_scenario(baseline.stem)


def tube_text(check: SignalCheck) -> str:
    """The tube of a check as the tables print it: ``0.001`` or ``0.001 (1e-06 quiet)``."""
    quiet = "" if check.tolerance.quiet_atol is None else f" ({check.tolerance.quiet_atol:.3g} quiet)"
    return f"{check.width:.3g}{quiet}"


def _failed_table(failed: Sequence[SignalCheck]) -> list[str]:
    """The Markdown table of the signals outside their tubes, the worst first (none: no lines)."""
    if not failed:
        return []
    lines = ["", "| signal | tube +- | first out (s) | worst at (s) | beyond tube | max abs deviation "
             "| samples out |", "|---|---|---|---|---|---|---|"]
    for s in sorted(failed, key=lambda s: -s.severity):
        lines.append(f"| {s.name} | {tube_text(s)} | {s.first_out:.3f} | {s.worst_time:.3f} | "
                     f"{s.worst_excess:.3g} | {s.max_deviation:.3g} | {s.n_out} of {s.count} |")
    return lines + [""]


def format_comparison(comparison: Comparison) -> str:
    """A Markdown table of the signals outside their tubes, then what is missing; one summary line."""
    c = comparison
    lines = [f"compare {c.result} with {c.baseline} (tolerances: {c.tolerances.source})"]
    failed = c.failed
    lines += _failed_table(failed)
    for p in c.problems:
        lines.append(f"problem: {p}")
    if c.lost:
        lines.append(f"missing in {c.result} (required): {', '.join(c.lost)}")
    skipped = [n for n in c.missing if n not in c.required]
    if skipped:
        lines.append(f"missing in {c.result} (not compared): {', '.join(skipped)}")
    if c.extra:
        lines.append(f"not in the baseline (not compared): {', '.join(c.extra)}")
    verdict = "PASS" if c.passed else "REGRESSION"
    where = f" at {c.grid}" if c.grid else ""
    also = f"; {len(c.problems)} problem(s) above" if c.problems else ""
    lost = f", {len(c.lost)} required signal(s) missing" if c.lost else ""
    lines.append(f"{verdict}: {len(c.checks) - len(failed)} of {len(c.checks)} signals inside their tubes"
                 f"{lost}{where}{also}")
    return "\n".join(lines)


# -- scenarios and baselines ------------------------------------------------------------------------
def output_columns(scenario: str | os.PathLike, fmu_dirs: Sequence[str | os.PathLike] = ()) -> list[str]:
    """Result columns of every component output (inputs are copies of outputs and are left out);
    ``fmu_dirs`` as for :func:`orchestrator.open_system`."""
    with open_system(scenario, fmu_dirs=fmu_dirs) as system:
        return [f"{c.name}.{o}" for c in system.components.values() for o in c.outputs]
