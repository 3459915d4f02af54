# SPDX-License-Identifier: BSD-2-Clause
"""The CPython runtime every FMU carries, so that it runs where no Python is installed.

Source: Debian 12 (bookworm) binary packages, pinned by version and SHA-256 in
``fmu_src/toolchain/runtime_pins.txt`` and downloaded by URL from the pool of Debian's archive (no apt-get,
no dpkg) into ``build/runtime/debs/`` by the FMU build itself: the shared libpython (built
``--enable-shared``), the pure-Python standard library, the two shared libraries libpython links
besides libc/libm (expat, zlib) and, for the shim's compile only, the headers. A ``.deb`` is an
``ar`` archive holding ``data.tar.*``: it is unpacked with the standard library. The same pinned
files give the same bytes, on any build machine, and every FMU ships their licences.

What goes into an FMU (``binaries/linux64/python/``, see :func:`runtime_members`):

* ``lib/libpython3.11.so.1.0``, ``fallback/libexpat.so.1``, ``fallback/libz.so.1``: unmodified
  from the packages (the shim loads the system's expat and zlib when there are, else these);
* ``python311.zip``: only the standard-library modules the FMU imports when it runs (measured:
  its model made and driven through a host's calls in the bundled interpreter,
  :func:`measured_imports`; modules frozen into libpython left out), as ``.pyc`` compiled by the
  bundled runtime itself (so any builder Python gives the same bytes);
* ``lib-dynload/``: the extension modules of that set that are not built into libpython;
* ``runtime.txt``: the packages, versions and digests it came from.

Licences (PSF for Python; expat's MIT; zlib's) go to ``documentation/licenses/``.

Usage (see docs/fmus/runtime.md)::

    python -m fmu_src.toolchain.runtime [fetch] [CACHE]
        fetch and unpack the runtime (the build does it on first use)
    python -m fmu_src.toolchain.runtime check
        one line: are the pins still the newest bookworm versions?
    python -m fmu_src.toolchain.runtime update
        move the pins to the newest bookworm(-security) versions
"""

from __future__ import annotations

import hashlib
import io
import json
import lzma
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import urllib.error
import urllib.request
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import NamedTuple

__all__ = [
    "PACKAGES",
    "PYTHON_VERSION",
    "Pin",
    "Runtime",
    "RuntimeBundleError",
    "check_pins",
    "compare_versions",
    "compile_bytecode",
    "ensure_runtime",
    "keep",
    "measured_imports",
    "newest_versions",
    "parse_pins",
    "read_kept",
    "read_pins",
    "runtime_members",
    "unpack_deb",
    "update_pins",
    "write_pins",
]

PYTHON_VERSION = (3, 11)
TAG = f"{PYTHON_VERSION[0]}{PYTHON_VERSION[1]}"  # "311"
SOABI = f"cpython-{TAG}-x86_64-linux-gnu"
PINS_FILE = Path(__file__).with_name("runtime_pins.txt")
# Debian's archive (what this machine's /etc/apt/sources.list.d/debian.sources and CI reach);
# FTC_DEBIAN_MIRROR names another mirror of the same layout (<mirror>/debian, <mirror>/debian-security).
MIRROR = os.environ.get("FTC_DEBIAN_MIRROR", "http://deb.debian.org").rstrip("/")
# (archive, suite) whose main/binary-amd64 packages the pins may come from; a pin is the newest of them.
SUITES = (("debian", "bookworm"), ("debian", "bookworm-updates"), ("debian-security", "bookworm-security"))
KEYRING = Path("/usr/share/keyrings/debian-archive-keyring.gpg")  # used by gpgv where it is installed
TIMEOUT = 60.0  # seconds without an answer from the mirror before a download fails
MAX_DEB = 64 << 20  # no pinned package is larger: bounded disk whatever the mirror sends
MAX_INDEX = 64 << 20  # a suite's Packages.xz (bookworm's: 9 MB)
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
    root = Path(__file__).resolve().parents[2]
    if (root / "pyproject.toml").is_file():
        return root / "build" / "runtime"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "fixed-time-cosim" / "runtime"


DEFAULT_CACHE = default_cache()
UPDATE_COMMAND = "make runtime-pins"


class RuntimeBundleError(RuntimeError):
    """The runtime cannot be fetched, verified or bundled; the message says what to do."""


class Pin(NamedTuple):
    """One pinned Debian package: name, version, SHA-256 and size of its ``.deb``, and its path
    under the mirror (``<archive>/pool/...``)."""

    name: str
    version: str
    sha256: str
    size: int
    path: str

    @property
    def file_name(self) -> str:
        """The ``.deb``'s file name in the pool (and in the cache)."""
        return self.path.rsplit("/", 1)[1]


def parse_pins(text: str, source: str = PINS_FILE.name) -> tuple[Pin, ...]:
    """The pins of ``text`` (lines ``name version sha256 size path``; ``#`` starts a comment)."""
    pins = []
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        if len(fields) != 5 or not fields[3].isdigit() or len(fields[2]) != 64:
            raise RuntimeBundleError(
                f"{source}:{number}: expected 'package version sha256 size path', got {line!r}")
        pins.append(Pin(fields[0], fields[1], fields[2], int(fields[3]), fields[4]))
    return tuple(pins)


def read_pins(path: Path = PINS_FILE) -> tuple[Pin, ...]:
    """The pins of the file ``path`` (see :func:`parse_pins`)."""
    return parse_pins(path.read_text(encoding="utf-8"), str(path))


PACKAGES = read_pins()


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

    @property
    def libpython(self) -> Path:
        """The bundled shared libpython."""
        return self.root / LIBRARIES[-1][0]

    @property
    def fallback_dir(self) -> Path:
        """Where the packages' zlib and expat are (for a machine that has none)."""
        return self.root / "lib" / "x86_64-linux-gnu"

    def run(self, launcher: Path, code: str, request: object, args: Sequence[str] = ()) -> object:
        """Run ``code`` in the bundled CPython (``launcher``: fmu_src/toolchain/shim/bundled_python.c built
        for this runtime) with ``request`` as JSON on its standard input and ``args`` in its
        ``sys.argv[1:]``; what it printed, as JSON.

        A fresh interpreter of a fixed start (no site, hash seed 0, only the runtime's standard
        library, nothing of the environment): marshal's output depends on the state of the
        process that compiles, so this is what makes the same sources give the same bytes in
        any build, whichever Python runs the build."""
        env = {"PYTHONHOME": str(self.root / "usr"), "PYTHONHASHSEED": "0", "PYTHONDONTWRITEBYTECODE": "1",
               "PYTHONUTF8": "1", "PATH": os.environ.get("PATH", "/usr/bin:/bin")}
        command = [str(launcher), str(self.libpython), str(self.fallback_dir), "-S", "-s", "-c", code, *args]
        result = subprocess.run(command, input=json.dumps(request), env=env, capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeBundleError(
                f"the bundled Python failed: {result.stderr.strip() or result.returncode}")
        return json.loads(result.stdout)


def manifest() -> str:
    """``runtime.txt``: where the bundled runtime came from."""
    lines = [
        f"# CPython {PYTHON_VERSION[0]}.{PYTHON_VERSION[1]} runtime of this FMU, unmodified from Debian 12's",
        "# binary packages (package, version, SHA-256 of the .deb); see fmu_src/toolchain/runtime.py.",
    ]
    lines += [f"{pin.name} {pin.version} {pin.sha256}" for pin in PACKAGES]
    return "\n".join(lines) + "\n"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _get(url: str, limit: int) -> bytes:
    """The body at ``url`` (at most ``limit`` bytes); urllib's errors propagate."""
    with urllib.request.urlopen(url, timeout=TIMEOUT) as answer:
        data: bytes = answer.read(limit + 1)
    if len(data) > limit:
        raise RuntimeBundleError(f"{url}: larger than {limit} bytes: not a file of the runtime")
    return data


def _locations(pin: Pin) -> list[str]:
    """Where ``pin``'s file may be on the mirror: its pinned path first, then the other archive
    (a security update moves into bookworm's own pool at the next point release)."""
    archive, _, rest = pin.path.partition("/")
    pool = rest.removeprefix("pool/").removeprefix("updates/")
    others = [f"debian-security/pool/updates/{pool}", f"debian/pool/{pool}"]
    return [pin.path] + [p for p in others if p != pin.path]


def _download(pin: Pin, target: Path) -> None:
    """Download ``pin`` into ``target``, checked against its SHA-256; one-line errors."""
    missing, unreachable = [], []
    for path in _locations(pin):
        url = f"{MIRROR}/{path}"
        try:
            data = _get(url, max(pin.size, 1) + 1024)
        except urllib.error.HTTPError as error:
            missing.append(f"{url}: HTTP {error.code}")
            continue
        except (urllib.error.URLError, OSError) as error:
            unreachable.append(f"{url}: {getattr(error, 'reason', error)}")
            continue
        digest = hashlib.sha256(data).hexdigest()
        if digest != pin.sha256:
            raise RuntimeBundleError(
                f"{url}: SHA-256 {digest} is not the pinned {pin.sha256} ({PINS_FILE.name}): refusing it")
        partial = target.with_name(target.name + ".part")
        partial.write_bytes(data)
        partial.replace(target)
        return
    if unreachable and not missing:
        raise RuntimeBundleError(
            f"cannot reach Debian's archive for {pin.name} {pin.version} ({unreachable[0]}) and "
            f"{target.parent} has no {pin.file_name}: build once with network access, or put the .deb "
            f"files listed in fmu_src/{PINS_FILE.name} there")
    raise RuntimeBundleError(
        f"Debian's archive no longer has {pin.name} {pin.version} ({'; '.join(missing + unreachable)}): "
        f"move the pins to the current versions with '{UPDATE_COMMAND}'")


def fetch(cache: Path = DEFAULT_CACHE, pins: Sequence[Pin] = PACKAGES) -> Path:
    """The pinned ``.deb`` files in ``cache/debs``, downloaded if missing, digests checked."""
    debs = cache / "debs"
    try:
        debs.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise RuntimeBundleError(f"cannot create the runtime cache {debs}: {error.strerror}") from error
    for pin in pins:
        path = debs / pin.file_name
        if not path.is_file():
            _download(pin, path)
        if _sha256(path) != pin.sha256:
            raise RuntimeBundleError(
                f"{path}: SHA-256 {_sha256(path)} is not the pinned {pin.sha256} (fmu_src/{PINS_FILE.name}); "
                "delete the file to fetch it again")
    return debs


def _ar_members(data: bytes, name: str) -> Iterator[tuple[str, bytes]]:
    """The members (name, bytes) of the ``ar`` archive ``data`` (the format of a ``.deb``)."""
    if not data.startswith(b"!<arch>\n"):
        raise RuntimeBundleError(f"{name}: not a Debian package (no ar archive header)")
    offset = 8
    while offset + 60 <= len(data):
        header = data[offset:offset + 60]
        if header[58:60] != b"`\n" or not header[48:58].strip().isdigit():
            raise RuntimeBundleError(f"{name}: damaged ar member header at byte {offset}")
        size = int(header[48:58])
        member = header[:16].decode("ascii", "replace").strip().rstrip("/")
        yield member, data[offset + 60:offset + 60 + size]
        offset += 60 + size + (size & 1)


def unpack_deb(deb: Path, root: Path) -> None:
    """Unpack the files of the Debian package ``deb`` under ``root``, as ``dpkg-deb -x`` does
    (regular files, folders, symbolic links that stay inside ``root``), with the standard library.
    The compressions of Debian 12's packages (xz, gzip, bzip2, none) are read; zstd is not."""
    members = dict(_ar_members(deb.read_bytes(), deb.name))
    data_name = next((n for n in members if n.startswith("data.tar")), None)
    if data_name is None:
        raise RuntimeBundleError(f"{deb}: no data.tar member")
    if data_name.endswith(".zst"):
        raise RuntimeBundleError(f"{deb}: data.tar.zst: zstd is not in Python's standard library")
    try:
        archive = tarfile.open(fileobj=io.BytesIO(members[data_name]), mode="r:*")
    except (tarfile.TarError, lzma.LZMAError, EOFError) as error:
        raise RuntimeBundleError(f"{deb}: cannot read {data_name}: {error}") from error
    with archive:
        for member in archive:
            parts = PurePosixPath(member.name).parts
            parts = tuple(p for p in parts if p not in (".", "/"))
            if not parts or ".." in parts:
                continue
            target = root.joinpath(*parts)
            if member.isdir():
                target.mkdir(parents=True, exist_ok=True)
            elif member.isfile():
                target.parent.mkdir(parents=True, exist_ok=True)
                source = archive.extractfile(member)
                assert source is not None  # a regular member always has data
                target.write_bytes(source.read())
                target.chmod(0o755 if member.mode & 0o111 else 0o644)
            elif member.issym():
                link = PurePosixPath(member.linkname)
                inside = PurePosixPath(*parts[:-1], link)
                if link.is_absolute() or ".." in inside.parts[: len(inside.parts) - len(link.parts)] or \
                        _escapes(inside):
                    continue  # e.g. sitecustomize.py -> /etc/...: a file of the build machine, never bundled
                target.parent.mkdir(parents=True, exist_ok=True)
                target.unlink(missing_ok=True)
                target.symlink_to(member.linkname)


def _escapes(path: PurePosixPath) -> bool:
    """Whether the relative ``path`` (with ``..``) leaves its root."""
    depth = 0
    for part in path.parts:
        depth += -1 if part == ".." else 1
        if depth < 0:
            return True
    return False


def ensure_runtime(cache: Path = DEFAULT_CACHE) -> Runtime:
    """The runtime unpacked under ``cache/root`` (fetched and unpacked on first use)."""
    root = cache / "root"
    stamp = root / ".pins"
    if stamp.is_file() and stamp.read_text() == manifest():
        return Runtime(root)
    debs = fetch(cache)
    staging = Path(tempfile.mkdtemp(prefix="root.", dir=cache))
    try:
        for pin in PACKAGES:
            unpack_deb(debs / pin.file_name, staging)
        (staging / ".pins").write_text(manifest())
        shutil.rmtree(root, ignore_errors=True)
        staging.rename(root)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return Runtime(root)


# ---- Moving the pins: Debian's package indexes ----------------------------------------------------


def _compare_part(a: str, b: str) -> int:
    """dpkg's comparison of an upstream version or revision: alternately a run of non-digits
    (character by character, '~' before the end, letters before the other characters) and a
    run of digits (as a number)."""

    def order(char: str) -> int:
        return -1 if char == "~" else ord(char) if char.isalpha() else ord(char) + 256

    while a or b:
        i = next((k for k, c in enumerate(a) if c.isdigit()), len(a))
        j = next((k for k, c in enumerate(b) if c.isdigit()), len(b))
        x, y = [order(c) for c in a[:i]] + [0], [order(c) for c in b[:j]] + [0]
        x += [0] * (len(y) - len(x))
        y += [0] * (len(x) - len(y))
        if x != y:
            return -1 if x < y else 1
        a, b = a[i:], b[j:]
        i = len(a) - len(a.lstrip("0123456789"))
        j = len(b) - len(b.lstrip("0123456789"))
        m, n = int(a[:i] or 0), int(b[:j] or 0)
        if m != n:
            return -1 if m < n else 1
        a, b = a[i:], b[j:]
    return 0


def compare_versions(a: str, b: str) -> int:
    """-1, 0 or 1 as the Debian version ``a`` is older than, the same as or newer than ``b``
    (epoch, upstream version, revision: Debian Policy 5.6.12, what dpkg --compare-versions does)."""

    def split(version: str) -> tuple[int, str, str]:
        epoch, _, rest = version.partition(":") if ":" in version else ("0", "", version)
        upstream, _, revision = rest.rpartition("-") if "-" in rest else (rest, "", "")
        return int(epoch), upstream, revision

    (e, u, r), (f, v, s) = split(a), split(b)
    if e != f:
        return -1 if e < f else 1
    return _compare_part(u, v) or _compare_part(r, s)


class Candidate(NamedTuple):
    """A package version one suite offers."""

    suite: str
    pin: Pin


def _gpgv(signed: bytes, suite: str) -> str:
    """'' when gpgv confirms Debian's signature of ``signed`` (an InRelease), a note when gpgv or
    the keyring is not there; RuntimeBundleError when the signature is bad."""
    if not shutil.which("gpgv") or not KEYRING.is_file():
        return f"{suite}: InRelease signature not checked (no gpgv or {KEYRING})"
    result = subprocess.run(["gpgv", "--keyring", str(KEYRING), "-"], input=signed, capture_output=True)
    if result.returncode != 0:
        raise RuntimeBundleError(f"{suite}: InRelease does not carry a valid Debian signature: "
                                 f"{result.stderr.decode(errors='replace').strip().splitlines()[-1:]}")
    return ""


def _index(archive: str, suite: str, cache: Path, notes: list[str]) -> str:
    """The text of ``suite``'s main/binary-amd64 Packages index, checked against the InRelease
    (whose signature gpgv checks where installed); kept in ``cache`` under its digest."""
    release = _get(f"{MIRROR}/{archive}/dists/{suite}/InRelease", MAX_INDEX)
    note = _gpgv(release, suite)
    if note:
        notes.append(note)
    wanted = "main/binary-amd64/Packages.xz"
    digest, size, section = "", 0, ""
    for line in release.decode("utf-8", "replace").splitlines():
        if not line.startswith(" "):
            section = line.rstrip(":")
            continue
        fields = line.split()
        if section == "SHA256" and len(fields) == 3 and fields[2] == wanted:
            digest, size = fields[0], int(fields[1])
    if not digest:
        raise RuntimeBundleError(f"{suite}: its InRelease lists no SHA-256 of {wanted}")
    kept = cache / f"{digest}.xz"
    if kept.is_file() and _sha256(kept) == digest:
        data = kept.read_bytes()
    else:
        data = _get(f"{MIRROR}/{archive}/dists/{suite}/{wanted}", max(size, 1) + 1024)
        if hashlib.sha256(data).hexdigest() != digest:
            raise RuntimeBundleError(f"{suite}: {wanted} does not match the SHA-256 of its InRelease")
        cache.mkdir(parents=True, exist_ok=True)
        kept.write_bytes(data)
    return lzma.decompress(data).decode("utf-8", "replace")


def newest_versions(pins: Sequence[Pin] = PACKAGES, cache: Path = DEFAULT_CACHE / "index",
                    notes: list[str] | None = None) -> dict[str, Candidate]:
    """For each pinned package, the newest version bookworm, bookworm-updates and
    bookworm-security offer (from their signed package indexes), with its SHA-256, size and path."""
    names = {pin.name for pin in pins}
    newest: dict[str, Candidate] = {}
    for archive, suite in SUITES:
        for stanza in _index(archive, suite, cache, notes if notes is not None else []).split("\n\n"):
            fields = dict(line.split(": ", 1) for line in stanza.splitlines()
                          if ": " in line and not line.startswith(" "))
            name = fields.get("Package")
            if name not in names or fields.get("Architecture") not in ("amd64", "all"):
                continue
            pin = Pin(name, fields["Version"], fields["SHA256"], int(fields["Size"]),
                      f"{archive}/{fields['Filename']}")
            if name not in newest or compare_versions(pin.version, newest[name].pin.version) > 0:
                newest[name] = Candidate(suite, pin)
    absent = sorted(names - set(newest))
    if absent:
        raise RuntimeBundleError(f"bookworm offers no {', '.join(absent)} for amd64")
    return newest


def _superseded(pins: Sequence[Pin], newest: dict[str, Candidate]) -> list[tuple[Pin, Candidate]]:
    return [(pin, newest[pin.name]) for pin in pins
            if compare_versions(newest[pin.name].pin.version, pin.version) > 0]


def check_pins(pins: Sequence[Pin] = PACKAGES, cache: Path = DEFAULT_CACHE / "index") -> str:
    """One line: whether Debian has newer versions of the pinned packages than the pins (never
    an exception: offline, it says so)."""
    try:
        changes = _superseded(pins, newest_versions(pins, cache))
    except (RuntimeBundleError, urllib.error.URLError, OSError, lzma.LZMAError, ValueError) as error:
        return f"runtime pins: not checked ({getattr(error, 'reason', error)})"
    if not changes:
        return f"runtime pins: current ({len(pins)} packages, newest in bookworm and bookworm-security)"
    moved = ", ".join(f"{pin.name} {pin.version} -> {new.pin.version} ({new.suite})" for pin, new in changes)
    return f"runtime pins: superseded: {moved}; run '{UPDATE_COMMAND}'"


def write_pins(pins: Sequence[Pin], path: Path = PINS_FILE) -> None:
    """Write the pin list (the format :func:`read_pins` reads)."""
    lines = [
        "# The Debian 12 (bookworm, amd64) packages of the FMUs' CPython runtime: package, version,",
        "# SHA-256 and size of the .deb, and its path under Debian's mirror. Written by",
        f"# '{UPDATE_COMMAND}' (python -m fmu_src.toolchain.runtime update); see docs/fmus/runtime.md.",
    ]
    lines += [f"{p.name} {p.version} {p.sha256} {p.size} {p.path}" for p in pins]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def update_pins(path: Path = PINS_FILE, cache: Path = DEFAULT_CACHE / "index") -> list[str]:
    """Move the pins of ``path`` to the newest versions bookworm(-updates, -security) offer and
    rewrite it; the lines saying what changed (or that nothing did)."""
    pins = read_pins(path)
    notes: list[str] = []
    newest = newest_versions(pins, cache, notes)
    changes = _superseded(pins, newest)
    moved = {pin.name: new.pin for pin, new in changes}
    updated = [moved.get(pin.name, pin) for pin in pins]
    python = {pin.version for pin in updated if pin.name.startswith("libpython")}
    if len(python) > 1:  # built from one source package: only one version works with the others
        raise RuntimeBundleError(f"the libpython3.11 packages would get different versions: {sorted(python)}")
    write_pins(updated, path)
    lines = notes + [f"{pin.name}: {pin.version} -> {new.pin.version} ({new.suite}, {new.pin.path})"
                     for pin, new in changes]
    return lines or [f"runtime pins: already the newest ({len(pins)} packages); {path.name} unchanged"]


# Run in the bundled interpreter: import the staged FMU's script as pythonfmu's binary does, make
# an instance and drive it through every call a host makes (the shim's direct binding included),
# then report every module the process holds that is not frozen into libpython (name -> file;
# None for one built into libpython). What the FMU imports at run time, measured, not guessed.
IMPORT_PROBE = """
import sys
resources, model, script, *excluded = sys.argv[1:]
for name in excluded:  # not bundled: as in the FMU, importing one fails (its importers fall back)
    sys.modules.setdefault(name, None)
sys.path.insert(0, resources)
module = __import__(script)
slave = getattr(module, model)(instance_name="probe", resources=resources, visible=False)
slave.setup_experiment(0.0, 1.0, None)
slave.enter_initialization_mode()
slave.exit_initialization_mode()
kinds = {kind: [vr for vr, v in slave.vars.items() if type(v).__name__ == kind]
         for kind in ("Real", "Integer", "Boolean", "String")}
reals = slave.get_real(kinds["Real"])
slave.get_integer(kinds["Integer"]), slave.get_boolean(kinds["Boolean"]), slave.get_string(kinds["String"])
claim = getattr(sys, "_ftc_fmu_claim", None)
binding = claim(model, "probe") if claim else None
for k in range(3):
    slave.do_step(0.01 * k, 0.01)
    if binding:
        binding[2](0.01 * k, 0.01)
        binding[3]()
slave._set_fmu_state(slave._get_fmu_state())
slave.terminate()
found = {}
for name, m in sorted(sys.modules.items()):
    spec = getattr(m, "__spec__", None)
    ours = name.startswith(("ftc_", "_ftc_", "pythonfmu"))
    if m is None or spec is None or spec.origin == "frozen" or ours:
        continue
    found[name] = getattr(m, "__file__", None)
import json
print(json.dumps(found))
"""


def measured_imports(runtime: Runtime, launcher: Path, resources: Path, model: str,
                     script: str) -> dict[str, Path | None]:
    """Every standard-library module (dotted name -> file in the runtime, None for one built into
    libpython) that the FMU whose Python code is staged in ``resources`` imports when it runs:
    its ``script`` module imported and ``model`` instantiated, initialized, stepped (also through
    the shim's direct binding), its state got and set and terminated, in the bundled interpreter
    over the runtime's whole standard library (:data:`IMPORT_PROBE`). Modules frozen into
    libpython are left out: they are never read from the zip."""
    stdlib = str(runtime.stdlib)
    found = runtime.run(launcher, IMPORT_PROBE, None, [str(resources), model, script, *EXCLUDED])
    assert isinstance(found, dict)
    measured: dict[str, Path | None] = {}
    for name, file in found.items():
        if file is None:
            measured[name] = None
        elif str(file).startswith(stdlib + "/"):
            measured[name] = Path(file)
    for name in STARTUP_MODULES:  # imported by the interpreter's start, before any probe runs
        measured.setdefault(name, runtime.stdlib.joinpath(*name.split(".")).with_suffix(".py"))
    return dict(sorted(measured.items()))


def _needed(path: Path) -> list[str]:
    """The DT_NEEDED entries of a shared object (readelf, from binutils)."""
    try:
        result = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as error:
        raise RuntimeBundleError(f"readelf (binutils) cannot list what {path.name} needs: {error}") from error
    return [line.split("[", 1)[1].rstrip("]") for line in result.stdout.splitlines() if "(NEEDED)" in line]


# Writes the standard-library zip in the bundled interpreter (see Runtime.run), every module as
# unchecked-hash bytecode (PEP 552: valid whatever the unpacked files' times).
ZIP_WRITER = """
import json, py_compile, sys, tempfile, zipfile
modules, target, date = json.loads(sys.stdin.read())
with zipfile.ZipFile(target, "w") as archive, tempfile.TemporaryDirectory() as tmp:
    for source, name in modules:
        py_compile.compile(source, cfile=tmp + "/m.pyc", dfile=name, doraise=True,
                           invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
        info = zipfile.ZipInfo(name + "c", date_time=tuple(date))
        info.compress_type = zipfile.ZIP_DEFLATED
        info.external_attr = 0o644 << 16
        archive.writestr(info, open(tmp + "/m.pyc", "rb").read())
print("null")
"""

# Compiles Python sources to unchecked-hash bytecode in the bundled interpreter (see Runtime.run).
PYC_WRITER = """
import json, py_compile, sys
for source, cfile, dfile in json.loads(sys.stdin.read()):
    py_compile.compile(source, cfile=cfile, dfile=dfile, doraise=True,
                       invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
print(json.dumps(sys.implementation.cache_tag))
"""


def read_kept(path: Path) -> bytes | None:
    """The bytes a build kept in ``path`` (None if it has none there), marked as used now: the
    modification time orders the build's pruning of kept files (``build.prune_kept``). A file
    removed meanwhile by a pruning beside is none."""
    try:
        with path.open("rb") as kept:
            data = kept.read()
        os.utime(path)
    except FileNotFoundError:
        return None
    return data


def keep(path: Path, data: bytes) -> None:
    """Keep ``data`` in ``path``, written under ``.<name>.<pid>`` and renamed: a build beside reads
    all of it or nothing, and a half-written file is left to the pruning."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.{os.getpid()}")
    partial.write_bytes(data)
    partial.replace(path)


def _stdlib_zip(runtime: Runtime, launcher: Path, modules: dict[str, Path]) -> bytes:
    """``python311.zip`` of the given modules, compiled by the bundled interpreter; kept in the
    runtime's cache (``members/``) under the digest of the runtime, the interpreter, the writer and
    the modules, since most FMUs import the same ones (a cold build compiled it nine times, 0.37 s
    of CPU each, for two different sets)."""
    listing = [(str(modules[n]), modules[n].relative_to(runtime.stdlib).as_posix()) for n in sorted(modules)]
    key = hashlib.sha256(json.dumps([manifest(), launcher.name, ZIP_WRITER, ZIP_DATE,
                                     [name for _, name in listing]]).encode()).hexdigest()
    kept = runtime.root.parent / "members" / f"stdlib-{key}.zip"
    known = read_kept(kept)
    if known is not None:
        return known
    with tempfile.TemporaryDirectory() as tmp:
        target = Path(tmp) / f"python{TAG}.zip"
        runtime.run(launcher, ZIP_WRITER, [listing, str(target), ZIP_DATE])
        data = target.read_bytes()
    keep(kept, data)
    return data


def compile_bytecode(runtime: Runtime, launcher: Path, sources: dict[str, bytes]) -> dict[str, bytes]:
    """Unchecked-hash ``.pyc`` bytes (PEP 552) of each Python source (member name -> text), keyed
    by its ``__pycache__`` member name, compiled by the bundled interpreter: the bytes do not
    depend on the Python that runs the build."""
    with tempfile.TemporaryDirectory() as tmp:
        jobs, members = [], []
        for i, name in enumerate(sorted(sources)):
            source = Path(tmp, f"{i}.py")
            source.write_bytes(sources[name])
            folder, file = name.rsplit("/", 1)
            members.append(f"{folder}/__pycache__/{file[:-3]}.cpython-{TAG}.pyc")
            jobs.append((str(source), str(Path(tmp, f"{i}.pyc")), name.removeprefix("resources/")))
        tag = runtime.run(launcher, PYC_WRITER, jobs)
        if tag != f"cpython-{TAG}":
            raise RuntimeBundleError(f"the bundled interpreter is {tag}, not cpython-{TAG}")
        return {member: Path(cfile).read_bytes() for member, (_, cfile, _) in zip(members, jobs, strict=True)}


def runtime_members(runtime: Runtime, launcher: Path, measured: dict[str, Path | None]) -> dict[str, bytes]:
    """Archive members (name -> bytes) of the runtime for an FMU that imports the modules
    ``measured`` (:func:`measured_imports`; ``launcher``: the bundled interpreter, see
    :meth:`Runtime.run`): libraries, standard-library zip, extension modules, manifest and licences."""
    closure = {name: file for name, file in measured.items() if file is not None}
    base = "binaries/linux64/python/"
    members = {base + name: (runtime.root / source).read_bytes() for source, name in LIBRARIES}
    pure = {n: p for n, p in closure.items() if p.suffix == ".py"}
    members[f"{base}python{TAG}.zip"] = _stdlib_zip(runtime, launcher, pure)
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
    """Command line: fetch (the default), check or update the runtime's pins; see the module's
    docstring."""
    args = list(sys.argv[1:] if argv is None else argv)
    command = args.pop(0) if args and args[0] in ("fetch", "check", "update") else "fetch"
    try:
        if command == "check":
            print(check_pins())
        elif command == "update":
            for line in update_pins():
                print(line)
        else:
            print(ensure_runtime(Path(args[0]) if args else DEFAULT_CACHE).root)
    except (RuntimeBundleError, urllib.error.URLError, OSError, lzma.LZMAError) as error:
        print(f"error: {getattr(error, 'reason', error)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
