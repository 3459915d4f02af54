# SPDX-License-Identifier: BSD-2-Clause
"""The FMUs' runtime builds on any machine (issue 30): fetched from Debian's archive by URL without
apt-get or dpkg-deb, as root and as a user; a pin Debian dropped, or no network, is one line naming
what to do; the pins move to the newest bookworm(-security) versions with one command; and the FMUs'
bytes do not depend on the Python that runs the build.

Oracles: dpkg itself (``dpkg-deb -x`` of the same package, ``dpkg-deb -f`` for its version,
``dpkg --compare-versions``), Debian's signed package indexes, and the bytes of a build made by a
second Python. Before (main 5287c35): the runtime came from ``apt-get download`` and ``dpkg-deb -x``
(without apt-get: a 20-line FileNotFoundError traceback), the pins were behind bookworm-security,
and a build on Python 3.12 gave other bytes (.py sources instead of bytecode)."""

from __future__ import annotations

import filecmp
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

from fmu_src.toolchain import runtime
from fmu_src.toolchain.build import REPO_ROOT

pytestmark = pytest.mark.system
DPKG_DEB = shutil.which("dpkg-deb")
ALT_PYTHON = REPO_ROOT / ".venv-alt" / "bin" / "python"
SYSTEM_PYTHON = Path("/usr/bin/python3.11")  # a Python an unprivileged user may run (the venv's is root's)
# The pins of main 5287c35 (Debian 12.13's point release), superseded by bookworm-security since.
POOL = {"libexpat1": "e/expat", "zlib1g": "z/zlib"}  # the others: p/python3.11
OLD_PINS = "".join(
    f"{name} {version} {digest} {size} debian/pool/main/{POOL.get(name, 'p/python3.11')}/"
    f"{name}_{version.split(':')[-1]}_amd64.deb\n"
    for name, version, digest, size in (
        ("libpython3.11", "3.11.2-6+deb12u8",
         "63845d53d5f64d2362cfb6007ec175ad1c6044cebe60a1885eff76d2ce637c35", 1988456),
        ("libpython3.11-minimal", "3.11.2-6+deb12u8",
         "f3beaa03994ffedacf73c43a0843d53b062d347115d8af65bee2034552a4e6f9", 817740),
        ("libpython3.11-stdlib", "3.11.2-6+deb12u8",
         "890b3540dad8a1ccc0deeca025db735bcc82629a76adacbe3b50fcc06ed528ca", 1798560),
        ("libpython3.11-dev", "3.11.2-6+deb12u8",
         "01a8eddeb8505bb6e2c01209cda66b41fb5ebeaa64e69d0e25f7131915f1cd32", 4737920),
        ("libexpat1", "2.5.0-1+deb12u2",
         "2255e62fc22a86d2c544b8a3f516da9aee19383ad5742722ab4ce7f66a30dbc8", 99888),
        ("zlib1g", "1:1.2.13.dfsg-1",
         "d7dd1d1411fedf27f5e27650a6eff20ef294077b568f4c8c5e51466dc7c08ce4", 86684),
    )
)


def tools_without_apt(tmp_path: Path) -> Path:
    """A folder for PATH holding what the runtime's fetch may use (compiler, readelf, gpgv, the
    shell's basics) and neither apt-get nor dpkg-deb."""
    folder = tmp_path / "bin"
    folder.mkdir()
    for tool in ("sh", "cc", "gcc", "readelf", "gpgv", "env", "ls"):
        found = shutil.which(tool)
        if found:
            (folder / tool).symlink_to(found)
    return folder


def fetch_command(python: Path, cache: Path, path: Path) -> subprocess.CompletedProcess:
    env = {"PATH": str(path), "HOME": str(cache.parent), "PYTHONPATH": str(REPO_ROOT)}
    return subprocess.run([str(python), "-m", "fmu_src.toolchain.runtime", "fetch", str(cache)],
                          capture_output=True, text=True, env=env, cwd=REPO_ROOT, timeout=600)


def same_tree(ours: Path, theirs: Path) -> None:
    """Every regular file and relative symbolic link dpkg-deb unpacked is in ``ours``, the same."""
    for path in theirs.rglob("*"):
        mine = ours / path.relative_to(theirs)
        if path.is_symlink():
            target = os.readlink(path)
            if not target.startswith("/"):
                assert os.readlink(mine) == target, mine
        elif path.is_file():
            assert filecmp.cmp(mine, path, shallow=False), mine


@pytest.mark.skipif(DPKG_DEB is None, reason="dpkg-deb (the oracle) is not installed")
def test_fetch_without_apt_get_or_dpkg_deb_as_root_and_as_a_user(tmp_path: Path) -> None:
    """``python -m fmu_src.toolchain.runtime fetch`` with apt-get and dpkg-deb hidden from PATH: as this user
    (root, as CI) and as an unprivileged one (setpriv, a Python the user may run). What it unpacked
    is, file for file, what ``dpkg-deb -x`` makes of the same packages."""
    path = tools_without_apt(tmp_path)
    assert shutil.which("apt-get", path=str(path)) is None
    assert shutil.which("dpkg-deb", path=str(path)) is None
    cache = tmp_path / "root-cache"
    result = fetch_command(Path(sys.executable), cache, path)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    oracle = tmp_path / "dpkg"
    for pin in runtime.PACKAGES:
        deb = cache / "debs" / pin.file_name
        subprocess.run([str(DPKG_DEB), "-x", str(deb), str(oracle)], check=True)
        version = subprocess.run([str(DPKG_DEB), "-f", str(deb), "Version"], capture_output=True, text=True,
                                 check=True).stdout.strip()
        assert version == pin.version
    same_tree(cache / "root", oracle)

    setpriv = shutil.which("setpriv")
    if os.geteuid() != 0 or setpriv is None or not SYSTEM_PYTHON.is_file():
        pytest.skip("the unprivileged run needs root, setpriv and /usr/bin/python3.11")
    home = Path(tempfile.mkdtemp(prefix="ftc-user-", dir="/tmp"))  # pytest's own folders are root's alone
    try:
        os.chmod(home, 0o755)
        os.chown(home, 65534, 65534)
        user = [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups"]
        env = {"PATH": str(path), "HOME": str(home), "PYTHONPATH": str(REPO_ROOT)}
        command = [*user, str(SYSTEM_PYTHON), "-m", "fmu_src.toolchain.runtime", "fetch", str(home / "cache")]
        result = subprocess.run(command, capture_output=True, text=True, env=env, cwd=str(home), timeout=600)
        assert result.returncode == 0, result.stderr
        assert (home / "cache" / "root").stat().st_uid == 65534
        same_tree(home / "cache" / "root", oracle)
    finally:
        shutil.rmtree(home)


def one_line_error(command: list[str], env: dict[str, str]) -> str:
    result = subprocess.run(command, capture_output=True, text=True, env=env, cwd=REPO_ROOT, timeout=300)
    assert result.returncode == 1, result
    assert result.stdout == "" and len(result.stderr.splitlines()) == 1, result.stderr
    assert "Traceback" not in result.stderr
    return result.stderr


def test_offline_with_no_cache_is_one_line(tmp_path: Path) -> None:
    """A mirror that does not answer (a closed port here) and an empty cache: one line, naming
    the cache and the pin file, exit 1."""
    env = {"PATH": os.environ["PATH"], "FTC_DEBIAN_MIRROR": "http://127.0.0.1:9"}
    line = one_line_error([sys.executable, "-m", "fmu_src.toolchain.runtime", "fetch", str(tmp_path / "c")],
                          env)
    assert "cannot reach Debian's archive" in line and "runtime_pins.txt" in line


def test_a_version_the_archive_no_longer_has_names_the_update_command(tmp_path: Path) -> None:
    """A pin whose file is in neither pool (a version that never was): one line saying so and
    naming 'make runtime-pins'."""
    gone = runtime.Pin("libexpat1", "2.5.0-1+deb12u0", "0" * 64, 100000,
                       "debian/pool/main/e/expat/libexpat1_2.5.0-1+deb12u0_amd64.deb")
    with pytest.raises(runtime.RuntimeBundleError) as raised:
        runtime.fetch(tmp_path, [gone])
    message = str(raised.value)
    assert "no longer has libexpat1 2.5.0-1+deb12u0" in message and "make runtime-pins" in message
    assert "\n" not in message and "HTTP 404" in message


def test_update_moves_old_pins_to_the_newest_and_says_what_changed(tmp_path: Path) -> None:
    """The pins of main, updated: every package moves to a newer version (bookworm-security's
    libpython3.11 and expat), the file is rewritten in the format the build reads, each change is
    one line, and a check of the result finds nothing superseded. The new expat's .deb, fetched,
    carries the pinned version (dpkg-deb's word)."""
    pins = tmp_path / "runtime_pins.txt"
    pins.write_text(OLD_PINS)
    old = {p.name: p for p in runtime.read_pins(pins)}
    assert "superseded" in runtime.check_pins(tuple(old.values()))
    lines = runtime.update_pins(pins)
    new = {p.name: p for p in runtime.read_pins(pins)}
    assert set(new) == set(old)
    for name in ("libpython3.11", "libpython3.11-stdlib", "libexpat1"):
        assert runtime.compare_versions(new[name].version, old[name].version) > 0
        assert any(line.startswith(f"{name}: {old[name].version} -> {new[name].version} (bookworm")
                   for line in lines), lines
    assert len({p.version for n, p in new.items() if n.startswith("libpython")}) == 1
    assert runtime.check_pins(tuple(new.values())).startswith("runtime pins: current")
    if DPKG_DEB:
        debs = runtime.fetch(tmp_path / "cache", [new["libexpat1"]])
        deb = debs / new["libexpat1"].file_name
        field = [DPKG_DEB, "-f", str(deb), "Version"]
        version = subprocess.run(field, capture_output=True, text=True, check=True)
        assert version.stdout.strip() == new["libexpat1"].version


def test_the_superseded_check_is_one_line() -> None:
    """What `make test` prints: one line whatever the archive says (here: the pins of main, which
    bookworm-security has superseded)."""
    old = runtime.parse_pins(OLD_PINS)
    line = runtime.check_pins(old)
    assert "\n" not in line
    assert line.startswith("runtime pins: superseded: libpython3.11 3.11.2-6+deb12u8 -> ")
    assert "make runtime-pins" in line


VERSIONS = ["1.0", "1.0-1", "1.0-0", "1.0~rc1", "1.0~rc1-1", "1.0+1", "1.0a", "1.0.1", "1:0.9", "0:1.0",
            "2.0", "3.11.2-6+deb12u8", "3.11.2-6+deb12u9", "3.11.2-6+deb12u10", "3.11.2-6", "2.5.0-1+deb12u5",
            "1:1.2.13.dfsg-1", "1.2.13.dfsg-1", "1.0~~", "1.0~", "1.0-1~bpo1", "10", "9", "1.a", "1.+",
            "1.01"]


@pytest.mark.skipif(shutil.which("dpkg") is None, reason="dpkg (the oracle) is not installed")
def test_version_order_is_dpkgs() -> None:
    """compare_versions agrees with ``dpkg --compare-versions`` on every pair of these."""
    for k, a in enumerate(VERSIONS):
        for b in VERSIONS[k:]:
            ours = runtime.compare_versions(a, b)
            theirs = subprocess.run(["dpkg", "--compare-versions", a, "lt", b]).returncode == 0
            same = subprocess.run(["dpkg", "--compare-versions", a, "eq", b]).returncode == 0
            assert ours == (0 if same else -1 if theirs else 1), (a, b)
            assert runtime.compare_versions(b, a) == -ours, (b, a)


@pytest.mark.skipif(not ALT_PYTHON.is_file(), reason=f"no venv of a second Python version: {ALT_PYTHON}")
def test_a_second_builder_python_gives_the_same_bytes(built: Path, tmp_path: Path) -> None:
    """Actuator built by another Python (make's .venv-alt, 3.12) is byte-identical to the build of
    this one (3.11), FMI 2.0 and 3.0 (before: other bytes and GUIDs, .py sources instead of .pyc)."""
    probe = subprocess.run([str(ALT_PYTHON), "-c", "import sys, pythonfmu; print(sys.version_info[:2])"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"{ALT_PYTHON} has no pythonfmu (make's .venv-alt installs it)")
    assert probe.stdout.strip() != str(sys.version_info[:2])
    command = [str(ALT_PYTHON), "-m", "fmu_src.toolchain", str(tmp_path / "fmus"), "--model",
               "Actuator", "--fmi3", str(tmp_path / "fmus3")]
    result = subprocess.run(command, capture_output=True, text=True, cwd=REPO_ROOT, timeout=600,
                            env={"PATH": os.environ["PATH"], "PYTHONPATH": str(REPO_ROOT)})
    assert result.returncode == 0, result.stderr
    for folder in ("fmus", "fmus3"):
        ours, theirs = built / folder / "Actuator.fmu", tmp_path / folder / "Actuator.fmu"
        assert theirs.read_bytes() == ours.read_bytes(), folder
    with zipfile.ZipFile(tmp_path / "fmus" / "Actuator.fmu") as archive:
        assert any(n.endswith(".cpython-311.pyc") for n in archive.namelist())
