"""The first thing ``orchestrate`` runs (imported before anything else of the package): SIGINT or
SIGTERM while the interpreter imports numpy, fmpy, lxml ... (about a second) ends the command at once
with one line and the shell's status (130, 143), not a traceback (SIGINT) or a silent death
(SIGTERM). Nothing has been written yet, so nothing needs cleaning up. Only in the ``orchestrate``
command's own process, as the console script or as ``python -m orchestrator`` (not a library
user's, not a worker process it starts); :func:`orchestrator.cli.main` replaces these handlers by
its own when it starts.

Only built-in modules are used before the handlers are in place (``_signal``, not ``signal``, which
imports ``enum``): every import before them is a moment a signal would still find Python's
defaults. What runs before this module cannot be covered by any code of the package: the
interpreter's initialization (SIGINT and SIGTERM kill the process silently until Python installs
its SIGINT handler, about 7 ms after exec; SIGTERM stays deadly until the guard) and ``site``,
whose ``.pth`` files import the editable install's finder (pathlib, re, urllib.parse: about 10 ms;
SIGINT there is a ``KeyboardInterrupt`` traceback). Measured from the parent's fork, polling
``/proc/PID/status`` (SigCgt) over 30 starts of ``orchestrate run`` on 2 shared cores at load 3:
SIGINT caught at a median 7 ms (5-14), the guard in place at a median 24 ms (18-35); with a plain
path ``.pth`` instead of the finder (``pip install -e . --config-settings editable_mode=compat``)
the guard is in place at 14 ms (9-19). The console script itself imports only ``sys`` before the
package, whose first import is this module: the guard follows ``site`` within about 1 ms.
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


def _dash_m_orchestrator(argv: list[str]) -> bool:
    """Whether the interpreter's own command line (``sys.orig_argv``) is ``python [options] -m
    orchestrator ...``: while the package is imported for ``-m``, ``sys.argv[0]`` is only ``-m``."""
    args = iter(argv[1:])
    for arg in args:
        if arg == "-m":
            return next(args, None) == "orchestrator"
        if arg.startswith("-m"):
            return arg == "-morchestrator"
        if arg in ("-X", "-W"):  # options that take the next argument
            next(args, None)
        elif arg == "-c" or arg == "-" or not arg.startswith("-"):  # a command, stdin or a script
            return False
    return False


def guard() -> None:
    """Install :func:`exit_now` for SIGINT and SIGTERM in the ``orchestrate`` command's process
    (the console script, or ``python -m orchestrator``): not in a process that multiprocessing
    started (a worker re-imports the command's script), nor in any other program that imports the
    package."""
    command = os.path.basename(sys.argv[0] if sys.argv else "") == "orchestrate"
    if not (command or _dash_m_orchestrator(getattr(sys, "orig_argv", []))):
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
