# SPDX-License-Identifier: BSD-2-Clause
"""``python -m orchestrator``: the ``orchestrate`` command, for a shell where it is not on the PATH."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
