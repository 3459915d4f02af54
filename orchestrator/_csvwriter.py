"""Child process that turns raw float64 rows from stdin into CSV lines (``python -m``).

The master sends blocks of rows as bytes; formatting floats costs about 0.5 us per value in
Python, so doing it here keeps it off the stepping loop (and on the other core). Every block is
written and flushed as soon as it arrives, so the CSV keeps every row received even if the parent
process dies. Usage: ``python -m orchestrator._csvwriter FILE NCOLUMNS`` with the header line first
on stdin.
"""

from __future__ import annotations

import signal
import sys


def main(argv: list[str]) -> int:
    """Copy the header line, then format rows until stdin closes (Ctrl-C is for the parent: it
    sends the rows it still holds and then closes stdin)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    path, ncols = argv[0], int(argv[1])
    source = sys.stdin.buffer
    row_bytes = 8 * ncols
    pending = b""
    with open(path, "w", encoding="utf-8", newline="\n") as out:
        out.write(source.readline().decode("utf-8"))
        out.flush()
        while chunk := source.read1(1 << 16):
            pending += chunk
            usable = len(pending) - len(pending) % row_bytes
            if not usable:
                continue
            values = memoryview(pending[:usable]).cast("d").tolist()
            pending = pending[usable:]
            out.write("".join(",".join(map(repr, values[i:i + ncols])) + "\n"
                              for i in range(0, len(values), ncols)))
            out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
