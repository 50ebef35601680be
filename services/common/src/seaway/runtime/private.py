"""Files and folders only the user who runs the stack can read: the stacks registry (where each
stack's credentials are), run folders, recordings and logs.

Least exposure by default: a run's files say where the vessel went, what it was told and the
credentials' paths; nobody else on the machine needs them. ``PRIVATE_UMASK`` is what the launcher
runs under (so every file it and its processes create is 0600, every folder 0700), and
``private_folder``/``open_private`` give the same modes explicitly where a program may be started
on its own (``seaway record``) under a wider umask.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

PRIVATE_UMASK = 0o077
"""The launcher's umask: new files 0600, new folders 0700."""
FOLDER_MODE = 0o700
FILE_MODE = 0o600


def private_folder(folder: Path) -> Path:
    """``folder`` made (with its missing parents) and set to 0700, also when it already existed with
    a wider mode: ``mkdir(mode=...)`` sets the mode of a new last folder only, under the umask, so a
    folder first made as some other path's parent keeps the default 0755."""
    folder = Path(folder)
    folder.mkdir(mode=FOLDER_MODE, parents=True, exist_ok=True)
    os.chmod(folder, FOLDER_MODE)
    return folder


def open_private(path: Path, buffering: int = -1) -> IO[bytes]:
    """``path`` opened for writing (created, or truncated), mode 0600 whatever the umask;
    ``buffering`` as ``open``'s (0: unbuffered)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, FILE_MODE)
    os.fchmod(fd, FILE_MODE)  # an existing file keeps its mode through O_CREAT
    return os.fdopen(fd, "wb", buffering=buffering)
