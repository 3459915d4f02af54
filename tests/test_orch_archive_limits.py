# SPDX-License-Identifier: BSD-2-Clause
"""Bounded extraction of hostile archives: only the SSD and what it references are extracted, and
the archive and every FMU in it stay within :class:`orchestrator.ssp.Limits` (refused in one line
naming the member, the limit and the option that raises it).

Oracles: the bytes on disk after unpacking (a folder walk), sizes computed here from what the
test wrote, the command's exit status and its one line.
"""

from __future__ import annotations

import random
import zipfile
from contextlib import ExitStack
from pathlib import Path

import pytest
from orch_helpers import loop_scenario, write_zip, zip_members

from orchestrator.cli import main
from orchestrator.errors import ScenarioError
from orchestrator.ssp import SSD_NAME, Limits, open_scenario

pytestmark = pytest.mark.system

MiB = 1 << 20


def _disk(folder: Path) -> int:
    return sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())


@pytest.fixture(scope="module")
def good(test_fmus, tmp_path_factory) -> Path:
    return loop_scenario(tmp_path_factory.mktemp("good") / "loop", test_fmus, stop=0.1)


def test_unused_member_is_not_extracted(good, tmp_path):
    """A 64 MiB member the SSD does not reference (1000:1 zeros) costs no disk and no refusal."""
    members = zip_members(good)
    referenced = sum(len(members[n]) for n in members)
    bad = write_zip(tmp_path / "junk.ssp", {**members, "resources/junk.bin": bytes(64 * MiB)})
    with ExitStack() as stack:
        folder = open_scenario(bad, stack)
        assert not (folder / "resources" / "junk.bin").exists()
        assert _disk(folder) == referenced  # exactly the SSD, the .ssv files and the FMUs
    assert main(["validate", str(bad)]) == 0


def test_compression_bomb_in_a_referenced_fmu_is_refused(good, tmp_path, capsys):
    members = zip_members(good)
    fmu = tmp_path / "Gain.fmu"
    write_zip(fmu, {**_members_of_bytes(members["resources/Gain.fmu"]), "resources/bomb.bin": bytes(8 * MiB)})
    bad = write_zip(tmp_path / "bomb.ssp", {**members, "resources/Gain.fmu": fmu.read_bytes()})
    assert main(["validate", str(bad)]) == 1
    out = capsys.readouterr().out.splitlines()
    ratio = 8 * MiB / zipfile.ZipFile(fmu).getinfo("resources/bomb.bin").compress_size
    assert out[0] == (f"error: bomb.ssp: resources/Gain.fmu: member 'resources/bomb.bin' expands {ratio:.0f} "
                      "times (to 8.0 MiB), above the limit of 100 (--max-ratio)")
    assert main(["validate", str(bad), "--max-ratio", "5000"]) == 0  # the option raises it


def test_fmu_member_escaping_is_refused_before_reading(good, tmp_path, capsys):
    members = zip_members(good)
    inner = _members_of_bytes(members["resources/Gain.fmu"])
    fmu = write_zip(tmp_path / "Gain.fmu", {**inner, "../evil.txt": b"x"})
    bad = write_zip(tmp_path / "evil.ssp", {**members, "resources/Gain.fmu": fmu.read_bytes()})
    assert main(["validate", str(bad)]) == 1
    assert capsys.readouterr().out.splitlines()[:2] == [
        "error: evil.ssp: resources/Gain.fmu: member '../evil.txt' points outside the archive folder",
        f"failed: {bad}: 1 error(s), 0 warning(s)"]  # refused whole: the FMU is not read


def _members_of_bytes(data: bytes) -> dict[str, bytes]:
    import io

    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {n: zf.read(n) for n in zf.namelist()}


@pytest.mark.parametrize("limits, message", [
    (Limits(members=5), "loop.ssp: 7 members, above the limit of 5 (--max-members)"),
    (Limits(xml=1 * MiB), "loop.ssp: member 'gain.ssv' is 2.0 MiB, above the limit of 1.0 MiB for an XML "
                          "file (--max-xml-size)"),
    (Limits(member=1 * MiB, xml=4 * MiB), "loop.ssp: member 'gain.ssv' is 2.0 MiB uncompressed, above the "
                                          "limit of 1.0 MiB per member (--max-member-size)"),
    (Limits(total=2 * MiB, xml=8 * MiB), "loop.ssp: {total} uncompressed in all, above the limit of 2.0 MiB "
                                         "(--max-total-size)"),
])
def test_limits_on_what_is_extracted(good, tmp_path, limits, message):
    members = zip_members(good)
    noise = random.Random(0).randbytes(MiB).hex().encode()  # 2 MiB that do not compress below 1:2
    padded = members["gain.ssv"].replace(b"<ssv:Parameters>", b"<!--" + noise + b"--><ssv:Parameters>")
    bad = write_zip(tmp_path / "loop.ssp", {**members, "gain.ssv": padded})
    total = sum(len(v) for v in {**members, "gain.ssv": padded}.values())  # every member is referenced
    message = message.format(total=f"{total / MiB:.1f} MiB")
    with ExitStack() as stack, pytest.raises(ScenarioError) as info:
        open_scenario(bad, stack, limits)
    assert info.value.problems == [message]
    with ExitStack() as stack:  # the defaults let it through
        assert (open_scenario(bad, stack) / SSD_NAME).is_file()


def test_limit_option_on_the_command_line(good, tmp_path, capsys):
    assert main(["validate", str(good), "--max-members", "3"]) == 1
    assert capsys.readouterr().out.splitlines()[0] == \
        "error: loop.ssp: 7 members, above the limit of 3 (--max-members)"
    with pytest.raises(SystemExit) as info:
        main(["validate", str(good), "--max-total-size", "lots"])
    assert info.value.code == 2
