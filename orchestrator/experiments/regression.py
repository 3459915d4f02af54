"""Regression of co-simulation results against stored baselines, with tubes.

``compare`` checks every signal of a baseline against a result on the baseline's time grid with the
tube of the FMI cross-check practice (:func:`fmpy.util.validate_signal`): a band of half-width
``max(atol, rtol * range)`` around the baseline, widened by ``dt`` seconds horizontally (the band's
min/max over neighbouring samples). ``baseline`` runs scenarios and stores their outputs, resampled
to a coarse grid, as CSV text under ``tests/baselines/``; the tolerances live beside them in
``tolerances.json`` with the measurement behind each one.

Two tolerances per signal, because of the physics of the sampled loop (1 ms zero-order hold, high
gains, ``sig(z)^(2 beta - 1)`` terms): up to the first chattering burst (``quiet_until``) nearby
trajectories contract and two correct integrators agree to 1e-8, so the tube is tight there
(``quiet_atol``); during bursts any difference, even round-off, is amplified to a bounded level
(about 5e-4 in y, several units in v), so afterwards the tube (``atol``) must be that wide.

Usage::

    orchestrate compare RESULT.csv BASELINE.csv [--plot-dir DIR]
    orchestrate baseline [--scenario NAME]...

Exit status of ``compare``: 0 every signal inside its tube, 1 regression (a signal outside its tube,
a baseline column missing from the result, or a result that does not cover the baseline's time
span), 2 usage or unreadable input.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from fmpy.util import validate_signal

from .. import files, open_system, run
from ..errors import UsageError
from ..master import time_grid
from ..results import read_result
from .scenarios import SCENARIO_DIR, all_scenarios, build_scenarios

__all__ = [
    "BASELINE_DIR",
    "BASELINE_GRID",
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
    "plot_failures",
    "read_result",
    "resample",
    "write_baseline",
    "write_baselines",
]

REPO_ROOT = Path(__file__).resolve().parents[2]
BASELINE_DIR = REPO_ROOT / "tests" / "baselines"
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
    scenarios = data.get("scenarios", {})
    if not isinstance(scenarios, Mapping) or not all(isinstance(v, Mapping) for v in scenarios.values()):
        raise RegressionError(f"{path}: 'scenarios' must map scenario names to objects of signals")
    own = {scenario: {name: _tolerance(entry, f"{path}: scenario '{scenario}', signal '{name}'")
                      for name, entry in entries.items() if name != "about"}
           for scenario, entries in scenarios.items()}
    return Tolerances(tubes, default, float(quiet_until), str(path), own)


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
def _fields(data: np.ndarray) -> tuple[str, ...]:
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

    @property
    def passed(self) -> bool:
        """True if every sample lies inside the tube."""
        return self.n_out == 0


@dataclass
class Comparison:
    """All signal checks plus the problems that fail a comparison without a tube."""

    result: str
    baseline: str
    tolerances: Tolerances
    checks: list[SignalCheck]
    missing: list[str]
    extra: list[str]
    problems: list[str]
    grid: str = ""  # where the signals were compared

    @property
    def failed(self) -> list[SignalCheck]:
        """Signals outside their tubes."""
        return [c for c in self.checks if not c.passed]

    @property
    def passed(self) -> bool:
        """No signal outside its tube, no missing column, no coverage problem."""
        return not self.failed and not self.missing and not self.problems


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


def compare(result: np.ndarray, baseline: np.ndarray, tolerances: Tolerances | None = None,
            result_name: str = "result", baseline_name: str = "baseline") -> Comparison:
    """Compare every baseline column with the result's column of the same name on the baseline's
    time grid (the result is interpolated linearly onto it)."""
    tolerances = tolerances or Tolerances()
    names = [n for n in _fields(baseline) if n != "time"]
    have = set(_fields(result))
    missing = [n for n in names if n not in have]
    extra = [n for n in _fields(result) if n != "time" and n not in set(_fields(baseline))]
    problems = []
    t_ref, t_res = baseline["time"], result["time"]
    eps = 1e-9 * max(1.0, abs(float(t_ref[-1])))
    if t_res[0] > t_ref[0] + eps or t_res[-1] < t_ref[-1] - eps:
        problems.append(f"{result_name} covers t = {t_res[0]:g} .. {t_res[-1]:g} s but {baseline_name} "
                        f"runs over t = {t_ref[0]:g} .. {t_ref[-1]:g} s (compared where both have rows)")
    at_ref, at_res, grid = _points(t_ref, t_res, eps)
    if len(at_ref) < 2:
        problems.append(f"{result_name} and {baseline_name} have fewer than two times in common")
        return Comparison(result_name, baseline_name, tolerances, [], missing, extra, problems)
    t = t_ref[at_ref]
    checks = []
    for n in names:
        if n in have:
            y_ref = np.asarray(baseline[n], dtype=float)[at_ref]
            if not np.isfinite(y_ref).all():
                problems.append(f"{baseline_name}: column '{n}' has non-finite values")
                continue
            y = result[n][at_res] if at_res is not None else np.interp(t, t_res, result[n])
            checks.append(_check(n, t, y, y_ref, tolerances.of(n), tolerances.quiet_until))
    return Comparison(result_name, baseline_name, tolerances, checks, missing, extra, problems, grid)


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
                  tolerances: Tolerances | None = None) -> Comparison:
    """``compare`` on two CSV files; tolerances default to ``tolerances.json`` beside the baseline."""
    baseline = Path(baseline)
    if tolerances is None:
        beside = baseline.parent / TOLERANCES_NAME
        tolerances = load_tolerances(beside) if beside.is_file() else Tolerances()
        tolerances = tolerances.for_scenario(baseline.stem)
    return compare(read_result(result), read_result(baseline), tolerances, str(result), str(baseline))


def format_comparison(comparison: Comparison) -> str:
    """A Markdown table of the signals outside their tubes, then what is missing; one summary line."""
    c = comparison
    lines = [f"compare {c.result} with {c.baseline} (tolerances: {c.tolerances.source})"]
    failed = c.failed
    if failed:
        lines += ["", "| signal | tube +- | first out (s) | worst at (s) | beyond tube | max abs deviation "
                  "| samples out |", "|---|---|---|---|---|---|---|"]
        for s in failed:
            quiet = "" if s.tolerance.quiet_atol is None else f" ({s.tolerance.quiet_atol:.3g} quiet)"
            lines.append(f"| {s.name} | {s.width:.3g}{quiet} | {s.first_out:.3f} | {s.worst_time:.3f} | "
                         f"{s.worst_excess:.3g} | {s.max_deviation:.3g} | {s.n_out} of {len(s.time)} |")
        lines.append("")
    for p in c.problems:
        lines.append(f"problem: {p}")
    if c.missing:
        lines.append(f"missing in {c.result}: {', '.join(c.missing)}")
    if c.extra:
        lines.append(f"not in the baseline (not compared): {', '.join(c.extra)}")
    verdict = "PASS" if c.passed else "REGRESSION"
    where = f" at {c.grid}" if c.grid else ""
    also = f"; {len(c.problems)} problem(s) above" if c.problems else ""
    lines.append(f"{verdict}: {len(c.checks) - len(failed)} of {len(c.checks) + len(c.missing)} signals "
                 f"inside their tubes{where}{also}")
    return "\n".join(lines)


def plot_failures(comparison: Comparison, folder: str | os.PathLike) -> list[Path]:
    """One PNG per signal outside its tube: baseline, result and tube, then the deviation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for s in comparison.failed:
        fig, (ax, ax_d) = plt.subplots(2, 1, sharex=True, figsize=(9, 5.5))
        ax.fill_between(s.time, s.lower, s.upper, color="tab:green", alpha=0.25, label="tube")
        ax.plot(s.time, s.reference, color="tab:green", linewidth=1, label="baseline")
        ax.plot(s.time, s.value, color="tab:blue", linewidth=1, label="result")
        out = (s.value < s.lower) | (s.value > s.upper) | ~np.isfinite(s.value)
        ax.plot(s.time[out], s.value[out], "r.", markersize=3, label="outside")
        ax.set_ylabel(s.name)
        ax.legend(loc="upper right", fontsize="small")
        ax.set_title(f"{s.name}: {s.n_out} samples outside, worst {s.worst_excess:.3g} beyond at "
                     f"t = {s.worst_time:.3f} s")
        ax_d.fill_between(s.time, s.lower - s.reference, s.upper - s.reference, color="tab:green", alpha=0.25)
        ax_d.plot(s.time, s.value - s.reference, color="tab:blue", linewidth=1)
        ax_d.set_ylabel("result - baseline")
        ax_d.set_xlabel("time (s)")
        for a in (ax, ax_d):
            a.grid(True, alpha=0.3)
        fig.tight_layout()
        path = folder / f"{s.name}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
    return written


# -- scenarios and baselines ------------------------------------------------------------------------
def output_columns(scenario: str | os.PathLike) -> list[str]:
    """Result columns of every component output (inputs are copies of outputs and are left out)."""
    with open_system(scenario) as system:
        return [f"{c.name}.{o}" for c in system.components.values() for o in c.outputs]


def write_baselines(names: Iterable[str] | None = None, dest: str | os.PathLike = BASELINE_DIR,
                    sources: str | os.PathLike = SCENARIO_DIR, grid: float = BASELINE_GRID) -> list[Path]:
    """Run each scenario over its full DefaultExperiment and write ``dest/<name>.csv`` (outputs on
    ``grid``). Each file is replaced only once its run has succeeded."""
    names = list(names) if names else all_scenarios(sources)
    written = []
    with tempfile.TemporaryDirectory(prefix="baselines-") as work:
        archives = build_scenarios(names, work, sources, fmi3=False)  # twins: FMI 2.0 baselines
        for name, archive in archives.items():
            result = run(archive).rows
            written.append(write_baseline(resample(result, grid, output_columns(archive)),
                                          Path(dest) / f"{name}.csv"))
    return written
