# SPDX-License-Identifier: BSD-2-Clause
"""``orchestrate export``: a whole SSP scenario as one Co-Simulation FMU (FMI 2.0 or 3.0), for the
tools that take one FMU and no SSP (Simulink, Modelica tools' FMU import, fmusim, FMPy's
``simulate_fmu``).

The container runs the engine's master semantics (same grid, same propagation order, same FMI
calls) with the engine's own C runtime (``orchestrator/native``); see :mod:`.container`."""

from __future__ import annotations

from .container import FMI_VERSIONS, export

__all__ = ["FMI_VERSIONS", "export"]
