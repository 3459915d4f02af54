# SPDX-License-Identifier: BSD-2-Clause
"""Build the project's FMUs with pythonfmu, reproducibly and safe to load side by side.

All pythonfmu FMUs in one process share one interpreter and one module cache, and each FMU's
``resources`` folder goes to ``sys.path[0]``. So two FMUs that bundle modules of the same name
see whichever was imported first. To rule that out, every FMU bundles its script and the code it
needs (modules of ``fmu_src`` and ``controller``) as a package ``_ftc_<model>_<hash>`` (the script
as ``fmu_src/<script>.py`` in it), where ``<hash>`` is a digest of every bundled byte;
pythonfmu's entry ``ftc_<model>_<hash>.py`` imports the model's class from there (:func:`_entry`).
Only the script's own ``from fmu_src... / from controller... import`` lines are rewritten (with ``ast``);
bundled modules must import their own package relatively, and the other local package with a
module-level ``from ... import`` (rewritten likewise: ``fmu_src.controller_core`` uses ``controller``).

Each FMU carries its own CPython runtime for each platform, and no third-party package (a bundled
module that imports one is refused): ``binaries/linux64`` Debian 12's (``fmu_src/toolchain/runtime.py``:
libpython, the two libraries it links and the standard-library modules the FMU imports when it runs,
from pinned packages), ``binaries/win64`` python.org's embeddable CPython 3.11 and the MSVC runtime
(``fmu_src/toolchain/runtime_win64.py``, the same standard-library modules). pythonfmu's binaries do
not start a Python of their own, so the build compiles ``fmu_src/toolchain/shim/`` in front of each:
with the system C compiler into ``binaries/linux64/<model>.so``, and cross-compiled with mingw-w64
into ``binaries/win64/<model>.dll``, pythonfmu's binary kept beside it as ``<model>_pythonfmu.so`` /
``.dll``; the shim starts the bundled runtime when the host has no Python (see the shim's
header). C extension modules are compiled for both platforms as well.

The archive is normalized afterwards: GUID derived from a digest of every bundled byte, no
generation date, sorted entries with fixed timestamps, licences under ``documentation/licenses``.
Nothing of the build machine (no path) goes in. Rebuilding the same sources with the same
compiler and runtime packages gives identical bytes, whichever Python (3.10 to 3.13) runs the
build: the bytecode is compiled by the bundled runtime itself (``fmu_src/toolchain/shim/bundled_python.c``).

Command line: ``python -m fmu_src.toolchain`` (``fmu_src/toolchain/__main__.py``; FMI 3.0
variants: ``fmu_src.toolchain.fmi3``, built on this module).
"""

from __future__ import annotations

import ast
import contextlib
import functools
import hashlib
import importlib.metadata
import io
import lzma
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
import zipfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import pythonfmu
from pythonfmu import FmuBuilder

from .. import cbase
from . import runtime_win64, stamps
from .controller_doc import controller_documentation
from .licences import documentation, generation_tool
from .runtime import (
    LIBRARIES,
    Runtime,
    RuntimeBundleError,
    compile_bytecode,
    ensure_runtime,
    keep,
    measured_imports,
    read_kept,
    runtime_members,
)
from .variable_table import TABLE_SOURCE, variable_table

__all__ = ["EXTENSIONS", "FMU_SCRIPTS", "PLATFORM_NAMES", "BuildError", "build_all", "build_fmu",
           "build_inputs", "build_sources", "buildable_platforms", "c_compiler", "compile_extension",
           "compile_in_place", "compile_shared", "fmu_current", "fmu_sources", "prune_kept"]

REPO_ROOT = Path(__file__).resolve().parents[2]
LOCAL_PACKAGES = ("fmu_src", "controller")
# Model name -> script in fmu_src/ (the model names are a contract with the scenarios).
FMU_SCRIPTS = {
    "Reference": "reference.py",
    "FixedTimeController": "fixed_time_controller.py",
    "FixedTimeController1": "fixed_time_controller1.py",
    "FixedTimeController3": "fixed_time_controller3.py",
    "FixedTimeController4": "fixed_time_controller4.py",
    "Actuator": "actuator.py",
    "Example1Plant": "example1_plant.py",
    "PendulumPlant": "pendulum_plant.py",
    "ManipulatorPlant": "manipulator_plant.py",
}
BUILD_OPTIONS = {"canGetAndSetFMUstate": True}
# Bump when the staging or normalization below changes the archive layout.
BUILD_FORMAT = "11"
SHIM_DIR = Path("fmu_src", "toolchain", "shim")  # relative to the source root
# The shim laid out as the Modelica Reference FMUs lay theirs out (shim.h says what each file holds).
# xz/: XZ Embedded's decoder (public domain / 0BSD, xz/README.md), for the runtime's .xz members (unpack.c).
XZ_SOURCES = ("xz/xz_crc32.c", "xz/xz_crc64.c", "xz/xz_dec_stream.c", "xz/xz_dec_lzma2.c", "xz/xz_dec_bcj.c")
SHIM_SOURCES = ("fmi2_functions.c", "guard.c", "cosimulation.c", "loader.c", "pool.c", "log.c", "resources.c",
                "start_python.c", "unpack.c", *XZ_SOURCES)
SHIM_HEADERS = ("shim.h", "start_python.h", "fmi2_calls.h", "description.h", "fmi3.h", "unpack.h", "xz/xz.h",
                "xz/xz_private.h", "xz/xz_config.h", "xz/xz_lzma2.h", "xz/xz_stream.h")
XZ_LICENSE = Path("fmu_src", "toolchain", "shim", "xz", "LICENSE")  # relative to the source root
XZ_LICENSE_NAME = "xz-embedded-COPYING.txt"
XZ_DEFINES = ("XZ_DEC_X86", "XZ_USE_CRC64")  # what the decoder is compiled with: the x86 BCJ filter, CRC64
# Shim sources no variant's -D changes (the decoder, the platform layer): compiled with the shim's
# flags alone, so that the FMI 2.0 shim, the FMI 3.0 shims and the clocked twins share their
# objects (the cold build compiled each of them four times per platform: 7 s of CPU).
VARIANT_FREE = ("unpack.c", *XZ_SOURCES, *cbase.PLATFORM_SOURCES)
CBASE_DIR = Path("fmu_src", "cbase")  # the lower C layer (platform.c, the FMI headers), relative to the root
# The shared flags (fmu_src/cbase: no debug info, build id or symbol table, so the bytes depend only
# on source, compiler and flags); the runtime's libraries are found by soname through
# $ORIGIN/python/lib (see the shim's header).
SHIM_FLAGS = (*cbase.REPRODUCIBLE_FLAGS, "-fPIC", "-shared", "-fvisibility=hidden", "-Wl,--enable-new-dtags",
              "-Wl,-rpath,$ORIGIN/python/lib", *(f"-D{d}" for d in XZ_DEFINES))
SHIM_LIBS = ("-ldl", "-pthread")
# The Windows shim: mingw-w64, linked against the system's KERNEL32 and msvcrt.dll only; no time
# stamp in the PE header, so the bytes depend only on sources, compiler and flags.
MINGW_FLAGS = (*cbase.REPRODUCIBLE_MINGW_FLAGS, "-shared", *(f"-D{d}" for d in XZ_DEFINES))
WIN_PYCONFIG = Path("fmu_src", "toolchain", "shim", "win64", "pyconfig.h")  # relative to the source root
# Windows extension modules: no C runtime of their own, python3.dll (stable ABI) and the Universal
# C Runtime imported as python311.dll imports it: only its exact math (sqrt, fabs, floor, fmod;
# controller/fmath.h gives exp, sin, cos and pow, the same bits as on Linux) and errno, and memcpy
# from VCRUNTIME140.dll (shipped; python311.dll has loaded it before any extension).
WIN_EXTENSION_FLAGS = tuple(
    "-std=c11 -O2 -shared -g0 -Wall -Wextra -ffp-contract=off "
    "-DPy_LIMITED_API=0x03080000 -s -Wl,--no-insert-timestamp -Wl,--disable-auto-import "
    "-Wl,--disable-runtime-pseudo-reloc -nostdlib -Wl,-e,0".split()
)
WIN_EXTENSION_SUFFIX = ".pyd"
WIN_IMPORTS = {
    "api-ms-win-crt-math-l1-1-0.dll": ("sqrt", "fabs", "floor", "fmod"),
    "api-ms-win-crt-runtime-l1-1-0.dll": ("_errno",),
    "VCRUNTIME140.dll": ("memcpy", "memmove", "memset"),
}
# description.h's IDENTITY_FILE: the resources folder names its FMU (GUID / instantiation token), so that
# the shim never runs another FMU's model from a resource location the host gives it
IDENTITY_FILE = "resources/fmu_identity.txt"
PLATFORMS = (("linux64", ".so"), ("win64", ".dll"))  # FMI 2.0 platform folders, binary suffix
PLATFORM_NAMES = tuple(name for name, _ in PLATFORMS)
# The bundled runtime as a command (for the build's bytecode and standard-library closure).
LAUNCHER_SOURCE = "bundled_python.c"
LAUNCHER_FLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra")
# The build's own code (fmu_src/): a change to it rebuilds every FMU.
BUILD_CODE = ("build.py", "fmi3.py", "clocked.py", "controller_doc.py", "runtime.py", "runtime_pins.txt",
              "runtime_win64.py", "runtime_pins_win64.txt", "licences.py", "variable_table.py")
# The runtime cache's folders of bytes a build made and keeps for the next (objects, runtime members,
# deflated and xz-compressed members), pruned to KEPT_BUDGET bytes after a build (prune_kept).
KEPT_FOLDERS = ("objects", "members", "deflated", "xz")
KEPT_BUDGET = 1 << 30  # about six full builds' (one uses about 160 MB, most of it runtime members)
KEPT_GRACE = 3600.0  # seconds: entries used more recently stay, whatever the budget

# C extension modules bundled with the FMUs that import them (dotted name -> C source, relative to
# the source root): built against the runtime's headers for the stable ABI, so that one binary
# loads in the FMU's runtime and in a host's Python alike. -ffp-contract=off: no fused
# multiply-add, so the compiled arithmetic rounds as Python's does (see fmu_src/models/_dopri.c).
EXTENSIONS = {"fmu_src.models._dopri": Path("fmu_src", "models", "_dopri.c"),
              "fmu_src.models._signals": Path("fmu_src", "models", "_signals.c"),
              "controller._law": Path("controller", "_law.c"),
              "controller._fmath": Path("controller", "_fmath.c")}
# The headers every extension module's source includes (relative to the source root): fmath.h and
# its fmath_pow.h, the elementary functions that give the same bits on every platform
# (controller/fmath.py), and direct_calls.h, the C entries the shim calls.
EXTENSION_HEADERS = (Path("controller", "fmath.h"), Path("controller", "fmath_pow.h"),
                     Path("controller", "direct_calls.h"))
FMATH_MODULE = "controller.fmath"  # musl's functions: an FMU that bundles them carries their licence
FMATH_LICENSE = Path("controller", "fmath-LICENSE.txt")
EXTENSION_SUFFIX = ".abi3.so"
EXTENSION_FLAGS = (
    "-std=c11 -O2 -fPIC -shared -fvisibility=hidden -g0 -Wall -Wextra -ffp-contract=off "
    "-DPy_LIMITED_API=0x03080000 -Wl,--build-id=none -s".split()
)
# pythonfmu's modules that only build FMUs (its command line, FmuBuilder, the CSV builder, the
# deployment helpers): left out of every FMU, whose __init__ then no longer imports the builder.
PYTHONFMU_BUILD_ONLY = ("__main__.py", "builder.py", "csvbuilder.py", "deploy.py", "osutil.py")
# Lines of pythonfmu's run-time modules replaced in the FMU's copy (file -> line -> replacement):
# the builder's import; the per-instance uuid1(), read only by to_xml at build time, which in the
# bundled Linux runtime (no _uuid: it needs libuuid) ran `ip link` in a child process of the host
# at the first instantiation (uuid.getnode); and the imports only to_xml uses (xml.etree, datetime,
# uuid with platform, an unused pathlib with urllib.parse and ipaddress), made where to_xml runs:
# 27 modules and pyexpat/_elementtree on Windows that every FMU carried and every host loaded.
_LAZY_XML = (
    "def Element(*args, **kwargs):  # fixed-time-cosim: xml.etree only when a description is written\n"
    "    from xml.etree.ElementTree import Element as make\n"
    "    return make(*args, **kwargs)\n\n\n"
    "def SubElement(*args, **kwargs):\n"
    "    from xml.etree.ElementTree import SubElement as make\n"
    "    return make(*args, **kwargs)\n"
)
PYTHONFMU_LINES = {
    "__init__.py": {"from .builder import FmuBuilder\n": ""},
    "fmi2slave.py": {"        self.guid = uuid1()\n":
                     "        self.guid = None  # the FMU's GUID is the build's (fixed-time-cosim)\n",
                     "import datetime\n": "",
                     "        t = datetime.datetime.now(datetime.timezone.utc)\n":
                     "        import datetime\n\n        t = datetime.datetime.now(datetime.timezone.utc)\n",
                     "from pathlib import Path\n": "",
                     "from uuid import uuid1\n": "",
                     "from xml.etree.ElementTree import Element, SubElement\n": _LAZY_XML},
    "variables.py": {"from xml.etree.ElementTree import Element, SubElement\n": _LAZY_XML},
}
CLASS_LINE = re.compile(r"^class (\w+)\(\s*Fmi2Slave\s*\)\s*:", re.MULTILINE)  # the script's one model class
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
DEFLATE_KEPT = 64 << 10  # members this large (the runtimes' libraries, zips, DLLs) are deflated once
# The two interpreter libraries, by far the runtimes' largest files, go into the FMU xz-compressed
# (<name>.xz, stored, not deflated again): the x86 BCJ filter and LZMA2 at preset 6 take
# libpython3.11.so.1.0 from 7.74 MB to 1.87 MB and python311.dll from 5.80 MB to 1.71 MB (deflate:
# 2.59 and 2.30 MB). The shim decodes one only when it must load the bundled interpreter (unpack.c).
# Preset 6's 8 MiB dictionary holds either file whole, and 8 MiB is all the decoder allocates
# (unpack.h's FTC_XZ_DICT_MAX); preset 9e gave 2 KB more in 1.3x the time (6.2 s of CPU for both
# files against 4.75 + 3.1 s, once per cold build: the result is kept).
XZ_MEMBERS = ("binaries/linux64/python/lib/libpython3.11.so.1.0", "binaries/win64/python/python311.dll")
XZ_SUFFIX = ".xz"
XZ_DICT = 8 << 20
XZ_FILTERS = ({"id": lzma.FILTER_X86},
              {"id": lzma.FILTER_LZMA2, "preset": 6, "dict_size": XZ_DICT})
XZ_LIMIT = 64 << 20  # unpack.h's FTC_XZ_LIMIT: the shim refuses to decode more
GUID_NAMESPACE = uuid.UUID("5b0f3a52-4c1e-4d59-9a4e-2f6f1c1e7a10")


class BuildError(RuntimeError):
    """An FMU cannot be built from these sources; the message names the file."""


@dataclass(frozen=True)
class Bundle:
    """What one FMU carries: its script, the local modules it needs and its run-time imports."""

    model: str
    script: Path
    modules: dict[str, Path]  # dotted name (e.g. "controller.law") -> source file
    third_party: frozenset[str]  # top-level names of non-local, non-stdlib imports
    extensions: dict[str, Path]  # dotted name -> C source of the extension modules it imports

    def digest(self, native: str) -> str:
        """SHA-256 over everything that ends up in the archive (sources, pythonfmu version, format,
        and ``native``: a digest of the compiled shim and of the bundled runtime's members)."""
        h = hashlib.sha256()
        options = repr(sorted(BUILD_OPTIONS.items()))
        for part in (BUILD_FORMAT, pythonfmu.__version__, self.model, options, native):
            h.update(part.encode() + b"\0")
        h.update(self.script.read_bytes() + b"\0")
        for name in sorted(self.modules):
            h.update(name.encode() + b"\0" + self.modules[name].read_bytes() + b"\0")
        for name in sorted(self.extensions):
            h.update(name.encode() + b"\0" + self.extensions[name].read_bytes() + b"\0")
        return h.hexdigest()


def _is_local(module: str | None) -> bool:
    return module is not None and module.split(".")[0] in LOCAL_PACKAGES


def _parse(path: Path) -> ast.Module:
    try:
        return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except (OSError, SyntaxError) as error:
        raise BuildError(f"{path}: cannot read or parse: {error}") from error


def _module_file(root: Path, name: str) -> Path:
    path = root.joinpath(*name.split(".")).with_suffix(".py")
    if not path.is_file():
        raise BuildError(f"module {name} not found at {path}")
    return path


def collect_bundle(model: str, root: Path = REPO_ROOT) -> Bundle:  # noqa: C901 (one walk of the import graph)
    """The script of ``model`` and the closure of local modules it imports, checked with ``ast``."""
    if model not in FMU_SCRIPTS:
        raise BuildError(f"unknown FMU {model!r}; known: {', '.join(FMU_SCRIPTS)}")
    script = root / "fmu_src" / FMU_SCRIPTS[model]
    if not script.is_file():
        raise BuildError(f"FMU script for {model} not found: {script}")
    third_party: set[str] = set()
    pending: list[str] = []
    for node in ast.walk(_parse(script)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _is_local(alias.name):
                    raise BuildError(f"{script}:{node.lineno}: use 'from {alias.name} import ...'")
                third_party.add(alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                raise BuildError(f"{script}:{node.lineno}: the FMU script must use absolute imports")
            assert node.module is not None  # an absolute "from X import" always names X
            if _is_local(node.module):
                pending.append(node.module)
            else:
                third_party.add(node.module.split(".")[0])

    modules: dict[str, Path] = {}
    extensions: dict[str, Path] = {}
    while pending:
        name = pending.pop()
        if name in modules or name in extensions:
            continue
        if name in EXTENSIONS:
            extensions[name] = root / EXTENSIONS[name]
            if not extensions[name].is_file():
                raise BuildError(f"C source of the extension module {name} not found: {extensions[name]}")
            continue
        path = modules[name] = _module_file(root, name)
        package = name.rpartition(".")[0]
        for node in ast.walk(_parse(path)):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if _is_local(alias.name):
                        raise BuildError(
                            f"{path}:{node.lineno}: bundled modules must import {alias.name} relatively"
                        )
                    third_party.add(alias.name.split(".")[0])
            elif isinstance(node, ast.ImportFrom):
                if node.level == 0:
                    assert node.module is not None  # an absolute "from X import" always names X
                    if _is_local(node.module) and node.module.split(".")[0] == name.split(".")[0]:
                        raise BuildError(
                            f"{path}:{node.lineno}: bundled modules must import {node.module} relatively"
                        )
                    if _is_local(node.module):  # the other local package: rewritten by _stage
                        pending.append(node.module)
                    else:
                        third_party.add(node.module.split(".")[0])
                elif node.level == 1:
                    targets = [node.module] if node.module else [alias.name for alias in node.names]
                    pending.extend(f"{package}.{target}" for target in targets)
                else:
                    raise BuildError(
                        f"{path}:{node.lineno}: relative imports beyond the package cannot be bundled"
                    )
    ignored = set(sys.stdlib_module_names) | {"__future__", "pythonfmu"}
    return Bundle(model, script, modules, frozenset(third_party - ignored), extensions)


def c_compiler() -> tuple[str, str]:
    """The system C compiler and its version line (fmu_src/cbase.c_compiler)."""
    try:
        return cbase.c_compiler("to build the FMI shim binaries/linux64/<model>.so")
    except cbase.CompilerError as error:
        raise BuildError(str(error)) from error


def mingw() -> str:
    """The mingw-w64 cross compiler for 64-bit Windows (fmu_src/cbase.mingw)."""
    try:
        return cbase.mingw("to build binaries/win64")[0]
    except cbase.CompilerError as error:
        raise BuildError(str(error)) from error


def _mingw_version() -> str:
    """The cross compiler's version (a new one rebuilds the FMUs, as a new system compiler does);
    'none' where there is none (only linux64 can then be built)."""
    try:
        return cbase.mingw("")[1]
    except cbase.CompilerError:
        return "none"


def _objects(work: Path, runtime: Runtime, flags: Sequence[str], sources: Sequence[str], what: Path,
             windows: str = "", plain: Sequence[str] = ()) -> tuple[str, list[str | Path], list[bytes]]:
    """Compile each of ``sources`` (in ``work``) to an object against the runtime's headers (with
    the Windows pyconfig.h for ``windows``), each once for the same bytes of it and of the headers
    beside it (nine FMUs share one shim's objects); those also in ``plain`` with the shim's flags
    without a variant's -D (:data:`VARIANT_FREE`). The compiler, the inputs every step shares,
    and the objects' bytes (also written beside their sources)."""
    compiler = mingw() if windows else c_compiler()[0]
    tree: list[str | Path] = []
    if windows:
        headers, headers_digest = _win_headers(runtime.include_dirs[0], REPO_ROOT / WIN_PYCONFIG,
                                               runtime.root.parent)
        includes, tree = [f"-I{headers}"], [f"include\0{headers_digest}"]
    else:
        includes = [f"-I{d}" for d in runtime.include_dirs]
    version = _mingw_version() if windows else c_compiler()[1]
    header_files = sorted(p for p in work.rglob("*.h") if p.is_file())
    here = Path(__file__).resolve().parent  # the build's code and the runtimes' pins
    common: list[str | Path] = [version, *(here / n for n in BUILD_CODE), *tree,
                                *(f"{p.relative_to(work)}\0{stamps.file_digest(p)}" for p in header_files)]
    objects = []
    base = MINGW_FLAGS if windows else SHIM_FLAGS  # for ``plain``: a shim variant's flags minus its -D
    for source in sources:
        own = base if source in plain else flags
        command = [compiler, *own, *includes, "-c", "-o", f"{source}.o", source]
        objects.append(_kept(runtime, work, command, f"{source}.o", what,
                             [*common, _relative(command, work), work / source]))
    for source, data in zip(sources, objects, strict=True):
        (work / f"{source}.o").write_bytes(data)
    return compiler, common, objects


@functools.cache
def _win_headers(include: Path, pyconfig: Path, cache: Path) -> tuple[Path, str]:
    """The runtime's Python headers with the Windows pyconfig.h (Debian's dispatches on
    ``__linux__``, and Python.h finds the one beside it first), and their digest: one copy per
    runtime and pyconfig.h in ``cache/win64-include``, hashed once per process. Each compile
    copied and hashed the 330 headers itself: 13 000 of a cold build's 19 000 new files."""
    own = include / "pyconfig.h"
    files = sorted(p for p in include.rglob("*") if p.is_file() and p != own)
    digest = stamps.digest(*(f"{p.relative_to(include)}\0{stamps.file_digest(p)}" for p in files),
                           f"pyconfig.h\0{stamps.file_digest(pyconfig)}")

    def make(folder: Path) -> None:
        shutil.copytree(include, folder)
        shutil.copyfile(pyconfig, folder / "pyconfig.h")

    return _made_once(cache / "win64-include", digest, make), digest


def _made_once(folder: Path, digest: str, make: Callable[[Path], None]) -> Path:
    """``folder/<digest>``, made by ``make`` (given a folder name that does not exist yet) unless it
    is there: made under a temporary name and renamed, so that a build beside this one sees all of
    it or nothing. Entries of other digests (an older runtime's) are removed, and half-made ones
    older than :data:`KEPT_GRACE` (a build killed while making one: 2 MB of headers each)."""
    target = folder / digest[:32]
    if target.is_dir():
        return target
    folder.mkdir(parents=True, exist_ok=True)
    partial = folder / f".{target.name}.{os.getpid()}"
    shutil.rmtree(partial, ignore_errors=True)
    make(partial)
    try:
        partial.rename(target)
    except OSError:  # made meanwhile by a build beside this one
        shutil.rmtree(partial, ignore_errors=True)
        if not target.is_dir():
            raise
    dead = time.time() - KEPT_GRACE
    for entry in folder.iterdir():
        with contextlib.suppress(FileNotFoundError):  # removed by a build beside
            if entry.name != target.name and (not entry.name.startswith(".") or entry.stat().st_mtime < dead):
                shutil.rmtree(entry, ignore_errors=True)
    return target


def _compile(work: Path, runtime: Runtime, flags: Sequence[str], sources: Sequence[str],
             libraries: Sequence[str], what: Path, windows: str = "", plain: Sequence[str] = (),
             archives: Sequence[Path] = ()) -> bytes:
    """Compile ``sources`` (in ``work``) into a shared object against the runtime's headers; its
    bytes (the same for the same sources, compiler, flags and runtime). ``what`` names the sources
    in the error. ``windows``: the DLL's file name, cross-compiled with mingw-w64 against the same
    headers with the Windows pyconfig.h. ``archives``: the static libraries ``libraries`` link from
    outside ``work`` (their bytes are part of what is kept)."""
    # Content-addressed, in two steps: the objects (_objects), then the link into the named
    # library; the build is reproducible, so a kept product is the one it would make.
    compiler, common, _ = _objects(work, runtime, flags, sources, what, windows, plain)
    out = windows or "out.so"
    command = [compiler, *flags, "-o", out, *(f"{source}.o" for source in sources), *libraries]
    return _kept(runtime, work, command, out, what,
                 [*common, _relative(command, work), *(work / f"{source}.o" for source in sources),
                  *(work / lib for lib in sorted(os.listdir(work)) if lib.endswith(".a")), *archives])


def _relative(command: Sequence[str], work: Path) -> str:
    """A command with ``work`` named '.' (what the compiler makes does not depend on the folder)."""
    return repr([str(part).replace(str(work), ".") for part in command])


def _kept(runtime: Runtime, work: Path, command: list[str], out: str, what: Path,
          inputs: Sequence[str | Path]) -> bytes:
    """The bytes ``command`` (run in ``work``) writes to ``out``: kept in the runtime's cache under
    the digest of ``inputs``, made where not kept yet."""
    key = stamps.digest(*inputs)
    kept = runtime.root.parent / "objects" / key
    known = read_kept(kept)
    if known is not None:
        return known
    result = subprocess.run(command, cwd=work, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"{what}: {command[0]} failed:\n{result.stderr.strip()}")
    binary = (work / out).read_bytes()
    keep(kept, binary)
    return binary


def _shim_work(root: Path, where: Path, sources: Sequence[str], defines: Sequence[str],
               windows: str) -> tuple[Path, list[str]]:
    """The shim's work folder under ``where`` holding ``sources`` and the headers, and its flags."""
    work = where / ("shim-win64" if windows else "shim")
    work.mkdir(parents=True, exist_ok=True)
    shim = root / SHIM_DIR
    for source in shim_files(root, sources):  # one folder (and xz/): the includes name files only
        if not source.is_file():
            raise BuildError(f"FMI shim source not found: {source}")
        target = work / (source.relative_to(shim) if source.is_relative_to(shim) else source.name)
        target.parent.mkdir(exist_ok=True)
        _place(source, target)
    return work, [*(MINGW_FLAGS if windows else SHIM_FLAGS), *(f"-D{d}" for d in defines)]


def _place(source: Path, target: Path) -> None:
    """``source`` at ``target`` for the compiler to read: a hard link where both are on one file
    system (no new inode: a cold build placed 3 800 shim files, and creating inodes was a fifth
    of its CPU on a busy ext4), else a copy. ``target`` is unlinked first, so that nothing is ever
    written through a link into the source tree."""
    target.unlink(missing_ok=True)
    try:
        os.link(source, target)
    except OSError:  # another file system (a tmpfs TMPDIR), or links not allowed
        shutil.copyfile(source, target)


def shim_files(root: Path, sources: Sequence[str] = SHIM_SOURCES) -> list[Path]:
    """The files the shim is compiled from: ``sources`` and the headers of ``fmu_src/toolchain/shim``,
    and the lower C layer's (``fmu_src/cbase``: platform.c, the official FMI headers)."""
    layer = root / CBASE_DIR
    return [*(root / SHIM_DIR / n for n in (*sources, *SHIM_HEADERS)),
            *(layer / n for n in (*cbase.PLATFORM_SOURCES, *cbase.PLATFORM_HEADERS)),
            *(layer / "fmi" / h.name for h in sorted(cbase.FMI_HEADERS.glob("*.h")))]


def shim_digest(root: Path, runtime: Runtime, where: Path, sources: Sequence[str] = SHIM_SOURCES,
                defines: Sequence[str] = (), windows: str = "") -> str:
    """A digest of the shim's compiled objects (all but the per-FMU variable table): what the
    FMU's GUID is made from, since the table is made from the model description that holds it.
    The same for the same code: a changed comment leaves it, a changed message changes it."""
    work, flags = _shim_work(root, where, sources, defines, windows)
    sources = [*sources, *cbase.PLATFORM_SOURCES]
    _, _, objects = _objects(work, runtime, flags, sources, root / SHIM_DIR, windows, VARIANT_FREE)
    return stamps.digest(*(hashlib.sha256(data).hexdigest() for data in objects))


def compile_shim(root: Path, runtime: Runtime, where: Path, description: bytes,
                 sources: Sequence[str] = SHIM_SOURCES, defines: Sequence[str] = (),
                 windows: str = "", constants: dict[str, int] | None = None) -> bytes:
    """Compile the FMI shim (``sources`` of ``fmu_src/toolchain/shim``, ``-D`` ``defines``) against
    the runtime's headers, with the variable table of the model description ``description``
    (:func:`variable_table`, an object of its own, with ``constants``: name -> value of the FMU's
    ``const uint32_t`` values the shim's sources name by -D, fmi3.h) linked in; returns the shared
    object's bytes (the same for the same sources, description, compiler and runtime).
    ``windows``: the DLL's name (``<model>.dll``), cross-compiled for 64-bit Windows instead."""
    work, flags = _shim_work(root, where, sources, defines, windows)
    try:
        table = variable_table(description)
        if constants:
            table += b"#include <stdint.h>\n" + "".join(
                f"const uint32_t {name} = {value}u;\n" for name, value in sorted(constants.items())).encode()
        (work / TABLE_SOURCE).write_bytes(table)
    except (ValueError, ElementTree.ParseError) as error:
        raise BuildError(f"the variable table of the shim: {error}") from error
    libraries = () if windows else SHIM_LIBS
    return _compile(work, runtime, flags, [*sources, *cbase.PLATFORM_SOURCES, TABLE_SOURCE], libraries,
                    root / SHIM_DIR, windows, VARIANT_FREE)


def _extension_work(source: Path, work: Path, root: Path) -> None:
    """``work`` made, holding ``source`` and :data:`EXTENSION_HEADERS` from ``root``."""
    work.mkdir(parents=True)
    _place(source, work / source.name)
    for header in EXTENSION_HEADERS:
        _place(root / header, work / header.name)


def compile_extension(source: Path, runtime: Runtime, where: Path, root: Path = REPO_ROOT) -> bytes:
    """Compile the C extension module ``source`` (with the headers of ``root``) for the stable ABI
    against the runtime's headers; the bytes of its ``<name>.abi3.so``."""
    work = where / f"ext_{source.stem}"
    _extension_work(source, work, root)
    return _compile(work, runtime, EXTENSION_FLAGS, [source.name], ["-lm"], source)


def compile_extension_win64(source: Path, runtime: Runtime, windows: runtime_win64.WinRuntime,
                            where: Path, root: Path = REPO_ROOT) -> bytes:
    """Compile the C extension module ``source`` for 64-bit Windows (stable ABI, python3.dll;
    its libm the Universal C Runtime's, as Python's math module on Windows); the bytes of its
    ``<name>.pyd``."""
    work = where / f"ext_win64_{source.stem}"
    _extension_work(source, work, root)
    imports = _win_import_libraries(runtime.root.parent)
    libraries = [str(windows.embed / "python3.dll"), f"-L{imports}",
                 *(f"-limports{number}" for number in range(len(WIN_IMPORTS))), "-lkernel32"]
    return _compile(work, runtime, WIN_EXTENSION_FLAGS, [source.name], libraries, source,
                    f"{source.stem}{WIN_EXTENSION_SUFFIX}", archives=sorted(imports.glob("*.a")))


@functools.cache
def _win_import_libraries(cache: Path) -> Path:
    """The import libraries of :data:`WIN_IMPORTS` (``libimports<n>.a``, one per DLL, by mingw's
    dlltool), made once per set of imports and compiler in ``cache/win64-imports``. Each extension's
    compile ran dlltool three times (and its assembler): 78 dlltool and 150 assembler runs in a
    cold build, most of them for objects already kept."""
    tool = Path(mingw()).with_name(Path(mingw()).name.replace("gcc", "dlltool"))
    definitions = [f"LIBRARY {dll}\nEXPORTS\n" + "\n".join(symbols) + "\n"
                   for dll, symbols in WIN_IMPORTS.items()]

    def make(folder: Path) -> None:
        folder.mkdir()
        for number, text in enumerate(definitions):
            definition = folder / f"imports{number}.def"
            definition.write_text(text)
            # dlltool leaves an empty temporary file behind on every call: keep it in this folder
            library = folder / f"libimports{number}.a"
            result = subprocess.run([str(tool), "-d", str(definition), "-l", str(library)],
                                    capture_output=True, text=True, env={**os.environ, "TMPDIR": str(folder)})
            if result.returncode != 0:
                raise BuildError(f"{tool} failed:\n{result.stderr.strip()}")

    return _made_once(cache / "win64-imports", stamps.digest(_mingw_version(), *definitions), make)


def compile_shared(root: Path = REPO_ROOT, platforms: Sequence[str] = PLATFORM_NAMES) -> None:
    """Compile what the FMUs share, once per platform, before builds run in parallel: the runtimes
    unpacked, the bundled interpreter, the shim's objects and every extension module (kept in the
    runtime's cache, where each build then finds them; else two builds that start at once both
    compile all of it)."""
    runtime = _ensure_runtime()
    bundled_python(runtime, root)
    windows = "win64" in _platforms(platforms)
    interpreters = {f"binaries/linux64/python/{name}": runtime.root / source for source, name in LIBRARIES}
    if windows:
        interpreters["binaries/win64/python/python311.dll"] = _ensure_win_runtime().embed / "python311.dll"
    xz_members({name: path.read_bytes() for name, path in interpreters.items() if name in XZ_MEMBERS})
    with tempfile.TemporaryDirectory(prefix="ftc_shared_") as tmp:
        shim_digest(root, runtime, Path(tmp))
        if windows:
            shim_digest(root, runtime, Path(tmp), windows="shared.dll")
        for source in EXTENSIONS.values():
            compile_extension(root / source, runtime, Path(tmp), root)
            if windows:
                compile_extension_win64(root / source, runtime, _ensure_win_runtime(), Path(tmp), root)


def _ensure_win_runtime() -> runtime_win64.WinRuntime:
    try:
        return runtime_win64.ensure_runtime()
    except RuntimeBundleError as error:
        raise BuildError(str(error)) from error


def _ensure_runtime() -> Runtime:
    try:
        return ensure_runtime()
    except RuntimeBundleError as error:
        raise BuildError(str(error)) from error


def bundled_python(runtime: Runtime, root: Path = REPO_ROOT) -> Path:
    """The bundled runtime as a command (``fmu_src/toolchain/shim/bundled_python.c``, compiled once into
    the runtime's cache): the interpreter that compiles every FMU's bytecode, so that the bytes do
    not depend on the Python running the build."""
    source = root / SHIM_DIR / LAUNCHER_SOURCE
    if not source.is_file():
        raise BuildError(f"launcher source not found: {source}")
    digest = hashlib.sha256(source.read_bytes() + repr(LAUNCHER_FLAGS).encode()).hexdigest()[:16]
    target = runtime.root.parent / "bin" / f"bundled_python-{digest}"
    if target.is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    compiler, _ = c_compiler()
    partial = target.with_name(target.name + f".{os.getpid()}")
    command = [compiler, *LAUNCHER_FLAGS, "-o", str(partial), str(source), "-ldl"]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"{source}: {compiler} failed:\n{result.stderr.strip()}")
    partial.replace(target)
    return target


def _runtime(bundle: Bundle, windows: bool, root: Path) -> dict[str, bytes]:
    """The runtime members of linux64 (and win64 with ``windows``) for ``bundle``: the
    standard-library modules it imports when it runs (:func:`_measure`)."""
    runtime = _ensure_runtime()
    launcher = bundled_python(runtime, root)
    if bundle.third_party:
        raise BuildError(
            f"{bundle.model} imports {', '.join(sorted(bundle.third_party))}: an FMU carries no third-party "
            "package (it must run where nothing is installed); use the standard library"
        )
    # what the FMU imports follows from its code and the build's: the same inputs, the same members
    platforms = PLATFORM_NAMES if windows else ("linux64",)
    key = stamps.digest("runtime members", fmu_inputs(bundle, root, platforms))
    kept = runtime.root.parent / "members" / f"{key}.zip"
    known = read_kept(kept)
    if known is not None:
        with zipfile.ZipFile(io.BytesIO(known)) as archive:
            return {name: archive.read(name) for name in archive.namelist()}
    with tempfile.TemporaryDirectory(prefix="ftc_imports_") as tmp:
        try:
            measured = _measure(bundle, runtime, launcher, Path(tmp), root)
            members = runtime_members(runtime, launcher, measured)
            if windows:
                members |= runtime_win64.runtime_members(_ensure_win_runtime(), measured, runtime.stdlib)
        except RuntimeBundleError as error:
            raise BuildError(f"{bundle.model}: {error}") from error
    kept.parent.mkdir(parents=True, exist_ok=True)
    partial = kept.with_name(f".{kept.name}.{os.getpid()}")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_STORED) as archive:
        for name in sorted(members):
            archive.writestr(name, members[name])
    partial.replace(kept)
    return members


def _measure(bundle: Bundle, runtime: Runtime, launcher: Path, where: Path,
             root: Path) -> dict[str, Path | None]:
    """The standard-library modules ``bundle``'s FMU imports when it runs (:func:`measured_imports`):
    its code staged as in the FMU (under a provisional package name: the imports do not depend on
    it) with its compiled extension modules and pythonfmu's run-time part, driven in the bundled
    interpreter."""
    stage = where / "stage"
    script, package_dir = _stage(bundle, "0" * 64, stage)
    for name, source in bundle.extensions.items():
        binary = compile_extension(source, runtime, where, root)
        package_dir.joinpath(*name.split(".")).with_suffix(EXTENSION_SUFFIX).write_bytes(binary)
    (stage / "pythonfmu").mkdir()
    installed = Path(pythonfmu.__file__).parent
    for name, data in runtime_pythonfmu({f.name: f.read_bytes() for f in installed.glob("*.py")}).items():
        (stage / "pythonfmu" / name).write_bytes(data)
    return measured_imports(runtime, launcher, stage, bundle.model, script.stem)


def runtime_pythonfmu(files: dict[str, bytes]) -> dict[str, bytes]:
    """pythonfmu's package files (name -> bytes) as a running FMU needs them: without the modules
    that only build FMUs (:data:`PYTHONFMU_BUILD_ONLY`), with the lines of :data:`PYTHONFMU_LINES`
    replaced (the builder's import would bring argparse, zipfile, tempfile, shutil, xml.dom... into
    every FMU)."""
    kept = {name: data for name, data in files.items() if name not in PYTHONFMU_BUILD_ONLY}
    for name, replacements in PYTHONFMU_LINES.items():
        lines = kept[name].decode().splitlines(keepends=True)
        for old, new in replacements.items():
            if lines.count(old) != 1:
                raise BuildError(f"pythonfmu {pythonfmu.__version__}'s {name} has not one line "
                                 f"{old.strip()!r}: check what a running FMU needs of it (PYTHONFMU_LINES)")
            lines[lines.index(old)] = new
        kept[name] = "".join(lines).encode()
    return kept


def _licence(distribution: str) -> bytes:
    """The licence file of an installed distribution (pythonfmu's ships in the FMU)."""
    for file in importlib.metadata.files(distribution) or ():
        if file.name.upper().startswith(("LICENSE", "LICENCE", "COPYING")):
            return file.read_binary()
    raise BuildError(f"no licence file in the installed {distribution} distribution")


def _rewrite_imports(path: Path, package: str) -> str:
    """The text of ``path`` with its absolute local ``from X import ...`` lines pointed into ``package``."""
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    tree = _parse(path)
    for node in sorted(tree.body, key=lambda n: n.lineno, reverse=True):
        if isinstance(node, ast.ImportFrom) and not node.level and _is_local(node.module):
            new = ast.ImportFrom(module=f"{package}.{node.module}", names=node.names, level=0)
            lines[node.lineno - 1 : node.end_lineno] = [ast.unparse(new) + "\n"]
    text = "".join(lines)
    for found in ast.walk(ast.parse(text)):
        if isinstance(found, ast.ImportFrom) and not found.level and _is_local(found.module):
            raise BuildError(f"{path}:{found.lineno}: local import of {found.module} outside module level")
    return text


def _rewrite_script(bundle: Bundle, package: str) -> str:
    """The script text with only its local ``from X import ...`` lines pointed into ``package``."""
    text = _rewrite_imports(bundle.script, package)
    classes = CLASS_LINE.findall(text)
    if classes != [bundle.model]:
        raise BuildError(
            f"{bundle.script}: expected exactly one line 'class {bundle.model}(Fmi2Slave):' "
            f"(the class the FMU's entry imports), found {classes}"
        )
    return text


def _stage(bundle: Bundle, digest: str, where: Path) -> tuple[Path, Path]:
    """Write the uniquely named package, the rewritten script in it (``fmu_src/<script>.py``), and
    pythonfmu's entry module (:func:`_entry`); return the entry's path and the package's."""
    package = f"_ftc_{bundle.model.lower()}_{digest[:12]}"
    package_dir = where / package
    package_dir.mkdir(parents=True)
    init = f'"""Code bundled into the {bundle.model} FMU under a name no other FMU can use."""\n'
    (package_dir / "__init__.py").write_text(init, encoding="utf-8")
    for name, source in bundle.modules.items():
        target = package_dir.joinpath(*name.split(".")).with_suffix(".py")
        for parent in reversed(target.relative_to(package_dir).parents):  # outermost first
            if parent != Path("."):
                (package_dir / parent).mkdir(exist_ok=True)
                (package_dir / parent / "__init__.py").write_text(init, encoding="utf-8")
        if target.name != "__init__.py":
            target.write_text(_rewrite_imports(source, package), encoding="utf-8")
    (package_dir / "fmu_src").mkdir(exist_ok=True)
    if not (package_dir / "fmu_src" / "__init__.py").exists():
        (package_dir / "fmu_src" / "__init__.py").write_text(init, encoding="utf-8")
    script_text = _rewrite_script(bundle, package)
    (package_dir / "fmu_src" / bundle.script.name).write_text(script_text, encoding="utf-8")
    script = where / f"ftc_{bundle.model.lower()}_{digest[:12]}.py"
    script.write_text(_entry(bundle, package), encoding="utf-8")
    return script, package_dir


def _entry(bundle: Bundle, package: str) -> str:
    """pythonfmu's entry module, which imports the model class from the bundled script.

    pythonfmu 0.7.0 compiles and runs this file again every time it constructs a component (its
    findClass, looking for the class), and keeps what that made: running the script itself there
    built, and leaked, the model's class once per instance. findClass also releases a reference
    to this module's namespace that it never took (``Py_DECREF`` of ``PyModule_GetDict``'s
    borrowed result); the leaked class's functions used to hold enough, so each run of the entry
    keeps one (8 bytes), or the second instance would find the namespace freed."""
    script = f"{package}.fmu_src.{bundle.script.stem}"
    return (f'"""The {bundle.model} FMU\'s entry for pythonfmu: the script is {script}.\n\n'
            "pythonfmu runs this file again for every component it constructs, then releases one\n"
            'reference to this namespace that it never took: each run keeps one."""\n\n'
            f"from {script} import {bundle.model}\n\n"
            f"__all__ = [\"{bundle.model}\"]\n"
            'globals().setdefault("_pythonfmu_references", []).append(globals())\n')


@contextmanager
def _isolated_imports() -> Iterator[None]:
    """Undo what pythonfmu's builder does to ``sys.path`` and ``sys.modules`` (it imports the script)."""
    path, modules, bytecode = list(sys.path), set(sys.modules), sys.dont_write_bytecode
    sys.dont_write_bytecode = True
    try:
        yield
    finally:
        sys.path[:] = path
        for name in set(sys.modules) - modules:
            if name.startswith("ftc_") or name.startswith("_ftc_"):
                del sys.modules[name]
        sys.dont_write_bytecode = bytecode


def _normalized_description(xml: bytes, digest: str, model: str) -> bytes:
    root = ElementTree.fromstring(xml)
    root.set("guid", "{" + str(uuid.uuid5(GUID_NAMESPACE, f"{model}:{digest}")) + "}")
    root.attrib.pop("generationDateAndTime", None)
    root.set("generationTool", generation_tool("PythonFMU 0.7.0, the shim and its own CPython"))
    root.set("license", "BSD-2-Clause; bundled third-party licences: documentation/licenses/license.txt")
    cosimulation = root.find("CoSimulation")
    if cosimulation is None:
        raise BuildError(f"pythonfmu's model description of {model} has no CoSimulation element")
    cosimulation.set("needsExecutionTool", "false")  # the FMU carries its runtime
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _write_normalized(raw_fmu: Path, target: Path, bundle: Bundle, digest: str, native: dict[str, bytes],
                      platforms: Sequence[str], link: Callable[[bytes], dict[str, bytes]]) -> None:
    """Copy the archive with the shim in front of pythonfmu's binaries of ``platforms`` (the others
    dropped), the runtimes and the licences added, a deterministic description, fixed timestamps
    and sorted entries."""
    with zipfile.ZipFile(raw_fmu) as archive:
        entries = {name: archive.read(name) for name in archive.namelist() if not name.endswith("/")
                   and not (name.startswith("binaries/") and name.split("/")[1] not in platforms)}
    prefix = "resources/pythonfmu/"  # its run-time part only
    package = {name[len(prefix):]: entries.pop(name) for name in list(entries)
               if name.startswith(prefix) and "/" not in name[len(prefix):]}
    entries.update({prefix + name: data for name, data in runtime_pythonfmu(package).items()})
    chosen = [(platform, suffix) for platform, suffix in PLATFORMS if platform in platforms]
    for platform, suffix in chosen:
        binary = f"binaries/{platform}/{bundle.model}{suffix}"
        if binary not in entries:
            raise BuildError(f"pythonfmu's archive for {bundle.model} has no {binary}")
        entries[f"binaries/{platform}/{bundle.model}_pythonfmu{suffix}"] = entries[binary]
    entries.update(xz_members(native))
    entries.update(documentation(entries))
    entries["modelDescription.xml"] = _normalized_description(
        entries["modelDescription.xml"], digest, bundle.model
    )
    try:  # the controller FMUs' documentation/index.html, from their model description
        entries.update(controller_documentation(bundle.model, entries["modelDescription.xml"]))
    except ValueError as error:
        raise BuildError(str(error)) from error
    entries[IDENTITY_FILE] = identity(entries["modelDescription.xml"])
    entries.update(link(entries["modelDescription.xml"]))  # the shims, with the final variable table
    entries.update(_bytecode(entries))
    write_archive(target, entries)


def identity(description: bytes) -> bytes:
    """The content of the resources folder's identity file: the model description's GUID (FMI 2.0)
    or instantiation token (FMI 3.0), one line."""
    root = ElementTree.fromstring(description)
    token = root.get("guid") or root.get("instantiationToken")
    if not token:
        raise BuildError("the model description has no guid or instantiationToken")
    return token.encode() + b"\n"


def _bytecode(entries: dict[str, bytes]) -> dict[str, bytes]:
    """``__pycache__`` members for every Python source under ``resources/``: unchecked-hash
    ``.pyc`` files (PEP 552) of the bundled runtime's version, compiled by that runtime, read
    whatever the unpacked files' times. Without them a Python FMU's sources are compiled on every
    instantiation wherever bytecode is not written (the runtime never writes it; nor does a host
    with PYTHONDONTWRITEBYTECODE): 36 modules, about 0.04 s per run for example1's four FMUs."""
    sources = {n: entries[n] for n in entries if n.startswith("resources/") and n.endswith(".py")}
    runtime = _ensure_runtime()
    try:
        return compile_bytecode(runtime, bundled_python(runtime), sources)
    except RuntimeBundleError as error:
        raise BuildError(f"cannot compile the FMU's Python sources: {error}") from error


def write_archive(target: Path, entries: dict[str, bytes], kept: Path | None = None) -> None:
    """Write ``entries`` (member name -> bytes) as a zip archive: sorted, fixed timestamps, mode 0644.
    Members of :data:`DEFLATE_KEPT` bytes or more are deflated once and kept in ``kept`` (default:
    the runtime cache's ``deflated/``): the runtimes' libraries are the same in every FMU, and
    deflating them was most of a build's CPU time. The archive's bytes are the same either way."""
    kept = _ensure_runtime().root.parent / "deflated" if kept is None else kept
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            data = entries[name]
            if name.endswith(XZ_SUFFIX):  # compressed already (:func:`xz_members`)
                info.compress_type = zipfile.ZIP_STORED
                archive.writestr(info, data)
            elif len(data) >= DEFLATE_KEPT:
                _write_deflated(archive, info, data, _deflated(data, kept))
            else:
                archive.writestr(info, data)


def xz_members(entries: dict[str, bytes], kept: Path | None = None) -> dict[str, bytes]:
    """``entries`` with the members of :data:`XZ_MEMBERS` replaced by ``<name>.xz``, compressed with
    :data:`XZ_FILTERS` (CRC64 check) once and kept in ``kept`` (default: the runtime cache's
    ``xz/``) under the digest of the bytes and the settings: 2.5-3.6 s of CPU a file."""
    kept = _ensure_runtime().root.parent / "xz" if kept is None else kept
    settings = repr(XZ_FILTERS).encode()
    out = dict(entries)
    for name in XZ_MEMBERS:
        if name not in out:
            continue
        data = out.pop(name)
        if len(data) > XZ_LIMIT:
            raise BuildError(f"{name}: {len(data)} bytes: more than the shim decodes ({XZ_LIMIT})")
        path = kept / hashlib.sha256(hashlib.sha256(data).digest() + settings).hexdigest()
        packed = read_kept(path)
        if packed is None:
            packed = lzma.compress(data, format=lzma.FORMAT_XZ, check=lzma.CHECK_CRC64,
                                   filters=list(XZ_FILTERS))
            keep(path, packed)
        out[name + XZ_SUFFIX] = packed
    return out


def _deflated(data: bytes, kept: Path) -> bytes:
    """``data`` deflated as zipfile deflates a member (a raw stream, zlib's default level), kept in
    the folder ``kept`` under its digest."""
    path = kept / hashlib.sha256(data).hexdigest()
    known = read_kept(path)
    if known is not None:
        return known
    compressor = zlib.compressobj(zlib.Z_DEFAULT_COMPRESSION, zlib.DEFLATED, -15)
    packed = compressor.compress(data) + compressor.flush()
    keep(path, packed)
    return packed


def prune_kept(cache: Path | None = None, budget: int = KEPT_BUDGET,
               grace: float = KEPT_GRACE) -> tuple[int, int]:
    """Remove the build's least recently used kept files (:data:`KEPT_FOLDERS` of the runtime cache
    ``cache``) beyond ``budget`` bytes, and the half-written ones of builds that ended without
    finishing them; nothing used less than ``grace`` seconds ago (a build beside may be reading
    it). Every new source, pin or compiler flag makes new entries (15 MB of runtime members per FMU):
    unpruned, a developer's cache grew to 1.8 GB. Returns (files removed, bytes kept)."""
    root = _ensure_runtime().root.parent if cache is None else cache
    recent = time.time() - grace
    entries = []
    for folder in KEPT_FOLDERS:
        with contextlib.suppress(FileNotFoundError):
            for entry in os.scandir(root / folder):
                with contextlib.suppress(FileNotFoundError):
                    stat = entry.stat(follow_symlinks=False)
                    partial = entry.name.startswith(".")
                    entries.append((stat.st_mtime, stat.st_size, partial, Path(entry.path)))
    removed, total = 0, 0
    for mtime, size, partial, path in sorted(entries, reverse=True):  # the newest first
        if mtime >= recent or not partial and total + size <= budget:
            total += size
            continue
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
    return removed, total


def _write_deflated(archive: zipfile.ZipFile, info: zipfile.ZipInfo, data: bytes, packed: bytes) -> None:
    """Append the member ``info`` of ``data`` whose deflated bytes are ``packed`` to ``archive`` (a
    seekable file opened for writing), as ``writestr`` would: the same header and bookkeeping
    (zipfile's ``_open_to_write`` and ``_ZipWriteFile.close``), without deflating again."""
    info.flag_bits, info.CRC = 0, zlib.crc32(data)
    info.file_size, info.compress_size = len(data), len(packed)
    if info.file_size * 1.05 > zipfile.ZIP64_LIMIT or info.compress_size > zipfile.ZIP64_LIMIT:
        raise BuildError(f"{info.filename}: {len(data)} bytes: too large for an FMU member")
    archive.fp.seek(archive.start_dir)  # type: ignore[union-attr]
    info.header_offset = archive.fp.tell()  # type: ignore[union-attr]
    archive._writecheck(info)  # type: ignore[attr-defined]  # noqa: SLF001 - zipfile's own check
    archive._didModify = True  # type: ignore[attr-defined]  # noqa: SLF001 - the central directory is due
    archive.fp.write(info.FileHeader(False) + packed)  # type: ignore[union-attr]
    archive.start_dir = archive.fp.tell()  # type: ignore[union-attr]
    archive.filelist.append(info)
    archive.NameToInfo[info.filename] = info


def build_inputs(root: Path = REPO_ROOT, platforms: Sequence[str] = PLATFORM_NAMES) -> tuple[str | Path, ...]:
    """What every FMU of the build is made from besides its own sources: the build's code, the
    runtime's pins, the shim's sources and flags, the compilers and pythonfmu (the files among
    them: :func:`build_sources`)."""
    windows = ("win64" in platforms and (repr(MINGW_FLAGS), _mingw_version())) or ()
    return (BUILD_FORMAT, pythonfmu.__version__, repr(sorted(BUILD_OPTIONS.items())), repr(SHIM_FLAGS),
            repr(SHIM_LIBS), repr(EXTENSION_FLAGS), c_compiler()[1], *windows, *build_sources(root))


def build_sources(root: Path = REPO_ROOT) -> list[Path]:
    """The source files every FMU is built from besides its own: the build's code, the pins,
    the shim (tracked files only: what a build product is made from)."""
    here = Path(__file__).resolve().parent
    shim = sorted({*shim_files(root), root / SHIM_DIR / LAUNCHER_SOURCE})
    return [*(here / n for n in BUILD_CODE), *shim, root / XZ_LICENSE, root / WIN_PYCONFIG,
            root / CBASE_DIR / "__init__.py"]


def fmu_sources(bundle: Bundle, root: Path = REPO_ROOT) -> list[Path]:
    """Every source file ``bundle``'s FMU is built from: its script, modules, extension sources
    and headers, and :func:`build_sources`."""
    return [bundle.script, *(bundle.modules[n] for n in sorted(bundle.modules)),
            *(bundle.extensions[n] for n in sorted(bundle.extensions)),
            *(root / h for h in EXTENSION_HEADERS if bundle.extensions), *build_sources(root)]


def fmu_inputs(bundle: Bundle, root: Path = REPO_ROOT, platforms: Sequence[str] = PLATFORM_NAMES) -> str:
    """The digest of everything ``bundle``'s FMU is built from: a build whose inputs have not
    changed is reused (``make build`` after editing one model rebuilds the FMUs that bundle it)."""
    names = " ".join([*sorted(bundle.modules), *sorted(bundle.extensions)])
    return stamps.digest(bundle.model, names, " ".join(platforms), *build_inputs(root, platforms),
                         *fmu_sources(bundle, root))


def buildable_platforms() -> tuple[tuple[str, ...], str]:
    """The platforms this machine can build (linux64 always; win64 with mingw-w64 and osslsigncode)
    and, where win64 cannot be built, one line saying why and how to get it."""
    tools = (os.environ.get("MINGW_CC") or cbase.MINGW, "osslsigncode")
    missing = [tool for tool in tools if not shutil.which(tool)]
    if not missing:
        return PLATFORM_NAMES, ""
    return ("linux64",), (f"win64 skipped: no {' and no '.join(missing)} (Debian: apt-get install "
                          "gcc-mingw-w64-x86-64 osslsigncode, or 'make windows-tools' as root); "
                          "the FMUs carry linux64 only")


def _platforms(platforms: Sequence[str]) -> tuple[str, ...]:
    """``platforms`` checked and in the build's order."""
    unknown = set(platforms) - set(PLATFORM_NAMES)
    if unknown or not platforms:
        raise BuildError(f"platforms {', '.join(sorted(unknown)) or '(none)'}: "
                         f"choose from {', '.join(PLATFORM_NAMES)}")
    return tuple(p for p in PLATFORM_NAMES if p in platforms)


def fmu_current(model: str, dest: Path, root: Path = REPO_ROOT,
                platforms: Sequence[str] = PLATFORM_NAMES) -> bool:
    """Whether ``dest/<model>.fmu`` was built from the sources under ``root`` as they are now, for
    at least ``platforms`` (an FMU built for more platforms serves as well)."""
    platforms = _platforms(platforms)
    target = Path(dest) / f"{model}.fmu"
    if not target.is_file():
        return False
    bundle = collect_bundle(model, root)
    return any(set(platforms) <= set(wider)
               and stamps.up_to_date(target, fmu_inputs(bundle, root, wider), wider)
               for wider in (PLATFORM_NAMES, platforms))


def build_fmu(model: str, dest: Path, root: Path = REPO_ROOT, platforms: Sequence[str] = PLATFORM_NAMES,
              *, force: bool = False) -> Path:
    """Build one FMU for ``platforms`` into ``dest/<model>.fmu`` from the sources under ``root``
    (reused when it was built from the same inputs for at least these platforms, :func:`fmu_inputs`,
    unless ``force``)."""
    platforms = _platforms(platforms)
    bundle = collect_bundle(model, root)
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    target = dest / f"{model}.fmu"
    if not force and fmu_current(model, dest, root, platforms):
        return target
    key = fmu_inputs(bundle, root, platforms)
    stamps.forget(target)
    windows = "win64" in platforms
    with tempfile.TemporaryDirectory(prefix=f"ftc_build_{model}_") as tmp:
        runtime = _ensure_runtime()
        native = _runtime(bundle, windows, root)
        # the shims are linked once the model description (their variable table) is final
        shims = {f"binaries/linux64/{model}.so": ""}
        if windows:
            shims[f"binaries/win64/{model}.dll"] = f"{model}.dll"
        for name, dll in shims.items():
            native[name] = shim_digest(root, runtime, Path(tmp), windows=dll).encode()
        native["documentation/licenses/pythonfmu-LICENSE.txt"] = _licence("pythonfmu")
        native[f"documentation/licenses/{XZ_LICENSE_NAME}"] = (root / XZ_LICENSE).read_bytes()
        if FMATH_MODULE in bundle.modules:
            native[f"documentation/licenses/{FMATH_LICENSE.name}"] = (root / FMATH_LICENSE).read_bytes()
        extensions = {name: compile_extension(source, runtime, Path(tmp), root)
                      for name, source in bundle.extensions.items()}
        extensions_win64 = {}
        if windows:
            win = _ensure_win_runtime()
            extensions_win64 = {name: compile_extension_win64(source, runtime, win, Path(tmp), root)
                                for name, source in bundle.extensions.items()}
        native_digest = hashlib.sha256()
        for name in sorted(native):
            native_digest.update(name.encode() + b"\0" + hashlib.sha256(native[name]).digest())
        for name in sorted(extensions):
            native_digest.update(name.encode() + b"\0" + hashlib.sha256(extensions[name]).digest())
            if windows:
                native_digest.update(hashlib.sha256(extensions_win64[name]).digest())
        digest = bundle.digest(native_digest.hexdigest())
        script, package_dir = _stage(bundle, digest, Path(tmp) / "stage")
        for name, binary in extensions.items():  # beside its importer: pythonfmu imports the script
            package_dir.joinpath(*name.split(".")).with_suffix(EXTENSION_SUFFIX).write_bytes(binary)
        for name, binary in extensions_win64.items():
            package_dir.joinpath(*name.split(".")).with_suffix(WIN_EXTENSION_SUFFIX).write_bytes(binary)
        with _isolated_imports():
            try:
                raw = FmuBuilder.build_FMU(
                    script, dest=Path(tmp) / "raw", project_files=[package_dir], **BUILD_OPTIONS
                )
            except Exception as error:
                raise BuildError(
                    f"pythonfmu could not build {model} from {bundle.script}: {error}"
                ) from error
        for name in shims:
            del native[name]

        def link(description: bytes) -> dict[str, bytes]:
            return {name: compile_shim(root, runtime, Path(tmp), description, windows=dll)
                    for name, dll in shims.items()}

        _write_normalized(Path(raw), target, bundle, digest, native, platforms, link)
    stamps.record(target, key, stamps.source_digests(fmu_sources(bundle, root), root), root, platforms)
    return target


def build_all(dest: Path, root: Path = REPO_ROOT) -> list[Path]:
    """Build every FMU of the project into ``dest``; returns the paths in FMU_SCRIPTS order."""
    return [build_fmu(model, dest, root) for model in FMU_SCRIPTS]


def compile_in_place(name: str, root: Path = REPO_ROOT) -> Path:
    """The extension module ``name`` (a key of :data:`EXTENSIONS`) compiled as the FMU build compiles
    it, written beside its source (``<stem>.abi3.so``): the checkout's own Python imports it, as an
    FMU imports its copy. Ignored by git (a built file)."""
    source = root / EXTENSIONS[name]
    target = source.with_name(source.stem + EXTENSION_SUFFIX)
    with tempfile.TemporaryDirectory() as tmp:
        binary = compile_extension(source, _ensure_runtime(), Path(tmp), root)
    partial = target.with_name(target.name + ".part")
    partial.write_bytes(binary)
    partial.replace(target)  # a running Python never sees half a module
    return target
