"""The worker plugin that ships the scenario archives to each Dask worker once (imported only when
a campaign runs: distributed is slow to import)."""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

from distributed import Worker, WorkerPlugin

from .worker import scenario_folder

__all__ = ["ScenarioPlugin"]


class ScenarioPlugin(WorkerPlugin):
    """Carries the scenario archives (digest -> bytes) to each worker once and unpacks each into
    ``<worker local directory>/campaign-<digest>/``, where :func:`run_variant` finds it."""

    def __init__(self, archives: Mapping[str, bytes]) -> None:
        self.archives = dict(archives)

    def setup(self, worker: Worker) -> None:
        for digest, data in self.archives.items():
            folder = scenario_folder(digest, Path(worker.local_directory))
            if folder.is_dir():
                continue
            partial = folder.with_name(folder.name + ".part")
            partial.mkdir(parents=True, exist_ok=True)
            archive = partial / "scenario.ssp"
            archive.write_bytes(data)
            with zipfile.ZipFile(archive) as zf:
                zf.extractall(partial / "scenario")  # validated by the client before shipping
            partial.rename(folder)
