"""The scenario container's runtime: ``container.c``, a generic FMI 2.0 Co-Simulation library that
loads the FMUs unpacked in its resources and replays the plan ``orchestrate export`` wrote for it
(see the C file's header). Compiled with the system C compiler, and for 64-bit Windows with
mingw-w64, as the FMUs' shim is; its operating-system calls go through the shim's portability
layer (``fmu_src/toolchain/shim/platform.c``).

No Python in it: the embedded FMUs bring their own runtime (each project FMU starts its bundled
CPython through its shim where the host has none), so the container adds nothing to carry.
"""

from __future__ import annotations

import functools
import importlib.util
import subprocess
import tempfile
from pathlib import Path

from ..build import MINGW_FLAGS, BuildError, c_compiler, mingw

__all__ = ["CONTAINER_SOURCE", "compile_container"]

CONTAINER_SOURCE = Path(__file__).resolve().parent / "container.c"
SHIM_HEADERS = Path(__file__).resolve().parent.parent / "shim"  # fmi2_types.h, platform.h
PLATFORM_SOURCE = SHIM_HEADERS / "platform.c"
# Like the shim's flags: no debug info, build id or symbols, so the bytes depend only on source,
# compiler and flags; no contraction of a * b + c into a fused multiply-add, so a connection's
# factor * value + offset rounds as NumPy's does in the engine's master; symbols bound inside the
# library, so an embedded FMU's fmi2* functions never resolve to the container's.
FLAGS = tuple(
    "-std=c11 -O2 -fPIC -shared -fvisibility=hidden -ffp-contract=off -g0 -Wall -Wextra "
    "-Wno-format-truncation -Wl,--build-id=none -s -Wl,-Bsymbolic".split()
)
LIBS = ("-ldl", "-lm")


def fmi3_headers() -> Path:
    """The folder of the FMI 3.0 headers (``fmi3Functions.h``) FMPy ships, which the container's
    FMI 3.0 API is compiled against."""
    spec = importlib.util.find_spec("fmpy")
    folders = list(spec.submodule_search_locations or []) if spec else []
    for folder in folders:
        if (Path(folder) / "c-code" / "fmi3Functions.h").is_file():
            return Path(folder) / "c-code"
    raise BuildError("the FMI 3.0 headers (fmpy/c-code/fmi3Functions.h) are not installed: install fmpy")


@functools.cache
def compile_container(windows: bool = False) -> bytes:
    """The container library's bytes (``binaries/linux64/<modelIdentifier>.so``, FMI 2.0 and 3.0
    APIs; ``windows``: ``binaries/win64/<modelIdentifier>.dll``); BuildError when the compiler
    fails. Compiled once per process."""
    compiler = mingw() if windows else c_compiler()[0]
    flags = [*MINGW_FLAGS, "-ffp-contract=off"] if windows else FLAGS
    with tempfile.TemporaryDirectory(prefix="ftc_container_") as tmp:
        target = Path(tmp) / ("container.dll" if windows else "container.so")
        command = [compiler, *flags, f"-I{fmi3_headers()}", f"-I{SHIM_HEADERS}", "-o", str(target),
                   str(CONTAINER_SOURCE), str(PLATFORM_SOURCE), *LIBS[1 if windows else 0:]]
        result = subprocess.run(command, capture_output=True, text=True)
        if result.returncode != 0:
            raise BuildError(f"{CONTAINER_SOURCE}: {compiler} failed:\n{result.stderr.strip()}")
        return target.read_bytes()
