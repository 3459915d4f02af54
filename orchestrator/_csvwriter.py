"""Child process that turns raw float64 rows from stdin into CSV lines (``python -m``).

The master sends blocks of rows as bytes; formatting floats costs about 0.5 us per value in
Python, so doing it here keeps it off the stepping loop (and on the other core). Every block is
written and flushed as soon as it arrives. The CSV is written to a temporary file beside the result
and renamed to the result's name when stdin closes, so the name never holds a half-written file
(a failed write leaves the previous file, if any, untouched), and two runs writing the same result
each rename a complete file. If the parent process dies, stdin closes too: the rows received are
still renamed into place. Usage: ``python -m orchestrator._csvwriter PART FINAL NCOLUMNS`` with the
header line first on stdin; ``PART == FINAL`` writes in place (a device such as ``/dev/null``).
On a write error the temporary file is removed, one line goes to stderr and the status is 1.
"""

from __future__ import annotations

import io
import os
import signal
import sys


def main(argv: list[str]) -> int:
    """Copy the header line, then format rows until stdin closes; then rename PART to FINAL.
    Ctrl-C and SIGTERM are for the parent: it stops at the next communication point, sends the rows
    it still holds and then closes stdin."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    part, final, ncols = argv[0], argv[1], int(argv[2])
    source = sys.stdin.buffer
    assert isinstance(source, io.BufferedReader)  # what the stdin pipe is; read1 takes what is there
    row_bytes = 8 * ncols
    pending = b""
    try:
        with open(part, "w", encoding="utf-8", newline="\n") as out:
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
        if part != final:
            os.replace(part, final)
    except OSError as exc:
        if part != final:
            try:
                os.unlink(part)
            except OSError:
                pass
        sys.stderr.write(f"{exc.strerror or exc}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
