# SPDX-License-Identifier: BSD-2-Clause
"""``python -m orchestrator``: the ``orchestrate`` command, for a shell where it is not on the PATH
(and the command itself: the launcher runs ``python -P -m orchestrator``)."""

import gc
import sys

from .cli import main

if __name__ == "__main__":
    # What the imports made (numpy, fmpy, lxml, the engine) lives as long as this process: the
    # collector skips it from now on. Its full collections walked all of it: one of them, 12 ms,
    # fell in every 30 s run of example1 (0.4 us per step; issue 46).
    gc.freeze()
    sys.exit(main())
