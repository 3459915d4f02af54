# SPDX-License-Identifier: BSD-2-Clause
"""Campaigns: many variants of a scenario run on Dask, one tidy table of results.

``sweep(scenarios, read_design(path), out)`` (or ``orchestrate sweep``) runs every point of a
design -- grid, ranges with counts, random/Latin hypercube samples, explicit table -- on an
embedded ``distributed.LocalCluster`` or an existing Dask cluster, writes one row per run (status,
one-line reason, wall time, metrics) to CSV and Parquet, and ``write_report`` draws the figures
the design asks for. Metrics are pluggable (:class:`Metrics`): this layer imports only the engine.
"""

from __future__ import annotations

from .design import Design, DesignError, read_design
from .report import write_report
from .sweep import SCHEDULER_ENV, CampaignInterrupted, CampaignSummary, connect, sweep
from .table import read_table
from .worker import Metrics, RunSpec, run_variant

__all__ = [
    "SCHEDULER_ENV",
    "CampaignInterrupted",
    "CampaignSummary",
    "Design",
    "DesignError",
    "Metrics",
    "RunSpec",
    "connect",
    "read_design",
    "read_table",
    "run_variant",
    "sweep",
    "write_report",
]
