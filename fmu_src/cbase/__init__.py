# SPDX-License-Identifier: BSD-2-Clause
"""The project's lower C layer, below both the FMUs' shim (``fmu_src/toolchain/shim``) and the SSP
engine's C code (``orchestrator/native``): the official FMI 2.0 and 3.0 headers (``fmi/``, the one
place FMI types are defined), the portability layer (``platform.c``: libraries, files, locks, paths
on POSIX and Windows), and here the C compilers and the flags every product shares.

Why here (see also README.md): the top-level names are fixed, ``controller`` holds no FMI, and the
``orchestrator`` package's ``__init__`` loads the whole engine, which the FMU build must not import;
``fmu_src/__init__.py`` is empty, so the engine imports this package and nothing else of
``fmu_src`` (tests/test_layout.py: layer ``fmu_src.cbase`` imports nothing of ours, and C files
include only their own folder, this one and the layers below theirs).
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
from pathlib import Path

__all__ = ["FMI_HEADERS", "HERE", "MINGW", "PLATFORM_HEADERS", "PLATFORM_SOURCES", "REPRODUCIBLE_FLAGS",
           "REPRODUCIBLE_MINGW_FLAGS", "WARNINGS", "CompilerError", "c_compiler", "mingw"]

HERE = Path(__file__).resolve().parent
FMI_HEADERS = HERE / "fmi"  # the official FMI headers, with their licence
PLATFORM_SOURCES = ("platform.c",)
PLATFORM_HEADERS = ("platform.h",)
MINGW = "x86_64-w64-mingw32-gcc"
# No debug info, build id or symbol table, so the bytes depend only on source, compiler and flags.
WARNINGS = ("-std=c11", "-O2", "-g0", "-Wall", "-Wextra", "-Wno-format-truncation")
REPRODUCIBLE_FLAGS = (*WARNINGS, "-Wl,--build-id=none", "-s")
# Windows (mingw-w64): no time stamp in the PE header, the GCC runtime linked in.
REPRODUCIBLE_MINGW_FLAGS = (*WARNINGS, "-static-libgcc", "-s", "-Wl,--no-insert-timestamp")


class CompilerError(RuntimeError):
    """No C compiler, or one that does not run; the message says what to install."""


def c_compiler(purpose: str) -> tuple[str, str]:
    """The system C compiler (``$CC``, else ``cc``, else ``gcc`` from PATH) and its version line;
    ``purpose`` ("to build ...") completes the message when there is none."""
    for name in (os.environ.get("CC"), "cc", "gcc"):
        path = shutil.which(name) if name else None
        if path:
            return path, _version_line(path, "--version")
    raise CompilerError(f"no C compiler (CC, cc or gcc on PATH) {purpose}; install one, "
                        "e.g. apt-get install gcc")


def mingw(purpose: str) -> tuple[str, str]:
    """The mingw-w64 cross compiler for 64-bit Windows (``$MINGW_CC``, else
    x86_64-w64-mingw32-gcc) and its version; ``purpose`` completes the message when there is none."""
    name = os.environ.get("MINGW_CC") or MINGW
    path = shutil.which(name)
    if not path:
        raise CompilerError(f"no mingw-w64 cross compiler ({name}) {purpose}: install it "
                            "(Debian: apt-get install gcc-mingw-w64-x86-64, or 'make windows-tools' as root)")
    return path, _version_line(path, "-dumpfullversion")


@functools.cache
def _version_line(compiler: str, option: str) -> str:
    """The first line of ``compiler option`` (read once per compiler and process)."""
    try:
        version = subprocess.run([compiler, option], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as error:
        raise CompilerError(f"the C compiler {compiler} does not run: {error}") from error
    return version.stdout.partition("\n")[0].strip()
