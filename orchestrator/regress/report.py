# SPDX-License-Identifier: BSD-2-Clause
"""The HTML report of a regression suite or of a baseline review: one self-contained file (figures
inline as PNG data, no file or network fetched) that a reviewer opens from a CI artifact.

A summary table (one row per scenario, linked to its section), then per scenario what failed and
a table of every signal, and per signal outside its tube the baseline, the tube and the result
plotted (linked from the tables, each linking back). A check box hides the scenarios that passed.
"""

from __future__ import annotations

import base64
import html
import os
import re
from collections.abc import Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path

from .. import files
from ..cli import version_line
from .figures import signal_png
from .suite import ERROR, FAIL, LABELS, NOT_RUN, PASS, Outcome
from .tubes import Comparison, SignalCheck, tube_text

__all__ = ["REPORT_NAME", "write_report"]

REPORT_NAME = "index.html"
MAX_FIGURES = 12  # per scenario: the worst signals are drawn, the rest listed
MAX_REPORT_FIGURES = 120  # in the whole report (about 6 MB): a bounded file however many scenarios fail

STYLE = """
body { font-family: "Liberation Sans", Arial, sans-serif; margin: 1.5em auto; max-width: 68em; color: #222;
       padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; margin-top: 2em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f2f2f2; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.badge { display: inline-block; padding: 0.1em 0.6em; border-radius: 0.3em; color: #fff; font-weight: bold;
         font-size: 0.85em; }
.pass .badge, .badge.pass { background: #2e7d32; }
.fail .badge, .badge.fail { background: #c62828; }
.error .badge, .badge.error { background: #6a1b9a; }
.notrun .badge, .badge.notrun { background: #757575; }
tr.out td { background: #fdecea; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
.meta { color: #555; font-size: 0.9em; }
pre { background: #f7f7f7; padding: 0.6em; overflow-x: auto; font-size: 0.85em; }
body.only-failing .pass { display: none; }
"""

SCRIPT = """
document.getElementById("only-failing").addEventListener("change", function (event) {
  document.body.classList.toggle("only-failing", event.target.checked);
});
"""

_CLASSES = {PASS: "pass", FAIL: "fail", ERROR: "error", NOT_RUN: "notrun"}


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


class _Ids:
    """Unique, valid HTML ids from scenario and signal names."""

    def __init__(self) -> None:
        self.used: set[str] = set()
        self.ids: dict[tuple[str, ...], str] = {}

    def __call__(self, *key: str) -> str:
        if key not in self.ids:
            base = re.sub(r"[^A-Za-z0-9_.-]", "_", "-".join(key)) or "x"
            candidate, n = base, 1
            while candidate in self.used:
                n += 1
                candidate = f"{base}-{n}"
            self.used.add(candidate)
            self.ids[key] = candidate
        return self.ids[key]


def _signal_rows(o: Outcome, ids: _Ids, drawn: set[str]) -> list[str]:
    c = o.comparison
    assert c is not None
    rows = []
    for s in sorted(c.checks, key=lambda s: (s.passed, -s.severity, s.name)):
        name = (f'<a href="#{ids(o.case.name, s.name)}">{_e(s.name)}</a>' if s.name in drawn else _e(s.name))
        first = f"{s.first_out:.3f}" if s.first_out is not None else ""
        worst = f"{s.worst_excess:.3g} at {s.worst_time:.3f} s" if s.worst_time is not None else ""
        cells = [_e(tube_text(s)), f"{s.max_deviation:.3g}", first, _e(worst), f"{s.n_out} of {len(s.time)}"]
        rows.append(f'<tr class="{"in" if s.passed else "out"}"><td>{name}</td>'
                    + "".join(f'<td class="num">{cell}</td>' for cell in cells) + "</tr>")
    for n in c.lost:
        rows.append(f'<tr class="out"><td>{_e(n)}</td><td colspan="5">missing from the run</td></tr>')
    return rows


def _figure(o: Outcome, s: SignalCheck, ids: _Ids, label: str) -> str:
    data = base64.b64encode(signal_png(s, label)).decode("ascii")
    caption = (f"{_e(o.case.name)}: {_e(s.name)}, tube &plusmn;{_e(tube_text(s))}; {s.n_out} of "
               f"{len(s.time)} samples outside from t = {s.first_out:.3f} s, worst {s.worst_excess:.3g} "
               f"beyond at t = {s.worst_time:.3f} s")
    return (f'<figure id="{ids(o.case.name, s.name)}">'
            f'<img alt="{_e(s.name)}: baseline, tube and {_e(label)}" src="data:image/png;base64,{data}">'
            f'<figcaption>{caption} &middot; <a href="#{ids(o.case.name)}">{_e(o.case.name)}</a> &middot; '
            f'<a href="#summary">summary</a></figcaption></figure>')


def _section(o: Outcome, ids: _Ids, label: str, labels: Mapping[str, str], budget: list[int]) -> str:
    cls = _CLASSES[o.status]
    parts = [f'<section class="scenario {cls}" id="{ids(o.case.name)}">',
             f'<h2>{_e(o.case.name)} <span class="badge">{labels[o.status]}</span></h2>',
             f'<p>{_e(o.message)}</p>',
             f'<p class="meta">scenario {_e(o.case.scenario)} &middot; baseline {_e(o.case.baseline)}'
             f'{" &middot; " + _e(f"{o.seconds:.1f} s") if o.status != NOT_RUN else ""}</p>']
    if o.comparison is not None:
        parts += _comparison_parts(o, o.comparison, ids, label, budget)
    if o.detail:
        parts.append(f"<pre>{_e(o.detail)}</pre>")
    if o.warnings:
        parts.append("<p>warnings:</p><ul>" + "".join(f"<li>{_e(w)}</li>" for w in o.warnings) + "</ul>")
    parts.append('<p><a href="#summary">back to the summary</a></p></section>')
    return "\n".join(parts)


def _comparison_parts(o: Outcome, c: Comparison, ids: _Ids, label: str, budget: list[int]) -> list[str]:
    """A scenario section's comparison: the signals' table, notes on what was not compared, and a
    figure per signal outside its tube while the report's ``budget`` of figures lasts."""
    parts = [f'<p class="meta">tolerances: {_e(c.tolerances.source)}; compared at {_e(c.grid)}</p>']
    failed = sorted(c.failed, key=lambda s: -s.severity)
    shown = min(MAX_FIGURES, budget[0], len(failed))
    budget[0] -= shown
    drawn = {s.name for s in failed[:shown]}
    heads = ["signal", "tube &plusmn;", "max |deviation|", "first out (s)", "worst beyond tube",
             "samples out"]
    parts += ['<table class="signals"><thead><tr>' + "".join(f"<th>{h}</th>" for h in heads)
              + "</tr></thead><tbody>", *_signal_rows(o, ids, drawn), "</tbody></table>"]
    notes = [*c.problems]
    skipped = [n for n in c.missing if n not in c.required]
    if skipped:
        notes.append(f"not in the run (not compared): {', '.join(skipped)}")
    if c.extra:
        notes.append(f"not in the baseline (not compared): {', '.join(c.extra)}")
    if len(failed) > shown:
        notes.append(f"{len(failed) - shown} more signals outside their tubes are listed, not drawn "
                     f"(at most {MAX_FIGURES} figures a scenario, {MAX_REPORT_FIGURES} a report)")
    parts += [f"<p>{_e(n)}</p>" for n in notes]
    return parts + [_figure(o, s, ids, label) for s in failed[:shown]]


def _summary_row(o: Outcome, ids: _Ids, labels: Mapping[str, str]) -> str:
    c = o.comparison
    signals = f"{len(c.checks) - len(c.failed)} of {len(c.checks)}" if c is not None else ""
    worst = ""
    if c is not None and c.failed:
        s = max(c.failed, key=lambda s: s.severity)
        worst = (f'<a href="#{ids(o.case.name, s.name)}">{_e(s.name)}</a>: {s.worst_excess:.3g} beyond '
                 f'at t = {s.worst_time:.3f} s')
    took = f"{o.seconds:.1f}" if o.status != NOT_RUN else ""
    return (f'<tr class="{_CLASSES[o.status]}"><td><a href="#{ids(o.case.name)}">{_e(o.case.name)}</a></td>'
            f'<td><span class="badge">{labels[o.status]}</span></td><td class="num">{signals}</td>'
            f'<td>{worst or _e(o.message if o.status != PASS else "")}</td><td class="num">{took}</td></tr>')


def report_html(outcomes: Sequence[Outcome], title: str, heading: str, label: str = "result",
                labels: Mapping[str, str] = LABELS) -> str:
    """The report as a string: ``title`` for the window, ``heading`` the one-line verdict,
    ``label`` what the compared runs are called in the figures (``result``, ``new run``),
    ``labels`` the badge of each status (those of the terminal, or a review's ``CHANGED``)."""
    ids = _Ids()
    ids("summary")
    failing = sum(o.status != PASS for o in outcomes)
    cls = "pass" if not failing else "fail"
    verdict = labels[PASS if not failing else FAIL]
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    rows = "\n".join(_summary_row(o, ids, labels) for o in outcomes)
    budget = [MAX_REPORT_FIGURES]
    sections = "\n".join(_section(o, ids, label, labels, budget) for o in outcomes)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_e(title)}</title>
<link rel="icon" href="data:,">
<style>{STYLE}</style>
</head>
<body>
<h1 id="summary" class="{cls}">{_e(title)} <span class="badge">{verdict}</span></h1>
<p>{_e(heading)}</p>
<p class="meta">{_e(version_line())} &middot; {when}</p>
<p><label><input type="checkbox" id="only-failing"> show only the scenarios that did not pass</label></p>
<table id="scenarios"><thead><tr><th>scenario</th><th>verdict</th><th>signals inside</th>
<th>worst signal / reason</th><th>time (s)</th></tr></thead>
<tbody>
{rows}
</tbody></table>
{sections}
<script>{SCRIPT}</script>
</body>
</html>
"""


def write_report(outcomes: Sequence[Outcome], folder: str | os.PathLike, title: str, heading: str,
                 label: str = "result", labels: Mapping[str, str] = LABELS) -> Path:
    """Write :func:`report_html` to ``folder/index.html``; returns its path."""
    return files.write_text(Path(folder) / REPORT_NAME, report_html(outcomes, title, heading, label, labels))
