# SPDX-License-Identifier: BSD-2-Clause
"""The suite's xdist groups hold (``make test``: ``pytest -n 2 --dist loadgroup``).

Tests that share an expensive module or session fixture (the 30 s monolithic references, the
regression sample's installed project, a wine prefix) carry ``xdist_group`` so that one worker
computes it once. pytest 9.2 with pytest-xdist 3.8 dropped the groups without a word
(pytest-dev/pytest-xdist#1386: xdist marks a test's group in the node id's old field): each
group's fixtures were then built in both workers, and the suite took 950 s instead of about 700.
Oracle: xdist's documented loadgroup behaviour, a grouped test's node id ending ``@<group>``.
"""

from __future__ import annotations

import pytest

GROUP = "suite-grouping"


@pytest.mark.xdist_group(GROUP)
def test_a_grouped_test_carries_its_group_under_loadgroup(request: pytest.FixtureRequest) -> None:
    if not getattr(request.config.option, "loadgroup", False):  # set in xdist's workers
        pytest.skip("only under pytest -n N --dist loadgroup (make test)")
    assert request.node.nodeid.endswith(f"@{GROUP}"), (
        f"{request.node.nodeid}: xdist did not group this test; with this pytest and pytest-xdist "
        "every xdist_group is ignored (see constraints.txt)"
    )
