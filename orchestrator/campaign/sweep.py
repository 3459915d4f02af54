# SPDX-License-Identifier: BSD-2-Clause
"""Run a campaign on Dask: every variant of a design on one or more scenarios, one task per run.

By default an embedded ``distributed.LocalCluster`` with one worker process per core and one
thread per worker (pythonfmu FMUs share one interpreter per process, so processes, not threads);
``scheduler="tcp://HOST:PORT"`` (or the environment variable ``ORCHESTRATE_SCHEDULER``) uses an
existing cluster instead, unchanged. The scenario archives go to each worker once, through a
worker plugin; tasks carry only their overrides.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
import signal
import socket
import sys
import tempfile
import time
import warnings
import zipfile
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, cast

from .. import DEFAULT_STEP, MASTERS, open_system
from ..errors import OrchestratorError, OutputError, ScenarioError, ScenarioWarning, UsageError, option
from ..ssp import DEFAULT_LIMITS, Limits
from .design import EXPERIMENT_KEYS, Design, read_design
from .table import CSV_NAME, Journal, read_rows
from .worker import FAILED, OK, TIMEOUT, Metrics, RunOutcome, RunSpec, run_variant

if TYPE_CHECKING:
    import numpy as np
    from distributed import Client, Future

__all__ = ["SCHEDULER_ENV", "CampaignInterrupted", "CampaignSummary", "check_address", "connect",
           "late_events", "plan", "sweep"]

SCHEDULER_ENV = "ORCHESTRATE_SCHEDULER"
DASHBOARD = "127.0.0.1:0"  # the embedded cluster's dashboard: this host only (it lists every task)
META_NAME = "campaign.json"
TRAJECTORY_DIR = "trajectories"


@dataclass
class CampaignSummary:
    """What a sweep did: counts of this campaign's rows, and where the table is."""

    table: Path
    parquet: Path
    total: int
    skipped: int
    ok: int
    failed: int
    timed_out: int
    wall_time: float
    workers: int
    run_time: float = 0.0  # s from the first task submitted to the last row written (no cluster start-up)
    not_run: int = 0  # runs the cluster did not finish (scheduler lost, ...): no row, --resume runs them
    not_run_reason: str = ""
    lost_workers: dict[str, list[int]] = field(default_factory=dict)  # worker -> runs it held when lost


class CampaignInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep, after every finished row was written; ``summary`` says how many."""

    def __init__(self, summary: CampaignSummary) -> None:
        super().__init__()
        self.summary = summary


def _archive_bytes(scenario: Path) -> bytes:
    """The scenario as .ssp bytes (a folder is zipped in memory: its regular files, never what a
    symbolic link in it points to, which may lie outside it)."""
    if scenario.is_file():
        return scenario.read_bytes()
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for root, _, names in sorted(os.walk(scenario)):  # does not enter linked folders
            for name in sorted(names):
                path = Path(root) / name
                if path.is_file() and not path.is_symlink():
                    zf.write(path, path.relative_to(scenario).as_posix())
    return buffer.getvalue()


def _run_id(digest: str, overrides: dict, stop: float, step: float, master: str) -> str:
    key = json.dumps(
        [digest, sorted((k, repr(v)) for k, v in overrides.items()), repr(stop), repr(step), master]
    )
    return hashlib.sha256(key.encode()).hexdigest()[:16]


def plan(
    scenarios: Sequence[str | os.PathLike],
    design: Design,
    *,
    timeout: float | None = None,
    keep_every: int | None = None,
    limits: Limits = DEFAULT_LIMITS,
) -> tuple[dict[str, bytes], list[RunSpec]]:
    """Check the design against every scenario (unknown names fail here, all at once, before
    anything runs) and list the runs: scenario-major, design order within. Returns the archives by
    digest and the run specs."""
    if design.master not in MASTERS:
        raise UsageError(
            f"{design.source}: unknown master '{design.master}' (choose from {', '.join(MASTERS)})"
        )
    names = _scenario_names(scenarios)
    archives: dict[str, bytes] = {}
    specs: list[RunSpec] = []
    variants = design.variants()
    limit = timeout if timeout is not None else design.timeout
    for scenario, name in zip(scenarios, names, strict=True):
        data = _archive_bytes(Path(scenario))
        digest = hashlib.sha256(data).hexdigest()
        archives[digest] = data
        default_stop, default_step, ssd = _experiment(scenario, design, variants, limits)
        for variant in variants:
            stop = variant.get("stop_time", default_stop)
            if stop is None:
                raise ScenarioError(
                    f"{ssd}: no stopTime in DefaultExperiment; give stop_time in {design.source}"
                )
            step = variant.get("step", default_step)
            overrides = {**design.fixed, **{k: v for k, v in variant.items() if k not in EXPERIMENT_KEYS}}
            specs.append(
                RunSpec(
                    index=len(specs),
                    run_id=_run_id(digest, overrides, stop, step, design.master),
                    scenario=name,
                    digest=digest,
                    overrides=overrides,
                    stop_time=float(stop),
                    step=float(step),
                    master=design.master,
                    timeout=limit,
                    keep_every=keep_every,
                )
            )
    return archives, specs


def _scenario_names(scenarios: Sequence[str | os.PathLike]) -> list[str]:
    """Each scenario's name in the table (an archive's stem, a folder's name); UsageError when two
    share one."""
    names = [Path(s).stem if Path(s).is_file() else Path(s).resolve().name for s in scenarios]
    if len(set(names)) != len(names):
        raise UsageError(
            f"two scenarios share the name {sorted(n for n in names if names.count(n) > 1)[0]!r}"
        )
    return names


def _experiment(scenario: str | os.PathLike, design: Design, variants: Sequence[Mapping[str, object]],
                limits: Limits) -> tuple[float | None, float, str]:
    """The stop time and step a run of ``scenario`` has where its variant gives none (the design's,
    else the scenario's DefaultExperiment, else the default step), and its SSD's path. The scenario
    is opened with the first variant's values (a bad name fails here, before anything runs)."""
    first = {k: v for k, v in variants[0].items() if k not in EXPERIMENT_KEYS} if variants else {}
    with open_system(scenario, overrides={**design.fixed, **first}, limits=limits) as system:
        ex = system.structure.experiment
        default_stop = design.stop_time if design.stop_time is not None else ex.stop_time
        default_step = design.step if design.step is not None else ex.step if ex.step is not None \
            else DEFAULT_STEP
    return default_stop, default_step, system.ssd


def check_address(scheduler: str | None, dashboard: str) -> None:
    """Before anything runs: UsageError for a scheduler address Dask cannot parse (``tcp://HOST:PORT``)
    or a dashboard address that is not HOST:PORT with a host this machine resolves (distributed
    gave a traceback for either, after the campaign had been planned)."""
    address = scheduler or os.environ.get(SCHEDULER_ENV) or None
    if address:
        _check_scheduler(address, option("scheduler") if scheduler else f"${SCHEDULER_ENV}")
        return
    host, sep, port = dashboard.rpartition(":")
    if not sep or not port.isdigit() or int(port) > 65535:
        raise UsageError(f"{option('dashboard')} {dashboard!r}: expected HOST:PORT (PORT 0 for a free one)")
    try:
        socket.getaddrinfo(host or None, int(port), type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as exc:
        raise UsageError(f"{option('dashboard')} {dashboard!r}: cannot resolve {host!r} "
                         f"({getattr(exc, 'strerror', None) or exc})") from None


def _check_scheduler(address: str, where: str) -> None:
    """UsageError, naming ``where`` the address came from, unless Dask can parse it."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise UsageError(f"{where} {address!r}: not a Dask scheduler address such as tcp://HOST:PORT "
                         f"({exc})") from None


def late_events(specs: Sequence[RunSpec], metrics: Metrics | None) -> list[str]:
    """What a ScenarioWarning says of runs that stop before an event of ``metrics.events`` (e.g. a
    fault time after the horizon: the metrics after the fault are then undefined, not failed)."""
    events = metrics.events.items() if metrics is not None else ()
    return [text for event, names in events if (text := _late_event(specs, event, names))]


def _late_event(specs: Sequence[RunSpec], event: str, names: Sequence[str]) -> str:
    """What :func:`late_events` says of one event (the parameter giving its time), or ""."""
    at = {s.index: float(cast(float, s.overrides[event])) for s in specs if event in s.overrides}
    late = [s for s in specs if s.index in at and at[s.index] >= s.stop_time]
    if not late:
        return ""
    times = [at[s.index] for s in late]
    stops = ", ".join(f"{t:g}" for t in sorted({s.stop_time for s in late})[:3])
    return (f"{len(late)} of {len(specs)} runs stop (t = {stops} s) "
            f"at or before their {event} ({min(times):g} .. {max(times):g} s): "
            f"{', '.join(names)} will be undefined (NaN) for them; a later stop time covers it")


@contextmanager
def connect(
    scheduler: str | None = None,
    workers: int | None = None,
    processes: bool = True,
    dashboard: str = DASHBOARD,
) -> Iterator[Client]:
    """A ``distributed.Client``: to ``scheduler`` (or $ORCHESTRATE_SCHEDULER) if given, else to an
    embedded LocalCluster of ``workers`` (default: one per core) single-threaded worker processes,
    whose dashboard (and the rest of the scheduler's HTTP server) listens on ``dashboard``
    (HOST:PORT; default this host only, a free port; distributed has no way to turn it off: None
    would listen on all interfaces, port 8787). The client's own logging of a lost connection
    (tracebacks) is silenced: the sweep reports what it means in one line."""
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    import dask
    from distributed import Client, LocalCluster

    address = scheduler or os.environ.get(SCHEDULER_ENV) or None
    if address:
        try:
            client = Client(address, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise OrchestratorError(f"cannot connect to the Dask scheduler at {address}: {exc}") from exc
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    # the workers' scratch space (Dask's default: TMPDIR/dask-scratch-space, left for ever) in a
    # folder of this campaign's, removed when the cluster is closed
    scratch = tempfile.TemporaryDirectory(prefix="orchestrate-dask-", ignore_cleanup_errors=True)
    try:
        with dask.config.set({"temporary-directory": scratch.name}):  # the scheduler's as well
            cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=processes,
                dashboard_address=dashboard,  # localhost, a free port: several campaigns may run at once
                silence_logs=logging.ERROR,
                local_directory=scratch.name,
            )
    except (OSError, RuntimeError, ValueError) as exc:  # a port taken, no process could start, ...
        scratch.cleanup()
        raise OrchestratorError(f"cannot start the embedded Dask cluster (dashboard {dashboard}): "
                                f"{' '.join(str(exc).split())}") from exc
    client = Client(cluster)
    try:
        if processes:
            client.run(_ignore_interrupts)
        yield client
    finally:
        client.close()
        cluster.close()
        scratch.cleanup()


@contextmanager
def _watch_workers(
    client: Client, by_key: dict[object, RunSpec], lost: dict[str, set[int]]
) -> Iterator[None]:
    """Note in ``lost`` every worker the scheduler removes, with the runs (``by_key``: task key ->
    run) it was running (the scheduler's ``remove-worker`` event). Unsubscribed before the client
    closes: else the scheduler logs a traceback sending the client its own removal."""

    def removed(event: tuple[float, dict]) -> None:
        message = event[1]
        if isinstance(message, dict) and message.get("action") == "remove-worker":
            held = {by_key[k].index for k in message.get("processing-tasks", ()) if k in by_key}
            lost.setdefault(str(message.get("worker", "?")), set()).update(held)

    client.subscribe_topic("all", removed)
    try:
        yield
    finally:
        try:
            client.unsubscribe_topic("all")
        except Exception:  # noqa: BLE001 - the scheduler is gone: nothing to unsubscribe from
            pass


def _ignore_interrupts() -> None:
    """In an embedded worker process: Ctrl-C reaches the whole process group, but only the client
    should handle it (it keeps the finished rows and closes the cluster; the workers printed
    tracebacks)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _resume(folder: Path, columns: list[str], specs: list[RunSpec], resume: bool, force: bool) -> list[dict]:
    """Rows of an earlier run of this campaign to keep (ok and failed; timeouts run again)."""
    path = folder / CSV_NAME
    if not path.is_file() or force:
        return []
    header, rows = read_rows(path)
    if not resume:
        if not rows:
            return []
        raise UsageError(
            f"{path} already holds {len(rows)} rows: pass --resume to continue the campaign, "
            "or --force to start it again"
        )
    if header != columns:
        raise UsageError(
            f"{path}: its columns differ from this campaign's (another design?); use another "
            "--out, or --force to start again"
        )
    _check_own_runs(path, rows, specs)
    return [r for r in rows if r["status"] in (OK, FAILED)]


def _check_own_runs(path: Path, rows: Sequence[dict], specs: Sequence[RunSpec]) -> None:
    """UsageError unless each row of the earlier table is a run of this campaign, at its place."""
    ids = {s.run_id: s.index for s in specs}
    foreign = [r for r in rows if r["run_id"] not in ids or ids[r["run_id"]] != r["run"]]
    if foreign:
        raise UsageError(
            f"{path}: {len(foreign)} rows are not runs of this campaign (run {foreign[0]['run']}: "
            "scenario, design or master changed); use another --out, or --force to start again"
        )


def _number(value: object) -> int | float:
    """A varied parameter's cell: always a number, an integer of the design kept one (mode = 1)."""
    return value if isinstance(value, int) and not isinstance(value, bool) else float(cast(float, value))


def _row(spec: RunSpec, outcome: RunOutcome, params: Sequence[str]) -> dict[str, object]:
    row: dict[str, object] = {"run": spec.index, "run_id": spec.run_id, "scenario": spec.scenario}
    row.update({p: _number(spec.overrides[p]) for p in params})
    row.update(
        stop_time=spec.stop_time,
        step=spec.step,
        status=outcome.status,
        reason=outcome.reason,
        wall_time=outcome.wall_time,
    )
    row.update(outcome.metrics)
    return row


def _write_trajectory(folder: Path, spec: RunSpec, data: np.ndarray) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder.mkdir(parents=True, exist_ok=True)
    names = data.dtype.names
    assert names is not None  # a result is a structured array, one field per column
    table = pa.table({name: data[name] for name in names})
    pq.write_table(table, folder / f"run-{spec.index:05d}-{spec.run_id}.parquet")


def _meta(design: Design, metrics: Sequence[str], specs: Sequence[RunSpec]) -> dict[str, object]:
    """The campaign's record (campaign.json, and the parquet table's metadata): the design, the
    metrics and the scenarios' archive digests."""
    return {
        "design": design.source,
        "description": design.description,
        "columns": list(design.columns),
        "fixed": dict(design.fixed),
        "master": design.master,
        "plots": list(design.plots),
        "labels": dict(design.labels),
        "metrics": list(metrics),
        "scenarios": {s.scenario: s.digest for s in specs},
        "runs": len(specs),
    }


def _start_journal(out: Path, columns: list[str], meta: dict[str, object], kept: list[dict]) -> Journal:
    """The campaign's table started with the rows ``kept`` from before, and campaign.json written;
    OutputError naming the file that cannot be written."""
    journal = Journal(out, columns, meta)
    try:
        journal.start(kept)
        (out / META_NAME).write_text(json.dumps(meta, indent=2, default=str) + "\n", encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"{exc.filename or out}: {exc.strerror or exc}") from exc
    return journal


def _left_to_run(specs: Sequence[RunSpec], kept: Sequence[dict]) -> tuple[list[RunSpec], dict[str, int]]:
    """The runs not among the rows ``kept`` from before, and those rows counted by status."""
    done = {r["run_id"] for r in kept}
    counts = {OK: 0, FAILED: 0, TIMEOUT: 0}
    for r in kept:
        counts[r["status"]] += 1
    return [s for s in specs if s.run_id not in done], counts


def _warn_late_events(specs: Sequence[RunSpec], metrics: Metrics | None) -> None:
    """A ScenarioWarning, at the caller of :func:`sweep`, for each event some runs stop before."""
    for message in late_events(specs, metrics):
        warnings.warn(message, ScenarioWarning, stacklevel=3)


def _submit(client: Client, todo: Sequence[RunSpec], metrics: Metrics | None,
            by_key: dict[object, RunSpec]) -> list[Future]:
    """One task per run, in order; ``by_key`` learns which run each task key is."""
    futures = []
    for spec in todo:
        future = client.submit(run_variant, spec, metrics, key=f"run-{spec.index}-{spec.run_id}", pure=False)
        by_key[future.key] = spec
        futures.append(future)
    return futures


def _record(out: Path, journal: Journal, spec: RunSpec, outcome: RunOutcome, params: Sequence[str]) -> None:
    """The run's row into the table, its kept trajectory (if any) into ``out/trajectories/``."""
    if outcome.trajectory is not None:
        _write_trajectory(out / TRAJECTORY_DIR, spec, outcome.trajectory)
    journal.append(_row(spec, outcome, params))


def _outcome(future: Future, spec: RunSpec) -> RunOutcome | str:
    """The run's outcome (a failed row when it killed every worker it ran on: an FMU crash), or why
    the cluster did not finish it (the scheduler lost, ...: no row); the future released."""
    from distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker as exc:
        reason = " ".join(f"worker lost: {type(exc).__name__}: {exc}".split())
        return RunOutcome(spec.index, FAILED, reason, float("nan"))
    except Exception as exc:  # noqa: BLE001 - the cluster, not the run: not run, no row
        return " ".join(f"{type(exc).__name__}: {exc}".split())
    finally:
        future.release()


def sweep(
    scenarios: Sequence[str | os.PathLike],
    design: Design | str | os.PathLike,
    out: str | os.PathLike,
    *,
    metrics: Metrics | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    processes: bool = True,
    resume: bool = False,
    force: bool = False,
    timeout: float | None = None,
    keep_every: int | None = None,
    progress: bool = True,
    limits: Limits = DEFAULT_LIMITS,
    dashboard: str = DASHBOARD,
) -> CampaignSummary:
    """Run every variant of ``design`` on each scenario and write ``out/runs.csv``, ``out/runs.parquet``
    and ``out/campaign.json`` (plus ``out/trajectories/`` with ``keep_every``: every n-th row of each
    run). ``design`` is a :class:`Design` or the path of a design file. A failed or timed-out run is
    a row; ``resume`` skips runs already in the table; Ctrl-C raises :class:`CampaignInterrupted`
    after writing every finished row. A run the cluster did not finish because the scheduler went
    away (or the connection to it) gets no row: it is counted as not run and ``resume`` runs it.
    Workers lost on the way are reported with the runs they held (Dask runs those again
    elsewhere; a run that kills every worker it is given fails with KilledWorker, a row). The
    archives reach the workers and are unpacked there within ``limits``, as by ``run``."""
    started = time.perf_counter()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"{option('out')} {out}: not a folder (the campaign writes runs.csv, runs.parquet "
                         "and campaign.json into it)")
    check_address(scheduler, dashboard)
    design = design if isinstance(design, Design) else read_design(design)
    archives, specs = plan(scenarios, design, timeout=timeout, keep_every=keep_every, limits=limits)
    _warn_late_events(specs, metrics)
    params = [c for c in design.columns if c not in EXPERIMENT_KEYS]
    names = list(metrics.names) if metrics is not None else []
    columns = ["run", "run_id", "scenario", *params, "stop_time", "step", "status", "reason", "wall_time",
               *names]
    kept = _resume(out, columns, specs, resume, force)
    journal = _start_journal(out, columns, _meta(design, names, specs), kept)
    todo, counts = _left_to_run(specs, kept)
    n_workers = 0
    phase = [0.0, 0.0]  # perf_counter at the first submission and at the last row
    not_run: list[tuple[RunSpec, str]] = []  # what the cluster did not finish, and why
    lost: dict[str, set[int]] = {}  # worker -> the runs it was running when it was removed

    def summary() -> CampaignSummary:
        return CampaignSummary(
            journal.csv_path,
            journal.parquet_path,
            len(specs),
            len(kept),
            counts[OK],
            counts[FAILED],
            counts[TIMEOUT],
            time.perf_counter() - started,
            n_workers,
            phase[1] - phase[0],
            len(not_run),
            not_run[0][1] if not_run else "",
            {w: sorted(runs) for w, runs in lost.items()},
        )

    if not todo:
        journal.finish()
        return summary()
    from distributed import as_completed
    from tqdm import tqdm

    from .plugin import ScenarioPlugin

    bar = tqdm(
        total=len(specs),
        initial=len(kept),
        unit="run",
        file=sys.stderr,
        disable=not progress,
        smoothing=0.1,
        dynamic_ncols=True,
    )
    try:
        by_key: dict[object, RunSpec] = {}
        with (
            connect(scheduler, workers, processes, dashboard) as client,
            _watch_workers(client, by_key, lost),
        ):
            plugin = hashlib.sha256("".join(sorted(archives)).encode()).hexdigest()[:16]
            client.register_plugin(ScenarioPlugin(archives, limits), name=f"orchestrate-campaign-{plugin}")
            n_workers = len(client.scheduler_info(n_workers=-1)["workers"])
            phase[0] = phase[1] = time.perf_counter()
            futures = _submit(client, todo, metrics, by_key)
            for future in as_completed(futures):
                spec = by_key[future.key]
                outcome = _outcome(future, spec)
                if isinstance(outcome, str):
                    not_run.append((spec, outcome))
                    continue
                _record(out, journal, spec, outcome, params)
                counts[outcome.status] += 1
                bar.set_postfix(failed=counts[FAILED] + counts[TIMEOUT], refresh=False)
                bar.update()
                phase[1] = time.perf_counter()
    except KeyboardInterrupt:
        bar.close()
        journal.finish()
        raise CampaignInterrupted(summary()) from None
    bar.close()
    journal.finish()
    return summary()
