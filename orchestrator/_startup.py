"""The first thing ``orchestrate`` runs (imported before anything else of the package): SIGINT or
SIGTERM while the interpreter imports numpy, fmpy, lxml ... (about a second) ends the command at once
with one line and the shell's status (130, 143), not a traceback (SIGINT) or a silent death
(SIGTERM). Nothing has been written yet, so nothing needs cleaning up. Only in the ``orchestrate``
command's own process (not a library user's, not a worker process it starts);
:func:`orchestrator.cli.main` replaces these handlers by its own when it starts."""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import FrameType

__all__ = ["exit_now", "guard"]


def exit_now(signum: int, frame: FrameType | None) -> None:
    """Say which signal stopped the command and exit with 128 + its number, at once."""
    os.write(2, f"orchestrate: {'terminated' if signum == signal.SIGTERM else 'interrupted'} by "
                f"{signal.Signals(signum).name}\n".encode())
    os._exit(128 + signum)


def guard() -> None:
    """Install :func:`exit_now` for SIGINT and SIGTERM in the ``orchestrate`` command's process."""
    import multiprocessing

    if (os.path.basename(sys.argv[0] if sys.argv else "") != "orchestrate"
            or threading.current_thread() is not threading.main_thread()
            or multiprocessing.parent_process() is not None):
        return
    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) in (signal.default_int_handler, signal.SIG_DFL):
            signal.signal(signum, exit_now)


guard()
