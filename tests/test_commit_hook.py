# SPDX-License-Identifier: BSD-2-Clause
"""The commit-msg hook that make installs (issue 47 item 5): 40 of 139 subjects ran past 72
characters. Oracle: the hook's exit status on messages of known lengths (multibyte counted as
characters, git's comment lines skipped)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

HOOK = Path(__file__).resolve().parents[1] / ".githooks" / "commit-msg"


@pytest.mark.parametrize(("subject", "accepted"), [
    ("x" * 72, True), ("x" * 73, False), ("é" * 72, True), ("é" * 73, False), ("", True)])
def test_the_hook_takes_subjects_of_at_most_72_characters(tmp_path: Path, subject: str,
                                                          accepted: bool) -> None:
    message = tmp_path / "COMMIT_EDITMSG"
    body = "A body line longer than seventy-two characters is fine: the detail goes here, after all."
    message.write_text(f"# Please enter the commit message\n{subject}\n\n{body}\n", encoding="utf-8")
    done = subprocess.run(["sh", str(HOOK), str(message)], capture_output=True, text=True,
                          env={"PATH": "/usr/bin:/bin", "LC_ALL": "C.UTF-8"}, timeout=30)
    assert (done.returncode == 0) == accepted, done.stderr
    assert ("at most 72" in done.stderr) == (not accepted)
