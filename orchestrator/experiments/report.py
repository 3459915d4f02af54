# SPDX-License-Identifier: BSD-2-Clause
"""The paper's examples by co-simulation: figures, the metrics beside Tables 1-2, and the
fixed-time claim measured (settling time over a grid of initial states).

``orchestrate report [--out results/report]`` builds the FMUs and scenarios into a
temporary folder, runs Example 1 and Example 2 (pendulum) with the fixed-time controller and the
finite-time baseline through the orchestrator, runs the settling-time study, and writes
``report.md`` with PNG figures into the output folder. Runs are spread over two processes
(pythonfmu FMUs share one interpreter per process, so processes, not threads).
"""

from __future__ import annotations

import datetime
import math
import os
import tempfile
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from controller.params import Mode

from .. import RunOptions, open_system, provenance, run
from ..campaign import Design, read_table, sweep
from ..campaign import write_report as campaign_report
from ..plots import axis_label
from .campaigns import TRACKING, claim_headlines, fault_headlines
from .metrics import TrackingMetrics, format_table, tracking_metrics
from .scenarios import build_scenarios

__all__ = ["CASES", "PAPER_TABLE", "SettlingRow", "run_cases", "settling_study", "write_report"]

DEFAULT_OUT = Path("results") / "report"
BAND = 0.05
# (example, method) -> scenario; the finite-time method is the paper's comparison "[36]"
CASES = {
    (1, "fixed-time"): "example1",
    (1, "finite-time"): "example1_finite_time",
    (2, "fixed-time"): "pendulum",
    (2, "finite-time"): "pendulum_finite_time",
}
# SPEC section 4 (the paper's Tables 1-2): RAE, MSE, RMSE, MAE
PAPER_TABLE = {
    (1, "fixed-time"): (0.1375, 0.0027, 0.0517, 0.0209),
    (1, "finite-time"): (0.1597, 0.0036, 0.0600, 0.0295),
    (2, "fixed-time"): (0.1157, 0.0066, 0.0810, 0.0477),
    (2, "finite-time"): (0.1422, 0.0092, 0.0960, 0.0636),
}
# example -> the fixed-time scenario with the semi-implicit discretization (issue 11)
SMOOTH = {1: "example1_smooth", 2: "pendulum_smooth"}
STUDY_SCENARIO = "example1_no_fault"
STUDY_VALUES = (-2.0, -1.0, 0.0, 1.0, 2.0)
STUDY_HORIZON = 10.0


def _run_case(args: tuple[Path, float | None, dict]) -> np.ndarray:
    archive, stop_time, overrides = args
    return run(archive, RunOptions(stop_time=stop_time, overrides=overrides)).rows


def _metrics(result: np.ndarray) -> TrackingMetrics:
    return tracking_metrics(result["time"], result["plant.y"], result["reference.yd"],
                            result["controller.v"], result["actuator.uf"], band=BAND)


def run_cases(archives: dict[str, Path], stop_time: float | None = None,
              processes: int = 2) -> dict[tuple[int, str], np.ndarray]:
    """Run the four cases of Tables 1-2 (full DefaultExperiment unless ``stop_time``)."""
    jobs: list[tuple[Path, float | None, dict]] = [(archives[s], stop_time, {}) for s in CASES.values()]
    with ProcessPoolExecutor(processes) as pool:
        return dict(zip(CASES, pool.map(_run_case, jobs), strict=True))


@dataclass(frozen=True)
class SettlingRow:
    """Settling time (s; ``inf`` never, ``nan`` the run failed) of both modes from one initial state."""

    x1_0: float
    x2_0: float
    fixed_time: float
    finite_time: float


def settling_study(archive: Path, values: Sequence[float] = STUDY_VALUES, horizon: float = STUDY_HORIZON,
                   processes: int = 2) -> list[SettlingRow]:
    """Settling time (band 0.05 on |y - yd|) of Example 1 from every (x1(0), x2(0)) in ``values``
    squared, in both modes: a campaign (``orchestrator.campaign.sweep``) on an embedded Dask cluster
    of ``processes`` workers."""
    states = [(a, b) for a in values for b in values]
    design = Design(source="settling study", columns=("plant.x1_0", "plant.x2_0", "controller.mode"),
                    points=tuple((a, b, float(mode)) for a, b in states for mode in Mode), stop_time=horizon)
    with tempfile.TemporaryDirectory(prefix="settling-") as work:
        summary = sweep([archive], design, work, metrics=TRACKING, workers=processes, progress=False)
        rows, _ = read_table(summary.parquet)
    times = [r["settling_time"] if r["status"] == "ok" else math.nan for r in rows]
    return [SettlingRow(a, b, times[2 * i], times[2 * i + 1]) for i, (a, b) in enumerate(states)]


# -- figures ---------------------------------------------------------------------------------------
FIGURES = (  # key, title, signals, with the reference, y label, columns whose unit the y axis shows
    ("output", "output y and reference yd", lambda r: {"y": r["plant.y"]}, True, "y, yd", ["plant.y"]),
    ("error", "tracking error y - yd", lambda r: {"y - yd": r["plant.y"] - r["reference.yd"]}, False,
     "y - yd", ["plant.y"]),
    ("x2", "state x2", lambda r: {"x2": r["plant.x2"]}, False, "x2", ["plant.x2"]),
    ("eta_hat", "adaptive estimates", lambda r: {"eta1_hat": r["controller.eta1_hat"],
                                                  "eta2_hat": r["controller.eta2_hat"]}, False,
     "eta_hat", ["controller.eta1_hat", "controller.eta2_hat"]),
    ("control", "control v and applied uf", lambda r: {"v": r["controller.v"], "uf": r["actuator.uf"]},
     False, "v, uf", ["controller.v", "actuator.uf"]),
    ("z_r", "unmodeled dynamics z and dynamic signal r",
     lambda r: {"z": r["plant.z"], "r": r["controller.r"]}, False, "z, r", ["plant.z", "controller.r"]),
)


def _figures(results: dict[tuple[int, str], np.ndarray], out: Path,
             units: dict[int, dict[str, str | None]] | None = None) -> dict[int, list[tuple[str, str]]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written: dict[int, list[tuple[str, str]]] = {}
    for example in sorted({e for e, _ in results}):
        for key, title, select, with_reference, ylabel, columns in FIGURES:
            fig, ax = plt.subplots(figsize=(9, 3.4))
            for (e, method), result in results.items():
                if e != example:
                    continue
                style = "-" if method == "fixed-time" else "--"
                for label, values in select(result).items():
                    ax.plot(result["time"], values, style, linewidth=0.9, label=f"{label} ({method})")
            if with_reference:
                r = results[(example, "fixed-time")]
                ax.plot(r["time"], r["reference.yd"], ":", color="black", linewidth=1.2, label="yd")
            if key == "control":
                ax.set_yscale("symlog", linthresh=10)
            ax.set_title(f"Example {example}: {title}")
            ax.set_ylabel(axis_label(ylabel, columns, (units or {}).get(example, {})))
            ax.set_xlabel("time (s)")
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize="small", ncol=2)
            fig.tight_layout()
            name = f"example{example}_{key}.png"
            fig.savefig(out / name, dpi=100)
            plt.close(fig)
            written.setdefault(example, []).append((title, name))
    return written


# -- the report -------------------------------------------------------------------------------------
def _experiment(archive: Path) -> tuple[float | None, float, dict[str, object]]:
    """Stop time, step and the controller's alpha, beta of a scenario, as the orchestrator reads them."""
    with open_system(archive) as system:
        ex = system.structure.experiment
        controller = system.components["controller"]
        variables = controller.variables
        params = {n: controller.start_values.get(n, variables[n].start) for n in ("alpha", "beta")}
        return ex.stop_time, ex.step or 1e-3, params


def _fmt(value: float) -> str:
    if math.isnan(value):
        return "failed"
    return "never" if math.isinf(value) else f"{value:.2f}"


def _provenance_line() -> str:
    """Date, commit and package versions of the code that wrote the report."""
    git = provenance.commit()
    code = (f"commit `{str(git['commit'])[:12]}`{' with local changes' if git['modified'] else ''}"
            if git else "not from a git checkout")
    packages = ", ".join(f"{k} {v}" for k, v in provenance.versions().items())
    date = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    return f"Written {date}; {code}; {packages}."


def write_report(out: str | os.PathLike = DEFAULT_OUT, stop_time: float | None = None,
                 study_values: Sequence[float] = STUDY_VALUES, study_horizon: float = STUDY_HORIZON,
                 processes: int = 2, campaigns: str | os.PathLike | None = None) -> Path:
    """Run everything and write ``out/report.md`` with its figures; returns the report's path.
    ``campaigns``: a folder holding the shipped campaigns' tables (``<name>/runs.parquet``, written
    by ``orchestrate sweep``), reported with their figures."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="report-") as work:
        archives = build_scenarios([*CASES.values(), *SMOOTH.values(), STUDY_SCENARIO], work, fmi3=False)
        results = run_cases(archives, stop_time, processes)
        with ProcessPoolExecutor(processes) as pool:
            smooth = dict(zip(SMOOTH, pool.map(_run_case, [(archives[s], stop_time, {})
                                                           for s in SMOOTH.values()]), strict=True))
        study = settling_study(archives[STUDY_SCENARIO], study_values, study_horizon, processes)
        settings = {s: _experiment(archives[s]) for s in CASES.values()}
        units = _units(archives)
    figures = _figures(results, out, units)
    elapsed = time.perf_counter() - started

    metrics = {case: _metrics(r) for case, r in results.items()}
    lines = ["# Fixed-time vs finite-time control by co-simulation", "",
             "Generated by `orchestrate report`: the four scenarios run as FMUs through the "
             "orchestrator (gauss-seidel master, outputs propagated in dependency order at every "
             "communication point).", ""]
    lines += [_provenance_line(), ""]
    lines += _settings_section(settings, stop_time)
    lines += _metrics_section(metrics)
    lines += _discretization_section(results, smooth, out)
    lines += _study_section(study, study_values, study_horizon)
    if campaigns is not None:
        lines += _campaign_sections(Path(campaigns), out)

    for example, items in figures.items():
        lines += [f"## Figures, Example {example}", "",
                  "Solid: fixed-time (proposed); dashed: finite-time [36].", ""]
        lines += [f"![{title}]({name})" for title, name in items]
        lines.append("")
    lines += [f"Wall time of this report: {elapsed:.0f} s ({processes} processes).", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def _units(archives: Mapping[str, Path]) -> dict[int, dict[str, str | None]]:
    """Per example, the units of its fixed-time scenario's columns (for the figures' axes)."""
    units = {}
    for (example, method), scenario in CASES.items():
        if method == "fixed-time":
            with open_system(archives[scenario]) as system:
                units[example] = provenance.column_units(system)
    return units


def _settings_section(settings: Mapping[str, tuple[float | None, float, dict[str, object]]],
                      stop_time: float | None) -> list[str]:
    """The report's settings: per example and method, the scenario, horizon, step and exponents."""
    lines = ["## Settings", "",
             "| example | method | scenario | horizon (s) | grid / step (s) | alpha | beta |",
             "|---|---|---|---|---|---|---|"]
    for (example, method), scenario in CASES.items():
        stop, step, p = settings[scenario]
        horizon = stop_time if stop_time is not None else stop
        lines.append(f"| {example} | {method} | {scenario} | {horizon:g} | {step:g} | {p['alpha']} "
                     f"| {p['beta']} |")
    return lines + ["", "Metrics are computed on every communication point (uniform grid, step above) "
                    "over the whole run, e = y - yd (SPEC section 4); the plant integrates with RK4 "
                    "sub-steps inside each communication step, the controller output is held over the "
                    "step (zero-order hold).", ""]


def _metrics_section(metrics: Mapping[tuple[int, str], TrackingMetrics]) -> list[str]:
    """The metrics beside the paper's Tables 1-2, settling and peaks, and per example whether the
    fixed-time law is ahead."""
    lines = ["## Metrics beside the paper's Tables 1-2", "",
             "| example | method | RAE | MSE | RMSE | MAE "
             "| paper RAE | paper MSE | paper RMSE | paper MAE |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for (example, method), m in metrics.items():
        paper = PAPER_TABLE[(example, method)]
        lines.append(f"| {example} | {method} | {m.rae:.4f} | {m.mse:.4f} | {m.rmse:.4f} | {m.mae:.4f} | "
                     + " | ".join(f"{v:.4f}" for v in paper) + " |")
    lines += ["", "Settling time (band 0.05) and peaks:", "",
              format_table([(f"Example {e}, {method}", m) for (e, method), m in metrics.items()]), ""]
    for example in sorted({e for e, _ in metrics}):
        fixed, finite = metrics[(example, "fixed-time")], metrics[(example, "finite-time")]
        ahead = fixed.rmse < finite.rmse and fixed.mae < finite.mae
        verdict = "ahead of" if ahead else "NOT ahead of"
        lines.append(f"Example {example}: the fixed-time controller is {verdict} "
                     f"the finite-time one on these runs (RMSE {fixed.rmse:.4f} vs {finite.rmse:.4f}, "
                     f"MAE {fixed.mae:.4f} vs {finite.mae:.4f}).")
    return lines + [""]


def _discretization_section(results: dict[tuple[int, str], np.ndarray], smooth: dict[int, np.ndarray],
                            out: Path) -> list[str]:
    """Issue 11: the fixed-time scenarios' control, explicit sampling against the semi-implicit law,
    measured (``discretization.chattering``) and plotted side by side after the 1 s transient (on a
    horizon shorter than 2 s: its second half)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .discretization import GAP, RATE, START, chattering

    # After the transient (START); a report on a horizon shorter than that measures its second half.
    stop = min(float(r["time"][-1]) for r in [*smooth.values(), *results.values()])
    start = START if stop > 2 * START else stop / 2
    lines = ["## Sampled law: explicit (the paper's) vs semi-implicit (`discretization = 1`)", "",
             f"Fixed-time scenarios, v after {start:g} s: total variation per second, peak, and chattering "
             f"bursts (reversals of v with both changes above {RATE:g}/s times the step, grouped when under "
             f"{GAP:g} s apart); tracking metrics over the whole run.", "",
             "| example | scenario | TV of v per s | peak abs(v) | bursts | burst time (s) | MAE | RMSE "
             "| settling (s) |", "|---|---|---|---|---|---|---|---|---|"]
    for example, semi in smooth.items():
        pair = (("explicit", CASES[(example, "fixed-time")], results[(example, "fixed-time")]),
                ("semi-implicit", SMOOTH[example], semi))
        for _, scenario, r in pair:
            c, m = chattering(r["time"], r["controller.v"], start=start), _metrics(r)
            lines.append(f"| {example} | {scenario} | {c.tv_per_second:.3g} | {c.peak:.3g} | {c.bursts} | "
                         f"{c.burst_time:.2f} | {m.mae:.5f} | {m.rmse:.4f} | {m.settling_time:.3f} |")
    lines.append("")
    for example, semi in smooth.items():
        pair = (("explicit", CASES[(example, "fixed-time")], results[(example, "fixed-time")]),
                ("semi-implicit", SMOOTH[example], semi))
        fig, axes = plt.subplots(1, 2, figsize=(12, 3.4), sharey=True)
        for ax, (label, scenario, r) in zip(axes, pair, strict=True):
            after = r["time"] >= start
            ax.plot(r["time"][after], r["controller.v"][after], linewidth=0.7, label="v")
            ax.plot(r["time"][after], r["actuator.uf"][after], linewidth=0.7, label="uf")
            ax.set_title(f"Example {example}, {label} (`{scenario}`)")
            ax.set_xlabel("time (s)")
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize="small")
        axes[0].set_ylabel("v, uf")
        fig.tight_layout()
        name = f"example{example}_control_discretization.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        lines += [f"![Example {example}: control, explicit vs semi-implicit]({name})", ""]
    return lines


# name -> (title, headline findings) of the campaigns shipped in ssp/campaigns/
SHIPPED_CAMPAIGNS = {"fixed_time_claim": ("the fixed-time claim over [-10, 10]^2", claim_headlines),
                     "fixed_time_claim_fine_step": ("the fixed-time claim at a 0.1 ms step", claim_headlines),
                     "fault_tolerance": ("fault tolerance", fault_headlines)}


def _campaign_sections(folder: Path, out: Path) -> list[str]:
    """A section per shipped campaign whose table is ``folder/<name>/runs.parquet``; its figures and
    summary go to ``out/campaigns/<name>/``."""
    lines = []
    for name, (title, headlines) in SHIPPED_CAMPAIGNS.items():
        table = folder / name / "runs.parquet"
        lines += [f"## Campaign: {title}", ""]
        if not table.is_file():
            lines += [f"Not run: no {table} (`orchestrate sweep ... --design ssp/campaigns/{name}.toml "
                      f"--out {folder / name}`).", ""]
            continue
        rows, meta = read_table(table)
        summary = campaign_report(table, out / "campaigns" / name)
        walls = [r["wall_time"] for r in rows if r["wall_time"] is not None]
        run_time = sum(w for w in walls if math.isfinite(w))
        lines += [f"{meta.get('description', '')}: {len(rows)} runs (`orchestrate sweep`, design "
                  f"`ssp/campaigns/{name}.toml`), {run_time:.0f} s of run time; details in "
                  f"[campaigns/{name}/summary.md](campaigns/{name}/summary.md).", ""]
        lines += [f"* {h}" for h in headlines(rows, meta.get("fixed", {}))] + [""]
        figures = sorted(summary.parent.glob("*.png"))
        lines += [f"![{p.stem}](campaigns/{name}/{p.name})" for p in figures] + [""]
    return lines


def _study_section(study: list[SettlingRow], values: Sequence[float], horizon: float) -> list[str]:
    fixed = np.array([r.fixed_time for r in study])
    finite = np.array([r.finite_time for r in study])
    grid = ", ".join(f"{v:g}" for v in values)
    lines = ["## The fixed-time claim, measured", "",
             f"Example 1 (scenario `{STUDY_SCENARIO}`: the paper's Example 1 without the actuator fault, "
             f"which would act only at t = 10 s) from every x1(0), x2(0) in {{{grid}}}, "
             f"z(0) = 0, horizon {horizon:g} s, settling time = first time after which |y - yd| <= {BAND} "
             "to the end of the run.", "",
             "| x1(0) | x2(0) | fixed-time settling (s) | finite-time settling (s) |", "|---|---|---|---|"]
    lines += [f"| {r.x1_0:g} | {r.x2_0:g} | {_fmt(r.fixed_time)} | {_fmt(r.finite_time)} |" for r in study]

    def spread(x: np.ndarray) -> str:
        ok = x[np.isfinite(x)]
        bad = len(x) - len(ok)
        text = f"{ok.min():.2f} .. {ok.max():.2f} s" if len(ok) else "none settled"
        return text + (f" ({bad} of {len(x)} runs never settled or failed)" if bad else "")

    lines += ["", f"Fixed-time: settling times {spread(fixed)}; finite-time: {spread(finite)}.", ""]
    # growth of the worst settling time from the near half of the grid to its farthest states
    distance = np.array([max(abs(r.x1_0), abs(r.x2_0)) for r in study])
    near, far = distance <= distance.max() / 2, distance == distance.max()
    if not near.any():
        lines.append(f"Every initial state of this grid is at max(|x1(0)|, |x2(0)|) = {distance.max():g}: "
                     "no nearer states to compare with, so the claim cannot be judged from this grid.")
    elif np.isfinite(fixed).all() and np.isfinite(finite).all():
        fixed_growth = fixed[far].max() - fixed[near].max()
        finite_growth = finite[far].max() - finite[near].max()
        lines.append(f"Worst settling time from the initial states with max(|x1(0)|, |x2(0)|) <= "
                     f"{distance.max() / 2:g} vs from the farthest ones: "
                     f"fixed-time {fixed[near].max():.2f} s -> "
                     f"{fixed[far].max():.2f} s, finite-time {finite[near].max():.2f} s -> "
                     f"{finite[far].max():.2f} s.")
        holds = fixed.max() < finite.max() and fixed_growth <= 0.25 * max(finite_growth, 0.0)
        lines.append("Verdict (criterion: the fixed-time worst case is below the finite-time one and "
                     "grows by at most a quarter as much): " + (
                         "yes, the fixed-time controller's settling time stays bounded independently of the "
                         "initial state on this grid, while the finite-time one's grows with it."
                         if holds else
                         "no, on this grid the measurement does not show the fixed-time controller's "
                         "settling time bounded independently of the initial state while the finite-time "
                         "one's grows."))
    else:
        lines.append("Some runs did not settle or failed (see the table), so the claim cannot be judged "
                     "from this grid alone.")
    lines.append("")
    return lines
