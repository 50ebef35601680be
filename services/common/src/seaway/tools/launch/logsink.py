"""A process's log file as the launcher writes it: line by line, never in the process's way.

The supervisor's pump reads each process's output (stdout and stderr, one pipe) and writes it to
``logs/<process>.log``. If a write raised (a full disk, foremost) and ended the pump, nothing
would read the pipe any more: once its 64 KiB buffer filled, the process would block on its next
line, and on a full disk every service of a run would hang that way. So ``LogSink.write`` never
raises: a line it cannot write is dropped and counted, the pump reads on, and the sink tries again
every ``RETRY_S``; the first line that goes through again follows one that says how many lines
were not written, and why. Each line is written whole or not at all (``AllOrNothing``).

A file that cannot be opened (no room even for it) is tried again the same way.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from seaway.runtime.disk import AllOrNothing

RETRY_S = 1.0
"""How often a log that could not be written is tried again [s]; lines meanwhile are dropped."""


class LogSink:
    """``path``, appended to one whole line at a time. ``trouble`` is called once when writing
    starts to fail, and once when it works again, with a line for the launcher's terminal."""

    def __init__(self, path: Path, trouble: Callable[[str], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.path = path
        self.trouble = trouble
        self.clock = clock
        self.lost_lines = 0
        """Lines not written since the last that was (0 while all are)."""
        self.lost_bytes = 0
        self.lost_total = 0
        """Lines not written over the sink's life."""
        self._file: AllOrNothing | None = None
        self._retry_at = 0.0
        self._why = ""
        self._closed = False

    def write(self, line: bytes) -> bool:
        """Append ``line`` (with its newline); False if it was dropped (counted)."""
        if self._closed:
            return False
        if self.lost_lines and self.clock() < self._retry_at:
            self._drop(line)
            return False
        try:
            if self._file is None:
                self._file = AllOrNothing(open(self.path, "ab", buffering=0))  # noqa: SIM115 - closed in close()
            if self.lost_lines:
                self._file.write(f"--- {self.lost_lines} lines ({self.lost_bytes} bytes) of this "
                                 f"output were not written here: {self._why}\n".encode())
            self._file.write(line)
        except OSError as err:
            if not self.lost_lines and self.trouble is not None:
                self.trouble(f"{self.path}: {err}: its lines are dropped and counted, and it is tried "
                             f"again every {RETRY_S:g} s")
            self._why = str(err)
            self._retry_at = self.clock() + RETRY_S
            self._drop(line)
            return False
        if self.lost_lines:
            if self.trouble is not None:
                self.trouble(f"{self.path}: written again; {self.lost_lines} lines were not")
            self.lost_lines = self.lost_bytes = 0
        return True

    def _drop(self, line: bytes) -> None:
        self.lost_lines += 1
        self.lost_bytes += len(line)
        self.lost_total += 1

    def close(self) -> None:
        self._closed = True
        if self._file is not None:
            self._file.close()
            self._file = None
