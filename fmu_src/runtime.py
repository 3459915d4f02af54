"""The CPython runtime every FMU carries, so that it runs where no Python is installed.

Source: Debian 12 (bookworm) binary packages, pinned by version and SHA-256 below and fetched
with ``apt-get download`` into ``build/runtime/`` by the FMU build itself: the shared libpython
(built ``--enable-shared``), the pure-Python standard library, the two shared libraries
libpython links besides libc/libm (expat, zlib) and, for the shim's compile only, the headers.
The same ``.deb`` files give the same bytes, and every FMU ships their licences.

What goes into an FMU (``binaries/linux64/python/``, see :func:`runtime_members`):

* ``lib/libpython3.11.so.1.0``, ``fallback/libexpat.so.1``, ``fallback/libz.so.1``: unmodified
  from the packages (the shim loads the system's expat and zlib when there are, else these);
* ``python311.zip``: only the standard-library modules the FMU's code can import (the import
  closure of its script, found with :mod:`modulefinder` over the Debian standard library),
  compiled to ``.pyc`` when the building interpreter is a 3.11 (else the ``.py`` sources);
* ``lib-dynload/``: the extension modules of that closure that are not built into libpython;
* ``runtime.txt``: the packages, versions and digests it came from.

Licences (PSF for Python; expat's MIT; zlib's) go to ``documentation/licenses/``.

Usage: ``python -m fmu_src.runtime [CACHE]`` fetches and unpacks the runtime (what the build does
on its first use).
"""

from __future__ import annotations

import hashlib
import json
import modulefinder
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "PACKAGES",
    "PYTHON_VERSION",
    "Runtime",
    "RuntimeBundleError",
    "ensure_runtime",
    "runtime_members",
    "stdlib_closure",
]

PYTHON_VERSION = (3, 11)
TAG = f"{PYTHON_VERSION[0]}{PYTHON_VERSION[1]}"  # "311"
SOABI = f"cpython-{TAG}-x86_64-linux-gnu"
# Debian 12 point release 12.13's packages (bookworm/main, amd64). To move to a newer point
# release: change the versions, delete build/runtime, run the build, and put the digests it
# reports here (the build refuses a file whose digest differs).
PACKAGES: tuple[tuple[str, str, str], ...] = (
    ("libpython3.11", "3.11.2-6+deb12u8", "63845d53d5f64d2362cfb6007ec175ad1c6044cebe60a1885eff76d2ce637c35"),
    (
        "libpython3.11-minimal",
        "3.11.2-6+deb12u8",
        "f3beaa03994ffedacf73c43a0843d53b062d347115d8af65bee2034552a4e6f9",
    ),
    (
        "libpython3.11-stdlib",
        "3.11.2-6+deb12u8",
        "890b3540dad8a1ccc0deeca025db735bcc82629a76adacbe3b50fcc06ed528ca",
    ),
    (
        "libpython3.11-dev",
        "3.11.2-6+deb12u8",
        "01a8eddeb8505bb6e2c01209cda66b41fb5ebeaa64e69d0e25f7131915f1cd32",
    ),
    ("libexpat1", "2.5.0-1+deb12u2", "2255e62fc22a86d2c544b8a3f516da9aee19383ad5742722ab4ce7f66a30dbc8"),
    ("zlib1g", "1:1.2.13.dfsg-1", "d7dd1d1411fedf27f5e27650a6eff20ef294077b568f4c8c5e51466dc7c08ce4"),
)
# (file in the unpacked packages, path in binaries/linux64/python/), in the order the shim loads
# them. libpython's folder is the shim's DT_RUNPATH; zlib and expat are fallbacks, loaded only
# where the system has none (the machine's own are preferred: Debian 12's expat needs glibc 2.36,
# while libpython asks only for the expat API of 2012 and glibc 2.35).
LIBRARIES = (
    ("lib/x86_64-linux-gnu/libz.so.1.2.13", "fallback/libz.so.1"),
    ("lib/x86_64-linux-gnu/libexpat.so.1.8.10", "fallback/libexpat.so.1"),
    ("usr/lib/x86_64-linux-gnu/libpython3.11.so.1.0", "lib/libpython3.11.so.1.0"),
)
LICENSES = (  # (file in the unpacked packages, name under documentation/licenses/)
    ("usr/lib/python3.11/LICENSE.txt", "Python-LICENSE.txt"),
    ("usr/share/doc/libpython3.11/copyright", "Python-debian-copyright.txt"),
    ("usr/share/doc/libexpat1/copyright", "expat-debian-copyright.txt"),
    ("usr/share/doc/zlib1g/copyright", "zlib-debian-copyright.txt"),
)
STDLIB = Path("usr/lib/python3.11")
INCLUDE = (Path("usr/include/python3.11"), Path("usr/include/x86_64-linux-gnu/python3.11"))
# Imported by name at start-up (the file-system and standard-stream codecs), not by an import line.
STARTUP_MODULES = (
    "encodings", "encodings.aliases", "encodings.utf_8", "encodings.ascii", "encodings.latin_1",
)
# Shared libraries an extension module may need besides the bundled ones: the C library's own.
SYSTEM_LIBRARIES = frozenset({"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1"})
# Never bundled: the standard library's tools and servers (unreachable from an FMU's calls), and
# extension modules needing a library the runtime does not carry, whose importers fall back
# (hashlib -> built-in hashes, decimal -> _pydecimal, zipfile without bz2/lzma, uuid without _uuid).
EXCLUDED = (
    "test", "unittest", "doctest", "pdb", "bdb", "pydoc", "pydoc_data", "asyncio", "multiprocessing",
    "concurrent", "http.server", "socketserver", "xmlrpc", "ftplib", "webbrowser", "distutils", "ctypes",
    "tkinter", "idlelib", "lib2to3", "ensurepip", "venv", "sqlite3", "curses", "dbm", "readline", "ssl",
    "_ssl", "_hashlib", "_bz2", "_lzma", "_ctypes", "_decimal", "_uuid", "_curses", "_dbm", "_sqlite3",
    "_tkinter", "_testcapi", "_testinternalcapi", "_multiprocessing", "_posixshmem", "_asyncio",
)
ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def default_cache() -> Path:
    """Where the runtime is fetched to: ``build/runtime/`` of a checkout; for an installed package
    the user's cache (``$XDG_CACHE_HOME/fixed-time-cosim/runtime``), never site-packages."""
    root = Path(__file__).resolve().parent.parent
    if (root / "pyproject.toml").is_file():
        return root / "build" / "runtime"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "fixed-time-cosim" / "runtime"


DEFAULT_CACHE = default_cache()


class RuntimeBundleError(RuntimeError):
    """The runtime cannot be fetched, verified or bundled; the message says what to do."""


@dataclass(frozen=True)
class Runtime:
    """The unpacked packages (``root``) and the pins they came from."""

    root: Path

    @property
    def stdlib(self) -> Path:
        return self.root / STDLIB

    @property
    def include_dirs(self) -> tuple[Path, ...]:
        return tuple(self.root / d for d in INCLUDE)


def manifest() -> str:
    """``runtime.txt``: where the bundled runtime came from."""
    lines = [
        f"# CPython {PYTHON_VERSION[0]}.{PYTHON_VERSION[1]} runtime of this FMU, unmodified from Debian 12's",
        "# binary packages (package, version, SHA-256 of the .deb); see fmu_src/runtime.py.",
    ]
    lines += [f"{name} {version} {digest}" for name, version, digest in PACKAGES]
    return "\n".join(lines) + "\n"


def _deb_name(name: str, version: str) -> str:
    return f"{name}_{version.replace(':', '%3a')}_amd64.deb"  # apt's file name: epoch escaped


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _download(missing: list[tuple[str, str]], debs: Path) -> str:
    """``apt-get download`` of the pinned versions into ``debs``; '' or apt's complaint."""
    if not shutil.which("apt-get"):
        return "apt-get is not on PATH (the runtime comes from Debian 12 packages)"
    command = ["apt-get", "download", "-q", *(f"{n}={v}" for n, v in missing)]
    result = subprocess.run(command, cwd=debs, capture_output=True, text=True)
    if result.returncode == 0:
        return ""
    return (result.stderr.strip() or result.stdout.strip()).splitlines()[-1]


def fetch(cache: Path = DEFAULT_CACHE) -> Path:
    """The pinned ``.deb`` files in ``cache/debs``, downloaded if missing, digests checked."""
    debs = cache / "debs"
    debs.mkdir(parents=True, exist_ok=True)
    missing = [(n, v) for n, v, _ in PACKAGES if not (debs / _deb_name(n, v)).is_file()]
    if missing:
        problem = _download(missing, debs)
        if problem and hasattr(os, "geteuid") and os.geteuid() == 0:  # stale package lists: refresh once
            subprocess.run(["apt-get", "update", "-qq"], capture_output=True)
            problem = _download(missing, debs)
        if problem:
            pins = " ".join(f"{n}={v}" for n, v in missing)
            raise RuntimeBundleError(
                f"cannot fetch the FMU runtime packages ({pins}) into {debs}: {problem}; on Debian 12 run "
                "'apt-get update' (as root) and build again, or put those .deb files there by hand"
            )
    for name, version, digest in PACKAGES:
        path = debs / _deb_name(name, version)
        if _sha256(path) != digest:
            raise RuntimeBundleError(
                f"{path}: SHA-256 {_sha256(path)} is not the pinned {digest} (fmu_src/runtime.py); "
                "delete the file to fetch it again"
            )
    return debs


def ensure_runtime(cache: Path = DEFAULT_CACHE) -> Runtime:
    """The runtime unpacked under ``cache/root`` (fetched and unpacked on first use)."""
    root = cache / "root"
    stamp = root / ".pins"
    if stamp.is_file() and stamp.read_text() == manifest():
        return Runtime(root)
    debs = fetch(cache)
    if not shutil.which("dpkg-deb"):
        raise RuntimeBundleError("dpkg-deb is not on PATH: it unpacks the runtime's Debian packages")
    staging = Path(tempfile.mkdtemp(prefix="root.", dir=cache))
    try:
        for name, version, _ in PACKAGES:
            deb = debs / _deb_name(name, version)
            command = ["dpkg-deb", "-x", str(deb), str(staging)]
            result = subprocess.run(command, capture_output=True, text=True)
            if result.returncode != 0:
                raise RuntimeBundleError(f"{deb}: dpkg-deb -x failed: {result.stderr.strip()}")
        (staging / ".pins").write_text(manifest())
        shutil.rmtree(root, ignore_errors=True)
        staging.rename(root)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return Runtime(root)


def stdlib_closure(runtime: Runtime, scripts: Iterable[Path], path: Iterable[Path]) -> dict[str, Path]:
    """Standard-library modules (dotted name -> file in the runtime) that ``scripts`` can import,
    following every import line (also those inside functions) with ``modulefinder`` over
    ``path`` (the FMU's own code) followed by the bundled standard library."""
    stdlib, dynload = runtime.stdlib, runtime.stdlib / "lib-dynload"
    finder = modulefinder.ModuleFinder(path=[*map(str, path), str(stdlib), str(dynload)], excludes=EXCLUDED)
    for script in scripts:
        finder.run_script(str(script))
    for name in STARTUP_MODULES:
        finder.import_hook(name)
    found: dict[str, Path] = {}
    for name, module in finder.modules.items():
        file = getattr(module, "__file__", None)
        if file and Path(file).is_relative_to(stdlib):
            found[name] = Path(file)
    return found


def _needed(path: Path) -> list[str]:
    """The DT_NEEDED entries of a shared object (readelf, from binutils)."""
    try:
        result = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as error:
        raise RuntimeBundleError(f"readelf (binutils) cannot list what {path.name} needs: {error}") from error
    return [line.split("[", 1)[1].rstrip("]") for line in result.stdout.splitlines() if "(NEEDED)" in line]


# Writes the standard-library zip in a fresh interpreter: marshal's output depends on the state of
# the process that compiles (reference counts decide which objects are written once and referred
# to; the hash seed orders frozenset constants), so a fixed start (no site, hash seed 0) is what
# makes the same sources give the same bytes in any build.
ZIP_WRITER = """
import json, py_compile, sys, tempfile, zipfile
modules, target, compiled, date = json.loads(sys.stdin.read())
with zipfile.ZipFile(target, "w") as archive, tempfile.TemporaryDirectory() as tmp:
    for source, name in modules:
        if compiled:
            py_compile.compile(source, cfile=tmp + "/m.pyc", dfile=name, doraise=True,
                               invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
            data, name = open(tmp + "/m.pyc", "rb").read(), name + "c"
        else:
            data = open(source, "rb").read()
        info = zipfile.ZipInfo(name, date_time=tuple(date))
        info.compress_type = zipfile.ZIP_DEFLATED
        info.external_attr = 0o644 << 16
        archive.writestr(info, data)
"""


def _stdlib_zip(modules: dict[str, Path], stdlib: Path) -> bytes:
    """``python311.zip`` of the given modules: ``.pyc`` from a 3.11 interpreter, else ``.py``."""
    compiled = sys.version_info[:2] == PYTHON_VERSION
    listing = [(str(modules[n]), modules[n].relative_to(stdlib).as_posix()) for n in sorted(modules)]
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(tmp) / f"python{TAG}.zip"
        request = json.dumps([listing, str(target), compiled, ZIP_DATE])
        env = {"PYTHONHASHSEED": "0", "PATH": os.environ.get("PATH", "/usr/bin:/bin")}
        result = subprocess.run([sys.executable, "-S", "-c", ZIP_WRITER], input=request, env=env,
                                capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeBundleError(f"cannot write the standard-library zip: {result.stderr.strip()}")
        return target.read_bytes()


def runtime_members(runtime: Runtime, scripts: Iterable[Path], path: Iterable[Path]) -> dict[str, bytes]:
    """Archive members (name -> bytes) of the runtime for an FMU whose code is ``scripts`` plus
    the modules under ``path``: libraries, standard-library zip, extension modules, manifest and
    licences."""
    closure = stdlib_closure(runtime, scripts, path)
    base = "binaries/linux64/python/"
    members = {base + name: (runtime.root / source).read_bytes() for source, name in LIBRARIES}
    pure = {n: p for n, p in closure.items() if p.suffix == ".py"}
    members[f"{base}python{TAG}.zip"] = _stdlib_zip(pure, runtime.stdlib)
    allowed = SYSTEM_LIBRARIES | {name.rsplit("/", 1)[1] for _, name in LIBRARIES}
    for name, file in sorted(closure.items()):
        if file.suffix != ".so":
            continue
        unmet = sorted(set(_needed(file)) - allowed)
        if unmet:
            raise RuntimeBundleError(
                f"the FMU's code imports {name} ({file.name}), which needs {', '.join(unmet)}: not bundled"
            )
        members[f"{base}lib-dynload/{file.name}"] = file.read_bytes()
    members[f"{base}runtime.txt"] = manifest().encode()
    for source, name in LICENSES:
        members[f"documentation/licenses/{name}"] = (runtime.root / source).read_bytes()
    return members


def main(argv: list[str] | None = None) -> int:
    """Fetch and unpack the runtime; prints where it is."""
    args = sys.argv[1:] if argv is None else argv
    try:
        runtime = ensure_runtime(Path(args[0]) if args else DEFAULT_CACHE)
    except RuntimeBundleError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(runtime.root)
    return 0


if __name__ == "__main__":
    sys.exit(main())
