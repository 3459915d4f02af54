# SPDX-License-Identifier: BSD-2-Clause
"""The paper's models as pure math, no FMI: reference signal, actuator (dead-zone and fault),
the two plants with their integrators, and the two examples' data.

The FMUs wrap these functions (the modules here are bundled into them, so they import each other
relatively and use plain floats in the hot paths); the monolithic reference simulation of
``orchestrator.experiments`` runs the very same functions. Import from the submodules.
"""
