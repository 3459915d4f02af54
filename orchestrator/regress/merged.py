# SPDX-License-Identifier: BSD-2-Clause
"""The comparison of two column files on any grids, a chunk of rows at a time (issue 44).

:func:`orchestrator.regress.tubes.compare` on whole arrays compares at the baseline's times
inside the result's span (all of them, or only those the result has too when its grid is coarser),
the result interpolated there by ``np.interp``, and builds each tube with fmpy's
``validate_signal``: the padded reference resampled by ``np.interp`` onto a uniform grid of as many
points (step: the median step of the compared times), a running minimum and maximum over ``2
round(dt / h) + 1`` of them, then ``np.interp`` back onto the compared times. Every one of these
steps reads its inputs in increasing order, so here each is a forward walk over chunks
(:class:`_Walk`): a window of the sequence holding, for the next queries, the two neighbours
``np.interp`` would pick in the whole sequence, which gives the same bits. The median step is
found exactly by a few passes that narrow the range holding it. Memory: a few chunks per walk,
whatever the files' lengths; the files are read several times (from the page cache)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from functools import partial

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from ..results import Columns
from . import tubes

Chunk = tuple[np.ndarray, ...]
Points = Callable[[], Iterator[Chunk]]  # a fresh stream of (t, y_ref, y) chunks
BUCKETS = 1024  # a pass of the median's search splits the range holding it into this many


def _chunks(columns: Columns, names: Sequence[str], start: int, end: int) -> Iterator[Chunk]:
    """Rows ``start`` to ``end`` of ``columns``' ``names``, ``tubes.CHUNK`` rows at a time."""
    for a in range(start, end, tubes.CHUNK):
        yield tuple(columns.part(n, a, min(tubes.CHUNK, end - a)) for n in names)


class _Walk:
    """A forward walk over the sorted chunks ``(x, *values)`` of a sequence: for queries in increasing
    order, a window of it holding each query's neighbours as ``np.interp`` picks them in the whole
    sequence (``x[j] <= q < x[j + 1]``, the first point below the sequence, the last above it).
    Each window starts with the previous one's last point."""

    def __init__(self, chunks: Iterator[Chunk]) -> None:
        self.chunks = (c for c in chunks if len(c[0]))
        self.window: Chunk = next(self.chunks)
        self.end = False

    def serve(self, q: np.ndarray) -> int:
        """How many leading queries of ``q`` (at least one) the window now serves."""
        while True:
            m = int(np.searchsorted(q, self.window[0][-1], "left"))
            if self.end:
                return len(q)
            if m:
                return m
            following = next(self.chunks, None)
            if following is None:
                self.end = True
            else:
                self.window = tuple(np.concatenate((w[-1:], c))
                                    for w, c in zip(self.window, following, strict=True))

    def interp(self, q: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """``np.interp(q, x, v)`` over the whole sequence for each of its values ``v``, and whether
        each query is one of its x."""
        ys = [np.empty(len(q)) for _ in self.window[1:]]
        hit = np.empty(len(q), dtype=bool)
        done = 0
        while done < len(q):
            m = done + self.serve(q[done:])
            x = self.window[0]
            for y, v in zip(ys, self.window[1:], strict=True):
                y[done:m] = np.interp(q[done:m], x, v)
            k = np.searchsorted(x, q[done:m], "right") - 1
            hit[done:m] = (k >= 0) & (x[np.maximum(k, 0)] == q[done:m])
            done = m
        return ys, hit


def _points(result: Columns, baseline: Columns, name: str, rows: tuple[int, int],
            common_only: bool) -> Points:
    """The compared points of signal ``name``: the baseline's ``rows`` (those the result has too when
    ``common_only``), as chunks (t, baseline value, result value interpolated there)."""
    def stream() -> Iterator[Chunk]:
        walk = _Walk(_chunks(result, ("time", name), 0, len(result)))
        for t, y_ref in _chunks(baseline, ("time", name), *rows):
            (y,), hit = walk.interp(t)
            yield (t[hit], y_ref[hit], y[hit]) if common_only else (t, y_ref, y)
    return stream


def _part(points: Points, quiet_until: float | None, quiet: bool) -> Points:
    """The points at ``t <= quiet_until`` (``quiet``) or after it; all when ``quiet_until`` is None."""
    if quiet_until is None:
        return points

    def stream() -> Iterator[Chunk]:
        for chunk in points():
            keep = chunk[0] <= quiet_until if quiet else chunk[0] > quiet_until
            yield tuple(c[keep] for c in chunk)
    return stream


def _steps(points: Points) -> Iterator[np.ndarray]:
    """The steps between consecutive times of ``points``."""
    last = None
    for t, *_ in points():
        if len(t):
            yield np.diff(t if last is None else np.concatenate(([last], t)))
            last = t[-1]


def _kth(values: Callable[[], Iterator[np.ndarray]], k: int) -> float:
    """The ``k``-th smallest (from 0) of the streamed ``values``, exactly: each pass counts them in
    ``BUCKETS`` buckets of the range known to hold it, until that range holds one value or few."""
    low, high, below = -math.inf, math.inf, 0  # the k-th lies in [low, high]; ``below`` values lie under low

    def inside() -> Iterator[np.ndarray]:
        return (v[(v >= low) & (v <= high)] for v in values())

    while True:
        count, least, most = 0, math.inf, -math.inf
        for v in inside():
            if len(v):
                count, least, most = count + len(v), min(least, float(v.min())), max(most, float(v.max()))
        if count <= tubes.CHUNK:
            return float(np.partition(np.concatenate(list(inside())), k - below)[k - below])
        if least == most:
            return least
        low, high = least, most
        edges = np.linspace(low, high, BUCKETS + 1)
        counts = np.zeros(BUCKETS, dtype=np.int64)
        for v in inside():
            counts += np.bincount(np.minimum(np.searchsorted(edges, v, "right") - 1, BUCKETS - 1),
                                  minlength=BUCKETS)
        b = int(np.searchsorted(np.cumsum(counts), k - below, "right"))
        below += int(counts[:b].sum())
        low, high = float(edges[b]), float(np.nextafter(edges[b + 1], -math.inf)) if b < BUCKETS - 1 else high


def _median_step(points: Points, n: int) -> float:
    """``np.median(np.diff(t))`` of the ``n`` times of ``points``."""
    def steps() -> Iterator[np.ndarray]:
        return _steps(points)
    m = n - 1
    if m % 2:
        return _kth(steps, m // 2)
    return (_kth(steps, m // 2 - 1) + _kth(steps, m // 2)) / 2


def _median_steps(times: Points) -> Callable[[float | None, bool, int], float]:
    """``median_step(until, quiet, n)``: the median step of the ``n`` times of a part (``_part``) of
    ``times``, found once per part: every signal has the same times, and each search reads the
    files a few times over (8 signals of 10^6 rows: 1.1 s of 3.6 s)."""
    found: dict[tuple[float | None, bool], float] = {}

    def median_step(until: float | None, quiet: bool, n: int) -> float:
        if (until, quiet) not in found:
            found[until, quiet] = _median_step(_part(times, until, quiet), n)
        return found[until, quiet]
    return median_step


def _band(points: Points, first: tuple[float, float], last: tuple[float, float], n: int, h: float,
          shift: float) -> Iterator[Chunk]:
    """validate_signal's resampled reference (``interp1d``, which is ``np.interp`` for float64) on
    ``np.linspace`` over the padded times: chunks (t_band, y_band)."""
    def padded() -> Iterator[Chunk]:
        yield np.array([first[0] - h]), np.array([first[1] + shift])
        for t, y_ref, _ in points():
            yield t, y_ref + shift
        yield np.array([last[0] + h]), np.array([last[1] + shift])

    walk = _Walk(padded())
    num = n + 2
    start, stop = first[0] - h, last[0] + h
    step = (stop - start) / (num - 1)
    for b in range(0, num, tubes.CHUNK):
        x = np.arange(b, min(b + tubes.CHUNK, num), dtype=np.float64) * step + start
        if b + len(x) == num:
            x[-1] = stop
        yield x, walk.interp(x)[0][0]


def _running(band: Iterator[Chunk], half: int, w: float) -> Iterator[Chunk]:
    """The band's running minimum and maximum over ``2 half + 1`` points (scipy's 'reflect' at the
    ends), minus and plus ``w``: chunks (t_band, lower, upper); each computed with ``half`` points
    of the neighbouring chunks on each side."""
    size = 2 * half + 1
    t_kept, y_kept = np.empty(0), np.empty(0)  # from the band's point `kept` on
    kept = done = 0  # done: points given out
    for t, y in itertools.chain(band, [(None, None)]):
        end = t is None or y is None
        if t is not None and y is not None:
            t_kept, y_kept = np.concatenate((t_kept, t)), np.concatenate((y_kept, y))
        total = kept + len(y_kept)
        upto = total if end else total - half
        if upto <= done:
            continue
        a = max(done - half, kept)
        piece = y_kept[a - kept:]
        low = minimum_filter1d(piece, size, mode="reflect")[done - a:upto - a] - w
        high = maximum_filter1d(piece, size, mode="reflect")[done - a:upto - a] + w
        yield t_kept[done - kept:upto - kept], low, high
        done = upto
        drop = max(done - half, kept) - kept
        t_kept, y_kept, kept = t_kept[drop:], y_kept[drop:], kept + drop


class _Stats:
    """A part's count, first and last point, its reference's extremes and whether they are finite."""

    def __init__(self, points: Points) -> None:
        self.n, self.low, self.high = 0, math.inf, -math.inf
        self.first = self.last = (math.nan, math.nan)
        self.finite = True
        for t, y_ref, _ in points():
            if len(t):
                self.finite = self.finite and bool(np.isfinite(y_ref).all())
                if not self.n:
                    self.first = (float(t[0]), float(y_ref[0]))
                self.n += len(t)
                self.last = (float(t[-1]), float(y_ref[-1]))
                self.low, self.high = min(self.low, float(y_ref.min())), max(self.high, float(y_ref.max()))


def _tube_out(points: Points, stats: _Stats, width: float, dt: float, step: Callable[[], float],
              out: tubes._Out) -> None:
    """:func:`tubes._tube` of one part and the samples outside it, into ``out``; ``step``: the
    median step of the part's times."""
    if stats.n == 1:
        bounds: Iterator[Chunk] = iter([(np.array([stats.first[0]]), np.array([stats.first[1] - width]),
                                         np.array([stats.first[1] + width]))])
        shift = 0.0
    else:
        h = step()
        span = stats.high - stats.low  # of the padded reference: its ends repeated
        shift = 1.0 - stats.first[1] if span == 0.0 else 0.0
        dy = width if span == 0.0 else width / span
        band_low, band_high = math.inf, -math.inf
        for _, y in _band(points, stats.first, stats.last, stats.n, h, shift):
            band_low, band_high = min(band_low, float(y.min())), max(band_high, float(y.max()))
        if band_low == band_high:  # validate_signal's width of a flat band
            w = 0.5 if band_low == 0 else abs(band_low) * dy
        else:
            w = (band_high - band_low) * dy
        half = int(round(dt / h))
        bounds = _running(_band(points, stats.first, stats.last, stats.n, h, shift), half, w)
    walk = _Walk(bounds)
    for t, y_ref, y in points():
        if len(t):
            (lower, upper), _ = walk.interp(t)
            tubes._gather(t, y, y_ref, lower - shift, upper - shift, out)


def _check(name: str, points: Points, tol: tubes.Tolerance, quiet_until: float,
           median_step: Callable[[float | None, bool, int], float], whole: _Stats | None = None
           ) -> tubes.SignalCheck:
    """:func:`tubes._check` of one signal's points, without arrays; ``median_step(until, quiet, n)``:
    the median step of the ``n`` times of a part (every signal has the same times); ``whole``: the
    statistics of all the points, where the caller has them (one pass fewer)."""
    until = quiet_until if tol.quiet_atol is not None else None
    loud = _part(points, until, quiet=False)
    loud_stats = whole if whole is not None and until is None else _Stats(loud)
    width = max(tol.atol, tol.rtol * (loud_stats.high - loud_stats.low)) if loud_stats.n else 0.0
    parts = [(loud, width)]
    if until is not None:
        parts.insert(0, (_part(points, until, quiet=True), tol.quiet_atol or 0.0))
    out = tubes._Out()
    for part, w in parts:
        quiet = part is not loud
        stats = _Stats(part) if quiet else loud_stats
        if stats.n:
            _tube_out(part, stats, w, tol.dt, partial(median_step, until, quiet, stats.n), out)
    return tubes.SignalCheck(name, tol, width, out.n_out, out.first_out, out.worst_time,
                             out.worst_excess if out.n_out else 0.0, out.deviation, *(np.empty(0),) * 5,
                             samples=out.samples, worst_half=out.worst_half)


def _inside(columns: Columns, low: float, high: float) -> tuple[int, int]:
    """The rows of ``columns`` whose times lie in [low, high] (they are consecutive)."""
    first = last = 0
    for (t,) in _chunks(columns, ("time",), 0, len(columns)):
        first += int(np.searchsorted(t, low, "left"))
        last += int(np.searchsorted(t, high, "right"))
    return first, last


def _min_step(columns: Columns) -> float:
    """The smallest step between the times of ``columns``."""
    return min(float(s.min()) for s in _steps(lambda: _chunks(columns, ("time",), 0, len(columns))))


def _ends(columns: Columns) -> np.ndarray:
    """The first and last time of ``columns``."""
    return np.concatenate((columns.part("time", 0, 1), columns.part("time", len(columns) - 1, 1)))


def compare_merged(result: Columns, baseline: Columns, tolerances: tubes.Tolerances, result_name: str,
                   baseline_name: str, signals: Sequence[str] | None,
                   failed_arrays: bool = True) -> tubes.Comparison:
    """:func:`tubes.compare` of two column files on any grids, a chunk at a time. With
    ``failed_arrays``, a signal outside its tube is checked again on whole arrays, for plots."""
    names, missing, extra = tubes._signal_names(result, baseline, signals, baseline_name)
    required = list(signals) if signals is not None else []
    have = set(result.dtype.names or ())
    t_ref, t_res = _ends(baseline), _ends(result)
    eps = 1e-9 * max(1.0, abs(float(t_ref[-1])))
    problems = tubes._coverage_problems(any(n in have for n in names), len(names), t_res, t_ref, eps,
                                        result_name, baseline_name)
    rows = _inside(baseline, float(t_res[0]) - eps, float(t_res[-1]) + eps)
    inside = rows[1] - rows[0]
    common = sum(len(t) for t, *_ in _points(result, baseline, "time", rows, True)()) if inside else 0
    common_only = common != inside and common >= 2 and _min_step(result) > _min_step(baseline) * (1 + 1e-9)
    if common == inside:
        grid = f"the baseline's {inside} times"
    elif common_only:
        grid = f"the {common} times both have (the result's grid is coarser)"
    else:
        grid = f"the baseline's {inside} times (the result interpolated)"
    if (common if common_only else inside) < 2:
        problems.append(f"{result_name} and {baseline_name} have fewer than two times in common")
        return tubes.Comparison(result_name, baseline_name, tolerances, [], missing, extra, problems,
                                required=required)
    median_step = _median_steps(_points(result, baseline, "time", rows, common_only))
    checks = []
    for n in (n for n in names if n in have):
        points = _points(result, baseline, n, rows, common_only)
        stats = _Stats(points)
        if not stats.finite:
            problems.append(f"{baseline_name}: column '{n}' has non-finite values")
            continue
        check = _check(n, points, tolerances.of(n), tolerances.quiet_until, median_step, stats)
        if not check.passed and failed_arrays:  # its arrays, for plots
            whole = tubes.compare(tubes.structured_copy(result, ["time", n]),
                                  tubes.structured_copy(baseline, ["time", n]), tolerances, signals=[n])
            check = whole.checks[0]
        checks.append(check)
    return tubes.Comparison(result_name, baseline_name, tolerances, checks, missing, extra, problems, grid,
                            required)


def compare_columns(result: Columns | np.ndarray, baseline: Columns | np.ndarray,
                    tolerances: tubes.Tolerances, result_name: str, baseline_name: str,
                    signals: Sequence[str] | None = None,
                    failed_arrays: bool = True) -> tubes.Comparison:
    """``orchestrate compare``'s comparison: two column files a chunk at a time, on one uniform grid
    (:func:`tubes._compare_streamed`) or any grids (:func:`compare_merged`); other results (another
    tool's CSV, Parquet, MAT) on whole arrays. Signals inside their tubes keep no arrays, nor do
    those outside without ``failed_arrays`` (their figures are the same; plots need the arrays)."""
    if isinstance(result, Columns) and isinstance(baseline, Columns):
        if tubes._same_uniform_grid(result, baseline):
            return tubes._compare_streamed(result, baseline, tolerances, result_name, baseline_name, signals,
                                           failed_arrays)
        return compare_merged(result, baseline, tolerances, result_name, baseline_name, signals,
                              failed_arrays)
    return tubes.compare(result, baseline, tolerances, result_name, baseline_name, signals=signals,
                         keep_passed=False)
