# SPDX-License-Identifier: BSD-2-Clause
"""What every FMU and exported container says about its licences and its external dependencies.

The FMI standard (3.0, section 2.5; 2.0.3 as a "should") puts licences under
``documentation/licenses/`` with an entry point ``license.{txt|html|spdx}``, and dependencies on
anything outside the archive in ``documentation/externalDependencies.{txt|html}``. The project's
own licence (BSD-2-Clause) ships beside the third-party ones (CPython, Debian's copyright files,
pythonfmu), so that anyone may redistribute an FMU; the entry point lists every licence file of
the archive with what it covers.
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Iterable
from pathlib import Path

__all__ = ["CONTAINER_DEPENDENCIES", "DISTRIBUTION", "LICENSES", "PROJECT_LICENSE", "documentation",
           "generation_tool", "project_licence"]

DISTRIBUTION = "fixed-time-cosim"
LICENSES = "documentation/licenses/"
PROJECT_LICENSE = "fixed-time-cosim-LICENSE.txt"
# licence file -> (what it covers, SPDX identifier); files of the archive not named here are
# listed as "see the file".
NOTICES = {
    PROJECT_LICENSE: ("this FMU's own code: the model and its Python sources, the shim, the container",
                      "BSD-2-Clause"),
    "pythonfmu-LICENSE.txt": ("pythonfmu 0.7.0: its binary (binaries/*/<model>_pythonfmu.*) and package",
                              "MIT"),
    "fmath-LICENSE.txt": ("controller/fmath (exp, sin, cos, pow), transcribed from musl's src/math, which "
                          "derives from Sun's fdlibm", "MIT"),
    "xz-embedded-COPYING.txt": ("XZ Embedded (Lasse Collin and contributors): the .xz decoder compiled into "
                                "the shim, which decodes python/lib/libpython3.11.so.1.0.xz and "
                                "python/python311.dll.xz", "0BSD"),
    "Python-LICENSE.txt": ("CPython 3.11: libpython and the standard library under binaries/*/python/",
                           "PSF-2.0"),
    "Python-debian-copyright.txt": ("Debian's packages of CPython 3.11 (copyright file)", "PSF-2.0"),
    "expat-debian-copyright.txt": ("expat, fallback/libexpat.so.1 (Debian's copyright file)", "MIT"),
    "zlib-debian-copyright.txt": ("zlib, fallback/libz.so.1 (Debian's copyright file)", "Zlib"),
    "Python-embeddable-LICENSE.txt": (
        "python.org's embeddable CPython 3.11 under binaries/win64/python/ (python311.dll, python3.dll, "
        "python311.zip, the .pyd modules), unmodified; its 'Additional Conditions for this Windows binary "
        "build' on the Microsoft Distributable Code it is linked with", "PSF-2.0"),
    "MSVC-runtime-redistribution.txt": (
        "Microsoft's Visual C++ runtime under binaries/win64/python/ (vcruntime140.dll, vcruntime140_1.dll, "
        "msvcp140.dll): Visual Studio 2022's Distributable Code (its REDIST list), shipped unmodified "
        "for Windows only", "LicenseRef-Microsoft-Visual-CPP-Redistributable"),
}
EXTERNAL_DEPENDENCIES = """\
External dependencies of this FMU (FMI 3.0 section 2.5, documentation/externalDependencies.txt)

Nothing needs to be installed: no Python, no environment variable, no network, no tool
(needsExecutionTool="false"). Each FMU carries its own CPython runtime. What it uses of the
machine it runs on:

binaries/linux64 (FMI 3.0: binaries/x86_64-linux), Linux x86_64:
  * the C library: glibc 2.35 or newer (libc.so.6, libm.so.6);
  * the C++ runtime of GCC 12 or newer: libstdc++.so.6 (GLIBCXX_3.4.30, CXXABI_1.3.9) and
    libgcc_s.so.1, used by pythonfmu's binary;
  * expat and zlib are taken from the machine where present, else from python/fallback/.
  So: Debian 12+, Ubuntu 22.04+, Fedora 36+, RHEL/Rocky/Alma 10; not RHEL 9 or Ubuntu 20.04.

binaries/win64 (FMI 3.0: binaries/x86_64-windows), Windows x64: Windows 10 or newer (the floor of
python.org's CPython 3.11). From Windows itself: KERNEL32.dll, msvcrt.dll and the Universal C
Runtime (api-ms-win-crt-*.dll, part of Windows 10); CPython (python311.dll, python3.dll) and the
MSVC runtime (MSVCP140.dll, VCRUNTIME140.dll, VCRUNTIME140_1.dll) are under python/.
"""
CONTAINER_DEPENDENCIES = """\
External dependencies of this FMU (FMI 3.0 section 2.5, documentation/externalDependencies.txt)

This FMU is a co-simulation of the FMUs under resources/fmus/<name>/, stepped by a C library that
needs only the C library of its platform: on Linux x86_64 (binaries/linux64 or
binaries/x86_64-linux) glibc 2.35 or newer, on Windows x64 (binaries/win64 or
binaries/x86_64-windows) Windows' own KERNEL32.dll and msvcrt.dll. No Python, no tool
(needsExecutionTool="false"). The FMUs it holds may need more: each says so in its own
documentation/externalDependencies.txt (on Linux the fixed-time-cosim FMUs need the C++ runtime of
GCC 12: libstdc++.so.6 and libgcc_s.so.1; on Windows, Windows 10 or newer).
"""


def project_licence() -> bytes:
    """The project's LICENSE: from the installed distribution's metadata (PEP 639), else from the
    checkout this module lies in."""
    try:
        text = importlib.metadata.distribution(DISTRIBUTION).read_text("licenses/LICENSE")
    except importlib.metadata.PackageNotFoundError:
        text = None
    if text:
        return text.encode("utf-8")
    checkout = Path(__file__).resolve().parents[2] / "LICENSE"
    if checkout.is_file():
        return checkout.read_bytes()
    raise FileNotFoundError(f"no LICENSE in the installed {DISTRIBUTION} or in {checkout.parent}")


def generation_tool(backend: str = "") -> str:
    """``generationTool`` of the model descriptions: this project and version, with what it built on."""
    try:
        version = importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        version = "source"
    return f"{DISTRIBUTION} {version}" + (f" ({backend})" if backend else "")


def _entry_point(files: Iterable[str], note: str) -> bytes:
    lines = ["Licences of this archive (the FMI entry point of documentation/licenses/)", ""]
    if note:
        lines += [note, ""]
    for name in sorted(set(files) | {PROJECT_LICENSE}):
        what, spdx = NOTICES.get(name, ("see the file", "see the file"))
        lines += [f"{name}", f"    covers:  {what}", f"    licence: {spdx}", ""]
    return "\n".join(lines).encode("utf-8")


def documentation(members: Iterable[str], note: str = "",
                  external: str = EXTERNAL_DEPENDENCIES) -> dict[str, bytes]:
    """The members to add to an archive whose other members are ``members``: the project's
    licence, the ``license.txt`` entry point listing every licence file of the archive, and
    ``externalDependencies.txt`` (``external``). ``note`` opens the entry point (e.g. where nested
    FMUs keep theirs)."""
    files = [m[len(LICENSES):] for m in members if m.startswith(LICENSES) and "/" not in m[len(LICENSES):]]
    files = [f for f in files if f not in ("license.txt", "")]
    return {
        LICENSES + PROJECT_LICENSE: project_licence(),
        LICENSES + "license.txt": _entry_point(files, note),
        "documentation/externalDependencies.txt": external.encode("utf-8"),
    }
