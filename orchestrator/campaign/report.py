# SPDX-License-Identifier: BSD-2-Clause
"""The campaign report: the figures a design asks for (``[[plots]]``) and a Markdown summary that
names the worst runs and every failure.

Plot kinds (keys of a ``[[plots]]`` entry):

* ``heatmap``: ``x``, ``y`` (parameters), ``metric``; optional ``facet`` (a column or a list of
  columns: one panel per value) and ``log`` (log colour scale). One colour scale for all panels.
  A cell shows the largest (worst) value of the runs on it; a failed run's cell is red with an x,
  a finished run whose metric is infinite (e.g. never settled) grey with an o; the legend sits
  below the panels.
* ``scatter``: ``x`` (parameter), ``metric``; optional ``facet`` (one series per value), ``log``.
* ``histogram``: ``metric``; optional ``facet``, ``bins`` (outlines, one per group).

A run that finished but whose metric is NaN has it *undefined* (e.g. the error after a fault that
comes after the horizon), which is not a failure: legends and the summary count failed, infinite
and undefined runs apart, and a panel with no value to draw says why.

Without ``[[plots]]`` every metric gets a histogram. Campaigns over several scenarios are split by
scenario as well. ``labels`` in the campaign metadata (``[labels."controller.mode"] "0" = "..."``)
name the values of a column in titles.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .table import read_table

__all__ = ["SUMMARY_NAME", "colour_norm", "outcomes", "write_report"]

SUMMARY_NAME = "summary.md"
WORST_COUNT = 5
FAILURES_LISTED = 20

Row = Mapping[str, Any]  # column -> cell: int, float, str or None, by column


def _value(row: Row, column: str) -> float:
    v = row.get(column)
    return math.nan if v is None else float(v)


def _label(meta: Mapping, column: str, value: object) -> str:
    labels = meta.get("labels", {}).get(column, {})
    key = f"{value:g}" if isinstance(value, float) else str(value)
    return labels.get(key, f"{column} = {key}" if column != "scenario" else key)


def _facets(spec: Mapping, rows: Sequence[Row], meta: Mapping) -> list[tuple[str, list[Row]]]:
    """(title, rows) per combination of the facet columns' values (and of the scenario)."""
    facet = spec.get("facet", [])
    columns = [facet] if isinstance(facet, str) else list(facet)
    if len({r["scenario"] for r in rows}) > 1 and "scenario" not in columns:
        columns.insert(0, "scenario")
    groups: dict[tuple, list[Row]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(c) for c in columns), []).append(r)
    return [
        (", ".join(_label(meta, c, v) for c, v in zip(columns, key, strict=True)), group)
        for key, group in sorted(groups.items(), key=lambda kv: tuple(str(k) for k in kv[0]))
    ]


def _file_name(spec: Mapping, index: int) -> str:
    parts = [spec["kind"], spec.get("metric", ""), spec.get("x", ""), spec.get("y", "")]
    return (
        f"{index:02d}-" + re.sub(r"[^A-Za-z0-9]+", "_", "-".join(p for p in parts if p)).strip("_") + ".png"
    )


Cells = list[tuple[float, float]]


def _heatmap_grid(
    spec: Mapping, rows: Sequence[Row]
) -> tuple[list[float], list[float], np.ndarray, Cells, Cells]:
    """(xs, ys, worst finite value per cell, failed cells, cells whose metric is infinite)."""
    x, y, metric = spec["x"], spec["y"], spec["metric"]
    xs = sorted({_value(r, x) for r in rows})
    ys = sorted({_value(r, y) for r in rows})
    grid = np.full((len(ys), len(xs)), np.nan)
    failed: Cells = []
    infinite: Cells = []
    for r in rows:
        i, j = ys.index(_value(r, y)), xs.index(_value(r, x))
        if r["status"] != "ok":
            failed.append((xs[j], ys[i]))
            continue
        v = _value(r, metric)
        if math.isinf(v):
            infinite.append((xs[j], ys[i]))
        elif not math.isnan(v) and not v <= grid[i, j]:
            grid[i, j] = v  # the worst run on this cell
    return xs, ys, grid, failed, infinite


def colour_norm(values: Sequence[float], log: bool):  # -> matplotlib Normalize
    """One colour scale for every panel of a figure, with no value on the bar that no run can have:
    a log scale over the positive finite values; a linear one from 0 when no value is negative (a
    settling time or a peak); a single value widened around itself (never below 0 if it is >= 0)."""
    from matplotlib.colors import LogNorm, Normalize

    finite = [v for v in values if math.isfinite(v)]
    positive = [v for v in finite if v > 0.0]
    if log and positive:
        low, high = min(positive), max(positive)
        return LogNorm(low, high) if high > low else LogNorm(low / 2.0, high * 2.0)
    return Normalize(*_linear_range(finite))


def _linear_range(finite: Sequence[float]) -> tuple[float, float]:
    """A linear colour scale's (low, high) over ``finite``: from 0 when none is negative, a single
    value widened around itself, (0, 1) for none."""
    if not finite:
        return 0.0, 1.0
    low, high = min(finite), max(finite)
    if low >= 0.0:
        low = 0.0
    if high <= low:
        high = low + (abs(low) if low else 1.0)
    return low, high


FAILED_COLOUR = "#d62728"
INFINITE_COLOUR = "#bbbbbb"


def _heatmap(ax, spec: Mapping, rows: Sequence[Row], norm, title: str):  # -> the mesh
    from matplotlib.patches import Rectangle

    xs, ys, grid, failed, infinite = _heatmap_grid(spec, rows)
    mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(grid), shading="nearest", cmap="viridis", norm=norm)
    dx = xs[1] - xs[0] if len(xs) > 1 else 1.0
    dy = ys[1] - ys[0] if len(ys) > 1 else 1.0
    for cells, colour, marker in ((failed, FAILED_COLOUR, "x"), (infinite, INFINITE_COLOUR, "o")):
        for cx, cy in cells:  # a filled cell with a black marker: visible on any colour of the map
            ax.add_patch(Rectangle((cx - dx / 2, cy - dy / 2), dx, dy, color=colour, lw=0))
        if cells:
            ax.plot(*zip(*cells, strict=True), marker, ls="", mfc="none", color="black", ms=4, mew=0.8)
    ax.set_xlim(xs[0] - dx / 2, xs[-1] + dx / 2)
    ax.set_ylim(ys[0] - dy / 2, ys[-1] + dy / 2)
    ax.set_xlabel(spec["x"])
    ax.set_ylabel(spec["y"])
    ax.set_title(title, fontsize="small")
    return mesh, len(failed), len(infinite)


def outcomes(rows: Sequence[Row], metric: str) -> dict[str, int]:
    """How many of ``rows`` have a finite ``metric`` (``shown``), failed or timed out (``failed``),
    finished with it infinite (``infinite``: e.g. never settled) or undefined (``undefined``: NaN,
    e.g. after a fault beyond the horizon)."""
    counts = dict.fromkeys(("shown", "failed", "infinite", "undefined"), 0)
    for r in rows:
        v = _value(r, metric)
        key = ("failed" if r["status"] != "ok" else "undefined" if math.isnan(v) else
               "infinite" if math.isinf(v) else "shown")
        counts[key] += 1
    return counts


def _not_shown(counts: Mapping[str, int]) -> str:
    """``3 failed, 40 undefined``: the runs a panel cannot draw, by why ('' when none)."""
    return ", ".join(f"{counts[k]} {k}" for k in ("failed", "infinite", "undefined") if counts[k])


def _empty_note(ax, metric: str, counts: Mapping[str, int]) -> None:
    """A panel with nothing to draw says why, in its middle."""
    why = _not_shown(counts) or "no runs"
    hint = " (an event after the horizon?)" if counts["undefined"] else ""
    ax.text(0.5, 0.5, f"no finite {metric}: {why}{hint}", ha="center", va="center", transform=ax.transAxes,
            fontsize="small", wrap=True)


def _panel_label(title: str, shown: int, counts: Mapping[str, int]) -> str:
    """A panel's legend entry: its title, how many runs it shows and why the others are not."""
    missing = _not_shown(counts)
    return f"{title or 'runs'} ({shown}" + (f" shown; {missing})" if missing else ")")


def _scatter(ax, spec: Mapping, panels: list[tuple[str, list[Row]]]) -> None:
    x, metric = spec["x"], spec["metric"]
    total = dict.fromkeys(("shown", "failed", "infinite", "undefined"), 0)
    for title, rows in panels:
        ok = [r for r in rows if r["status"] == "ok" and math.isfinite(_value(r, metric))]
        counts = outcomes(rows, metric)
        total = {k: total[k] + counts[k] for k in total}
        ax.plot(
            [_value(r, x) for r in ok],
            [_value(r, metric) for r in ok],
            ".",
            alpha=0.7,
            label=_panel_label(title, len(ok), counts),
        )
    if spec.get("log") and total["shown"]:
        ax.set_yscale("log")
    if not total["shown"]:
        _empty_note(ax, metric, total)
    ax.set_xlabel(x)
    ax.set_ylabel(metric)
    ax.legend(fontsize="x-small")


def _histogram(ax, spec: Mapping, panels: list[tuple[str, list[Row]]]) -> None:
    metric = spec["metric"]
    total = dict.fromkeys(("shown", "failed", "infinite", "undefined"), 0)
    for title, rows in panels:
        values = [_value(r, metric) for r in rows if r["status"] == "ok"]
        values = [v for v in values if math.isfinite(v)]
        counts = outcomes(rows, metric)
        total = {k: total[k] + counts[k] for k in total}
        if values:  # outlines, not filled bars: no group hides another
            ax.hist(
                values, bins=int(spec.get("bins", 30)), histtype="step", linewidth=1.5,
                label=_panel_label(title, len(values), counts),
            )
    ax.set_xlabel(metric)
    ax.set_ylabel("runs")
    if not total["shown"]:
        _empty_note(ax, metric, total)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="x-small")


def _legend_below(fig, failed: int, infinite: int, metric: str) -> None:
    """The heat maps' legend, below the panels (outside the data)."""
    from matplotlib.patches import Patch

    handles = []
    if failed:
        handles.append(Patch(color=FAILED_COLOUR, label=f"failed (x): {failed}"))
    if infinite:
        handles.append(Patch(color=INFINITE_COLOUR, label=f"{metric} infinite (o): {infinite}"))
    if handles:
        fig.legend(
            handles=handles, loc="outside lower center", ncol=len(handles), fontsize="small", frameon=False
        )


def _draw(spec: Mapping, rows: Sequence[Row], meta: Mapping, target: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = _facets(spec, rows, meta)
    if spec["kind"] == "heatmap":
        columns = min(len(panels), 2)
        lines = math.ceil(len(panels) / columns)
        fig, axes = plt.subplots(
            lines, columns, figsize=(5.2 * columns, 4.2 * lines + 0.6), squeeze=False, layout="constrained"
        )
        metric = spec["metric"]
        norm = colour_norm(
            [v for r in rows if r["status"] == "ok" for v in [_value(r, metric)]], bool(spec.get("log"))
        )
        failed = infinite = 0
        mesh = None
        for ax, (title, group) in zip(axes.flat, panels, strict=False):
            mesh, f, i = _heatmap(ax, spec, group, norm, f"{metric}: {title}" if title else metric)
            failed, infinite = failed + f, infinite + i
        for ax in list(axes.flat)[len(panels) :]:
            ax.set_visible(False)
        assert mesh is not None  # at least one panel
        fig.colorbar(mesh, ax=axes.ravel().tolist(), label=metric, shrink=0.9)
        _legend_below(fig, failed, infinite, metric)
        fig.savefig(target, dpi=100)
        plt.close(fig)
        return
    fig, ax = plt.subplots(figsize=(7, 4))
    (_scatter if spec["kind"] == "scatter" else _histogram)(ax, spec, panels)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(target, dpi=100)
    plt.close(fig)


def _fmt(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return "inf" if math.isinf(value) else "nan" if math.isnan(value) else f"{value:.4g}"
    return str(value).replace("|", "\\|")


def _worst(rows: Sequence[Row], metric: str) -> list[Row]:
    """Finished runs by ``metric``, largest first (infinite first of all)."""
    done = [r for r in rows if r["status"] == "ok" and not math.isnan(_value(r, metric))]
    return sorted(done, key=lambda r: -_value(r, metric))[:WORST_COUNT]


def _by_group(rows: Sequence[Row], meta: Mapping, metrics: Sequence[str]) -> list[str]:
    """Per group of the first plot's facet (and per scenario): counts, median and largest metric."""
    spec: Mapping[str, Any] = next((p for p in meta.get("plots", []) if p.get("facet")), {})
    panels = _facets(spec, rows, meta)
    if len(panels) < 2:
        return []
    head = "".join(f" median {m} | max {m} |" for m in metrics)
    lines = [
        "## By group",
        "",
        "| group | runs | ok | failed | timed out |" + head,
        "|---" * (5 + 2 * len(metrics)) + "|",
    ]
    lines += [_group_row(title, group, metrics) for title, group in panels]
    return lines + [""]


def _group_row(title: str, group: Sequence[Row], metrics: Sequence[str]) -> str:
    """One group's row: its counts by status, the median and largest of each metric over its
    finished runs."""
    cells = [title, str(len(group))] + [
        str(sum(r["status"] == s for r in group)) for s in ("ok", "failed", "timeout")
    ]
    for m in metrics:
        values = [_value(r, m) for r in group if r["status"] == "ok" and not math.isnan(_value(r, m))]
        cells += [_fmt(float(np.median(values))), _fmt(max(values))] if values else ["-", "-"]
    return "| " + " | ".join(cells) + " |"


def _summary(rows: Sequence[Row], meta: Mapping, figures: Sequence[tuple[str, str]], table: Path) -> str:
    params = [c for c in meta.get("columns", []) if c not in ("stop_time", "step")]
    metrics = list(meta.get("metrics", []))
    finite_metrics = _finite_metrics(rows, metrics)
    lines = _heading(rows, meta, table) + _metric_table(rows, finite_metrics)
    lines += _never_defined(rows, [m for m in metrics if m not in finite_metrics])
    worst_by = _plotted_metrics(meta, metrics) or finite_metrics[:1]
    for m in worst_by:
        lines += _worst_runs(rows, m, params)
    lines += _by_group(rows, meta, worst_by)
    lines += _failures(rows, params)
    if figures:
        lines += ["## Figures", ""] + [f"![{title}]({name})" for title, name in figures] + [""]
    return "\n".join(lines)


def _finite_metrics(rows: Sequence[Row], metrics: Sequence[str]) -> list[str]:
    """The metrics finite in at least one finished run, in order."""
    return [m for m in metrics if any(math.isfinite(_value(r, m)) for r in rows if r["status"] == "ok")]


def _plotted_metrics(meta: Mapping, metrics: Sequence[str]) -> list[str]:
    """The campaign's metrics that its plots show, in the plots' order, each once."""
    plotted = dict.fromkeys(str(p["metric"]) for p in meta.get("plots", []) if p.get("metric"))
    return [m for m in plotted if m in metrics]


def _heading(rows: Sequence[Row], meta: Mapping, table: Path) -> list[str]:
    """The summary's title, its sources and the count of runs by status."""
    status = {s: sum(r["status"] == s for r in rows) for s in ("ok", "failed", "timeout")}
    wall = sum(_value(r, "wall_time") for r in rows if math.isfinite(_value(r, "wall_time")))
    expected = meta.get("runs", len(rows))
    return [
        f"# Campaign: {meta.get('description') or Path(str(meta.get('design', table))).stem}",
        "",
        f"Design `{meta.get('design', '?')}`, scenarios "
        + ", ".join(f"`{s}`" for s in meta.get("scenarios", {}))
        + f", table `{table}`.",
        "",
        f"{len(rows)} of {expected} runs in the table: {status['ok']} ok, {status['failed']} failed, "
        f"{status['timeout']} timed out; {wall:.0f} s of run time in total.",
        "",
    ]


def _metric_table(rows: Sequence[Row], metrics: Sequence[str]) -> list[str]:
    """Min, median and max of each metric over the finished runs, with its infinite and undefined
    counts; nothing without a metric finite somewhere."""
    if not metrics:
        return []
    lines = [
        "## Metrics over the finished runs",
        "",
        "| metric | min | median | max | infinite | undefined |",
        "|---|---|---|---|---|---|",
    ]
    for m in metrics:
        values = np.array([_value(r, m) for r in rows if r["status"] == "ok"])
        undefined = int(np.isnan(values).sum())
        values = values[~np.isnan(values)]
        ok = values[np.isfinite(values)]
        lines.append(
            f"| {m} | {ok.min():.4g} | {np.median(ok):.4g} | {ok.max():.4g} | "
            f"{int(np.isinf(values).sum())} | {undefined} |"
        )
    return lines + [""]


def _never_defined(rows: Sequence[Row], candidates: Sequence[str]) -> list[str]:
    """The line naming the metrics (of ``candidates``) undefined in every finished run: not a failure."""
    finished = sum(r["status"] == "ok" for r in rows)
    never = [m for m in candidates if finished
             and all(math.isnan(_value(r, m)) for r in rows if r["status"] == "ok")]
    if not never:
        return []
    return [f"Undefined (NaN) in every one of the {finished} finished runs, not failed: "
            + ", ".join(f"`{m}`" for m in never)
            + " (a metric after an event that comes after the horizon has no value).", ""]


def _worst_runs(rows: Sequence[Row], metric: str, params: Sequence[str]) -> list[str]:
    """The table of the finished runs largest in ``metric``, with their parameters."""
    worst = _worst(rows, metric)
    if not worst:
        return []
    lines = [
        f"## Worst runs by {metric}",
        "",
        "| run | scenario | " + " | ".join(params) + f" | {metric} |",
        "|---" * (len(params) + 3) + "|",
    ]
    lines += [
        f"| {r['run']} | {r['scenario']} | "
        + " | ".join(_fmt(r.get(p)) for p in params)
        + f" | {_fmt(r.get(metric))} |"
        for r in worst
    ]
    return lines + [""]


def _failures(rows: Sequence[Row], params: Sequence[str]) -> list[str]:
    """The table of failed and timed-out runs with their reasons, the first ``FAILURES_LISTED``."""
    bad = [r for r in rows if r["status"] != "ok"]
    if not bad:
        return []
    lines = [
        f"## Failed and timed-out runs ({len(bad)})",
        "",
        "| run | scenario | " + " | ".join(params) + " | status | reason |",
        "|---" * (len(params) + 4) + "|",
    ]
    lines += [
        f"| {r['run']} | {r['scenario']} | "
        + " | ".join(_fmt(r.get(p)) for p in params)
        + f" | {r['status']} | {_fmt(r['reason'])} |"
        for r in bad[:FAILURES_LISTED]
    ]
    if len(bad) > FAILURES_LISTED:
        lines.append(f"\nand {len(bad) - FAILURES_LISTED} more (see the table).")
    return lines + [""]


def write_report(table: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Draw the design's figures from a campaign table into ``out`` and write ``out/summary.md``;
    returns the summary's path."""
    table, out = Path(table), Path(out)
    rows, meta = read_table(table)
    out.mkdir(parents=True, exist_ok=True)
    specs = list(meta.get("plots", [])) or [
        {"kind": "histogram", "metric": m}
        for m in meta.get("metrics", [])
        if any(r["status"] == "ok" and math.isfinite(_value(r, m)) for r in rows)
    ]
    figures = []
    for i, spec in enumerate(specs):
        name = _file_name(spec, i)
        if rows:
            _draw(spec, rows, meta, out / name)
            title = f"{spec['kind']} of {spec.get('metric', '')}" + (
                f" over {spec['x']}" + (f" and {spec['y']}" if spec.get("y") else "") if spec.get("x") else ""
            )
            figures.append((title, name))
    path = out / SUMMARY_NAME
    path.write_text(_summary(rows, meta, figures, table), encoding="utf-8")
    return path
