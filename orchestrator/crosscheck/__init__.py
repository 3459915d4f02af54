# SPDX-License-Identifier: BSD-2-Clause
"""Cross-checks: the same ``.ssp`` archives in other SSP tools (libcosim, Ecos, OMSimulator) and a
conformance matrix against our masters (``orchestrate crosscheck``).

``run_libcosim`` (libcosim through libcosimpy, results shaped like ours) is also what the engine's
tests and benchmarks use to compare our ``jacobi`` master with libcosim.
"""

from __future__ import annotations

from .ecos import EcosCliTool, EcospyTool
from .exported import ExportedFmpyTool, ExportedFmuCheckTool, ExportedFmusimTool
from .libcosim import LibcosimError, LibcosimTool, run_libcosim
from .omsimulator import OMSimulatorCliTool, OMSimulatorNoPythonTool, OMSimulatorPythonTool
from .tools import Scenario, Tolerance, Tool, ToolRun

__all__ = ["TOOLS", "LibcosimError", "Scenario", "Tolerance", "Tool", "ToolRun", "run_libcosim",
           "select_tools"]

# Every supported tool, in the matrix's order (key -> adapter class).
TOOLS: dict[str, type[Tool]] = {t.key: t for t in (LibcosimTool, EcospyTool, EcosCliTool, OMSimulatorCliTool,
                                                   OMSimulatorNoPythonTool, OMSimulatorPythonTool,
                                                   ExportedFmusimTool, ExportedFmuCheckTool,
                                                   ExportedFmpyTool)}


def select_tools(keys: list[str] | None = None) -> list[Tool]:
    """Adapters for ``keys`` (default: every supported tool), in the matrix's order."""
    return [cls() for key, cls in TOOLS.items() if keys is None or key in keys]
