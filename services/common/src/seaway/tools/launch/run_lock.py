"""One launch per run folder: the launcher holds ``<run folder>/launch.lock`` while it runs.

``main.earlier_recordings`` refuses a folder holding an earlier launch's recording, but a recorder
writes its file only once it is up: two launchers started into one ``--run-dir`` within those
seconds (two stacks on two rendezvous ports, or ``--composed``, which claims no port) both passed
that check and ran into one folder, their run descriptions, mission files, event logs, process logs
and recordings mixed (the second recorder's beside the first's, which the report and a study read
as one run's). The lock is an exclusive ``flock``, so it is let go whenever the launcher ends, a
SIGKILL included: a lock file left behind holds nothing, and the next launch takes it.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path

LOCK_FILE = "launch.lock"
"""In the run folder: holds the pid of the launcher that has it (for the message)."""


class RunFolderInUseError(RuntimeError):
    """Another launcher runs into this run folder."""


class RunLock:
    """The held lock of one run folder (``take``); ``release`` (or the launcher's end) lets go."""

    def __init__(self, fd: int, path: Path, made_folder: bool) -> None:
        self.fd, self.path, self.made_folder = fd, path, made_folder

    def release(self) -> None:
        """Let go; a folder this launch made and left holding nothing but the lock (it stopped
        before it started anything: no credentials, a bad profile) goes too, as if never made."""
        if self.fd < 0:
            return
        folder = self.path.parent
        with contextlib.suppress(OSError):
            if self.made_folder and [p.name for p in folder.iterdir()] == [LOCK_FILE]:
                self.path.unlink()  # while still held: nobody takes a lock on a file going away
                folder.rmdir()
        with contextlib.suppress(OSError):
            os.close(self.fd)  # the flock goes with the last descriptor
        self.fd = -1


def take(run_dir: Path) -> RunLock:
    """Make ``run_dir`` if need be and lock it for this launch; RunFolderInUseError naming the
    launcher that has it (its pid) and what to do; OSError if the folder cannot be made."""
    made_folder = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    path = run_dir / LOCK_FILE
    # O_CLOEXEC: the processes the launcher starts must not hold it past the launcher's end.
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise RunFolderInUseError(
            f"--run-dir {run_dir}: another launcher (pid {holder}) runs into this folder; a launch "
            f"needs a run folder of its own: give a new --run-dir, or leave it out (a fresh folder "
            f"under runs/)") from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return RunLock(fd, path, made_folder)
