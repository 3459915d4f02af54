# SPDX-License-Identifier: BSD-2-Clause
"""Parameter checks shared by the models: every violation named with its value."""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["bound_problems", "finite_problems"]


def finite_problems(p: object, names: Sequence[str]) -> list[str]:
    """``name`` must be finite, for every name."""
    values = {name: getattr(p, name) for name in names}
    return [
        f"{name} must be a finite number (got {v!r})"
        for name, v in values.items() if not math.isfinite(v)
    ]


def bound_problems(p: object, names: Sequence[str], strict: bool) -> list[str]:
    """``name > 0`` (strict) or ``name >= 0`` for every name, finite."""
    problems = []
    for name in names:
        value = getattr(p, name)
        ok = math.isfinite(value) and (value > 0.0 if strict else value >= 0.0)
        if not ok:
            relation = ">" if strict else ">="
            problems.append(f"{name} must satisfy {name} {relation} 0 (got {value!r})")
    return problems
