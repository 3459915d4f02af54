# SPDX-License-Identifier: BSD-2-Clause
"""The engine's Python names of the compiled executor's failures (orchestrator.native FUNCTIONS, by
function code, and NO_STATUS, by a status that is no FMI status) are the C core's own: its
``enum function`` and ``NAMES2`` table, its ``#define``s of those statuses and the words
``fmu_status`` gives them (orchestrator/native/core.h, core.c). The two were kept in step by hand;
a code added on one side only would name another call or say "no FMI status" in a user's error."""

from __future__ import annotations

import re
from pathlib import Path

from orchestrator.native import FUNCTIONS, NO_STATUS

NATIVE = Path(__file__).resolve().parents[1] / "orchestrator" / "native"


def test_function_names_are_the_cores() -> None:
    core_c = (NATIVE / "core.c").read_text()
    table = re.search(r"NAMES2\[FUNCTIONS\] = \{(.*?)\};", core_c, re.S)
    assert table is not None
    assert tuple(re.findall(r'"(\w+)"', table.group(1))) == FUNCTIONS
    enum = re.search(r"enum function \{(.*?)\};", (NATIVE / "core.h").read_text(), re.S)
    assert enum is not None
    codes = [name.strip() for name in enum.group(1).split(",")]
    assert codes[-1] == "FUNCTIONS" and len(codes) - 1 == len(FUNCTIONS)


def test_statuses_that_are_no_fmi_status_are_the_cores() -> None:
    defines = dict(re.findall(r"#define (\w+) \((-\d+)\)", (NATIVE / "core.h").read_text()))
    words = dict(re.findall(r'if \(status == (\w+)\) return "([^"]+)";', (NATIVE / "core.c").read_text()))
    assert {int(code): words[name] for name, code in defines.items()} == NO_STATUS
