# SPDX-License-Identifier: BSD-2-Clause
"""The first thing ``orchestrate`` runs (imported before anything else of the package): SIGINT or
SIGTERM while the interpreter imports numpy, fmpy, lxml ... (about a second) ends the command at once
with one line and the shell's status (130, 143), not a traceback (SIGINT) or a silent death
(SIGTERM). Nothing has been written yet, so nothing needs cleaning up. Only in the ``orchestrate``
command's own process, started by the launcher (``python -P -m orchestrator``), typed as ``python
-m orchestrator`` or as pip's console script where no launcher is installed (not a library user's,
not a worker process it starts); :func:`orchestrator.cli.main` replaces these handlers by
its own when it starts.

Only built-in modules are used before the handlers are in place (``_signal``, not ``signal``, which
imports ``enum``): every import before them is a moment longer that a signal waits. What runs
before this module, the interpreter's initialization and ``site`` (whose ``.pth`` files import the
editable install's finder), no code of the package can cover: SIGINT and SIGTERM kill silently
until Python installs its SIGINT handler (about 7 ms after exec), SIGINT in ``site`` is a
``KeyboardInterrupt`` traceback, SIGTERM stays deadly until the guard. So the ``orchestrate``
command covers it from outside: ``make`` installs a small native launcher (orchestrator/launcher.c)
over pip's console script, which blocks both signals as its first action and execs ``python -P -m
orchestrator``. A signal meanwhile stays pending; :func:`guard` unblocks exactly those the launcher
held (``ORCHESTRATE_HELD_SIGNALS``, removed from the environment here so that no process the command
starts inherits it) once the handlers are in, and it is delivered to them. Measured from the
parent's Popen, polling ``/proc/PID/status`` over 30 starts of ``orchestrate run`` on 2 shared
cores at load 1: the launcher's mask (SigBlk) in place at 0.9 ms (0.9-3.1, the fork included),
the guard (SigCgt) and the unblocking at a median 22 ms (20-34); pip's console script: no mask,
the guard at 20 ms (17-21), a signal before it a silent death or a traceback. What nothing can
cover is the kernel's part of exec: a signal sent as soon as Popen returns reaches the launcher
before its first instruction (a silent death, as for any program; see launcher.c: within about
0.5 ms). Typed ``python -m orchestrator`` has no launcher: its guard follows ``site`` as the
console script's did.
"""

from __future__ import annotations

import _signal  # type: ignore[import-not-found]  # the C module behind signal (no stub)
import os
import sys

__all__ = ["exit_now", "guard", "numpy_loaded"]

HELD = "ORCHESTRATE_HELD_SIGNALS"  # set by the launcher: the signals it blocked, e.g. "2,15"
BLAS_THREADS = "OPENBLAS_NUM_THREADS"  # read by NumPy's OpenBLAS when it loads
BLAS_CHOICES = (BLAS_THREADS, "GOTO_NUM_THREADS", "OMP_NUM_THREADS")  # OpenBLAS obeys any, in this order
_blas_threads_set = False  # whether this module set BLAS_THREADS (numpy_loaded takes it back)
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


def _held_by_the_launcher() -> list[int]:
    """The signals the launcher (orchestrator/launcher.c) blocked before exec, named in
    ``ORCHESTRATE_HELD_SIGNALS``; the variable leaves the environment here, so that no process the
    command starts (Dask workers, tools) takes it for its own."""
    named = os.environ.pop(HELD, "").split(",")
    return [signum for signum in NAMES if str(signum) in named]


def guard() -> None:
    """Install :func:`exit_now` for SIGINT and SIGTERM in the ``orchestrate`` command's process
    (started by the launcher, or ``python -m orchestrator``): not in a process that multiprocessing
    started (a worker re-imports the command's script), nor in any other program that imports the
    package. Then unblock what the launcher held, handlers or not (a signal sent meanwhile is
    delivered now: one line, 130 or 143)."""
    held = _held_by_the_launcher()
    try:
        _install()
    finally:
        if held:
            _signal.pthread_sigmask(_signal.SIG_UNBLOCK, held)


def _install() -> None:
    """The handlers of :func:`guard`, where they belong."""
    command = os.path.basename(sys.argv[0] if sys.argv else "") == "orchestrate"
    if not (command or _dash_m_orchestrator(getattr(sys, "orig_argv", []))):
        return
    multiprocessing = sys.modules.get("multiprocessing")  # imported already in a child it started
    if multiprocessing is not None and multiprocessing.parent_process() is not None:
        return
    _one_blas_thread()
    for signum in NAMES:
        try:
            if _signal.getsignal(signum) in (_signal.default_int_handler, _signal.SIG_DFL):
                _signal.signal(signum, exit_now)
        except ValueError:  # not the main thread
            return


def _one_blas_thread() -> None:
    """NumPy's OpenBLAS starts a thread per core when it loads, and those threads spin before they
    sleep: 0.12 s of CPU in every ``orchestrate run`` on 2 cores (start-up 0.35 -> 0.23 s), more
    with more cores, for nothing: the command multiplies no matrices large enough to share. So its
    own process loads OpenBLAS with one thread, unless the user chose a number (in any of the
    variables OpenBLAS reads)."""
    global _blas_threads_set
    if not any(name in os.environ for name in BLAS_CHOICES) and "numpy" not in sys.modules:
        os.environ[BLAS_THREADS] = "1"
        _blas_threads_set = True


def numpy_loaded() -> None:
    """NumPy is loaded: the variable :func:`_one_blas_thread` set leaves the environment, so that
    the processes the command starts (Dask workers, other tools) get the user's."""
    global _blas_threads_set
    if _blas_threads_set:
        os.environ.pop(BLAS_THREADS, None)
        _blas_threads_set = False


guard()
