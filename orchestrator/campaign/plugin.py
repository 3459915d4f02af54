# SPDX-License-Identifier: BSD-2-Clause
"""The worker plugin that ships the scenario archives to each Dask worker once (imported only when
a campaign runs: distributed is slow to import)."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path

from distributed import Worker, WorkerPlugin

from ..errors import ScenarioError
from ..ssp import DEFAULT_LIMITS, Limits, extract_scenario
from .worker import scenario_folder

__all__ = ["ScenarioPlugin"]


class ScenarioPlugin(WorkerPlugin):
    """Carries the scenario archives (digest -> bytes) to each worker once and unpacks each into
    ``<worker local directory>/campaign-<digest>/``, where :func:`run_variant` finds it, with the
    engine's bounded extraction (``limits``; unsafe members left out, only what the SSD references),
    so a worker costs no more disk than ``run`` would."""

    def __init__(self, archives: Mapping[str, bytes], limits: Limits = DEFAULT_LIMITS) -> None:
        self.archives = dict(archives)
        self.limits = limits

    def setup(self, worker: Worker) -> None:
        for digest, data in self.archives.items():
            folder = scenario_folder(digest, Path(worker.local_directory))
            if folder.is_dir():
                continue
            partial = folder.with_name(folder.name + ".part")
            shutil.rmtree(partial, ignore_errors=True)  # a worker that died while unpacking
            partial.mkdir(parents=True)
            archive = partial / "scenario.ssp"
            archive.write_bytes(data)
            problems = extract_scenario(archive, partial / "scenario", self.limits)
            if problems:  # the client checked the same bytes: only a damaged copy gets here
                raise ScenarioError(problems)
            archive.unlink()
            partial.rename(folder)
