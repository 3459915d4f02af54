# SPDX-License-Identifier: BSD-2-Clause
"""The paper's experiments on top of the SSP engine: tracking metrics, the monolithic reference
simulation, the alpha/beta study, scenario building and the report (regression against baselines is
the application :mod:`orchestrator.regress`).

The engine (``orchestrator.ssp``, ``.system``, ``.master``, ``.results``) never imports this package.
"""
