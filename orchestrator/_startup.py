"""The first thing ``orchestrate`` runs (imported before anything else of the package): SIGINT or
SIGTERM while the interpreter imports numpy, fmpy, lxml ... (about a second) ends the command at once
with one line and the shell's status (130, 143), not a traceback (SIGINT) or a silent death
(SIGTERM). Nothing has been written yet, so nothing needs cleaning up. Only in the ``orchestrate``
command's own process (not a library user's, not a worker process it starts);
:func:`orchestrator.cli.main` replaces these handlers by its own when it starts.

Only built-in modules are used before the handlers are in place (``_signal``, not ``signal``, which
imports ``enum``): every import before them is a moment a signal would still find Python's
defaults. What runs before this module (the interpreter's start-up, ``site``) cannot be covered.
"""

from __future__ import annotations

import _signal  # type: ignore[import-not-found]  # the C module behind signal (no stub)
import os
import sys

__all__ = ["exit_now", "guard"]

NAMES = {_signal.SIGINT: ("interrupted", "SIGINT"), _signal.SIGTERM: ("terminated", "SIGTERM")}


def exit_now(signum: int, frame: object) -> None:
    """Say which signal stopped the command and exit with 128 + its number, at once."""
    what, name = NAMES.get(signum, ("stopped", f"signal {signum}"))
    os.write(2, f"orchestrate: {what} by {name}\n".encode())
    os._exit(128 + signum)


def guard() -> None:
    """Install :func:`exit_now` for SIGINT and SIGTERM in the ``orchestrate`` command's process:
    not in a process that multiprocessing started (a worker re-imports the command's script)."""
    if os.path.basename(sys.argv[0] if sys.argv else "") != "orchestrate":
        return
    multiprocessing = sys.modules.get("multiprocessing")  # imported already in a child it started
    if multiprocessing is not None and multiprocessing.parent_process() is not None:
        return
    for signum in NAMES:
        try:
            if _signal.getsignal(signum) in (_signal.default_int_handler, _signal.SIG_DFL):
                _signal.signal(signum, exit_now)
        except ValueError:  # not the main thread
            return


guard()
