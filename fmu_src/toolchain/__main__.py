# SPDX-License-Identifier: BSD-2-Clause
"""``python -m fmu_src.toolchain``: build FMUs into a folder without the orchestrator (one path a
line), their FMI 3.0 variants beside, or compile an extension module into the checkout.
``orchestrate build`` is the everyday command (it packs the scenarios too)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from .build import EXTENSIONS, FMU_SCRIPTS, BuildError, build_fmu, buildable_platforms, compile_in_place
from .fmi3 import build_fmu3


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: build FMUs into a folder; prints one path per line."""
    parser = argparse.ArgumentParser(prog="python -m fmu_src.toolchain", description=__doc__.split("\n\n")[0])
    parser.add_argument("dest", type=Path, nargs="?", help="output folder, e.g. build/fmus")
    parser.add_argument(
        "--model", action="append", choices=list(FMU_SCRIPTS), help="build only these (repeatable)"
    )
    parser.add_argument("--fmi3", type=Path, metavar="DEST3",
                        help="also write each FMU's FMI 3.0 Co-Simulation variant there, e.g. build/fmus3")
    parser.add_argument("--in-place", metavar="MODULE", choices=sorted(EXTENSIONS),
                        help="instead, compile this extension module beside its source, for the checkout's "
                             "own Python runs (controller._fmath: the monolithic reference simulations)")
    options = parser.parse_args(argv)
    if options.in_place is None and options.dest is None:
        parser.error("the output folder is required (or --in-place MODULE)")
    try:
        if options.in_place is not None:
            print(compile_in_place(options.in_place))
            return 0
        platforms, note = buildable_platforms()
        if note:
            print(note, file=sys.stderr)
        models = options.model or FMU_SCRIPTS
        paths = [build_fmu(model, options.dest, platforms=platforms) for model in models]
        if options.fmi3 is not None:
            paths += [build_fmu3(path, options.fmi3) for path in list(paths)]
    except BuildError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
