"""The paper's experiments on top of the SSP engine: tracking metrics, the monolithic reference
simulation, the alpha/beta study, scenario building, regression against baselines and the report.

The engine (``orchestrator.ssp``, ``.system``, ``.master``, ``.results``) never imports this package.
"""
