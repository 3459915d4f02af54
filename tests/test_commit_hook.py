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


@pytest.mark.parametrize("message", [
    "Shim: call the models' step and refresh as C entries\nEach model extension now exposes a capsule\n",
    "Short subject\n\nA body of one line after the blank one.\n",
    "  \nLeading blank line, then a subject\nand its second line, no blank one\n",
    "One line with a trailing space \n\nbody\n"])
def test_the_hook_measures_the_subject_git_shows(tmp_path: Path, message: str) -> None:
    """The subject is the first paragraph, its lines joined, as git shows it (oracle: ``git log
    --format=%s`` of the same message committed without the hook): a body without the blank line
    before it is part of the subject."""
    who = {f"GIT_{role}_{field}": value for role in ("AUTHOR", "COMMITTER")
           for field, value in (("NAME", "t"), ("EMAIL", "t@example.org"))}
    env = {"PATH": "/usr/bin:/bin", "LC_ALL": "C.UTF-8", "HOME": str(tmp_path), **who}
    subprocess.run(["git", "init", "-q", str(tmp_path / "repo")], check=True, env=env, timeout=30)
    (tmp_path / "message").write_text(message, encoding="utf-8")
    subprocess.run(["git", "-C", str(tmp_path / "repo"), "commit", "-q", "--allow-empty", "--no-verify",
                    "-F", str(tmp_path / "message")], check=True, env=env, timeout=30)
    shown = subprocess.run(["git", "-C", str(tmp_path / "repo"), "log", "-1", "--format=%s"], check=True,
                           env=env, capture_output=True, text=True, timeout=30).stdout.rstrip("\n")
    done = subprocess.run(["sh", str(HOOK), str(tmp_path / "message")], capture_output=True, text=True,
                          env=env, timeout=30)
    assert (done.returncode == 0) == (len(shown) <= 72), (shown, done.stderr)
