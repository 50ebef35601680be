"""Writing on a disk that may fill up: what a full disk looks like, and a file that takes each write
whole or not at all.

A disk with no room (or a user's quota reached) fails a write with ``ENOSPC`` (``EDQUOT``). Unlike
other write errors it passes once room is made, so a process that must not lose data waits and
tries again (the recorder), and one that must not stop reading its input drops and counts what it
cannot write (the launcher's process logs). Both need to know what is on the disk after a failed
write: ``AllOrNothing`` cuts a write that went out in part back off the file.
"""

from __future__ import annotations

import errno
import os
from typing import IO

DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
"""The errors of a disk (or a quota) with no room: they pass when room is made, unlike the others."""


def disk_full(err: BaseException) -> bool:
    """Whether ``err`` says there is no room on the disk (or in the user's quota) for a write."""
    return isinstance(err, OSError) and err.errno in DISK_FULL_ERRNOS


class AllOrNothing:
    """A file that takes each write whole or not at all: a write the disk has no room for (or that
    fails otherwise) is cut back off the file before the error is raised, so the file stays what the
    writes that succeeded made it. Unbuffered: a buffer would hide the error until a later write,
    when the bytes at fault are gone (the recorder's ``McapWriter`` writes a chunk at a time). Takes over
    ``raw`` (a file object opened for writing, unbuffered) and closes it."""

    def __init__(self, raw: IO[bytes]) -> None:
        self._raw = raw
        self._fd = raw.fileno()
        self._at = os.lseek(self._fd, 0, os.SEEK_CUR)

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        at, done = self._at, 0
        try:
            while done < len(view):
                done += os.write(self._fd, view[done:])
        except BaseException:
            if done:  # a part went out: cut it off again (a cut also frees the room it took)
                self.cut(at)
            raise
        self._at = at + done
        return done

    def cut(self, at: int) -> None:
        """Drop what was written from byte ``at`` on: the next write goes there."""
        try:
            os.ftruncate(self._fd, at)
        finally:
            os.lseek(self._fd, at, os.SEEK_SET)
            self._at = at

    def tell(self) -> int:
        """Bytes written [bytes]: where the next write goes."""
        return self._at

    def fileno(self) -> int:
        return self._fd

    def flush(self) -> None:
        """Nothing to do: every write went to the OS when it returned."""

    def read_all(self) -> bytes:
        """Everything written (a file opened for reading too)."""
        out = bytearray()
        while len(out) < self._at:
            got = os.pread(self._fd, self._at - len(out), len(out))
            if not got:
                break
            out += got
        return bytes(out)

    @property
    def closed(self) -> bool:
        return self._raw.closed

    def close(self) -> None:
        self._raw.close()
