"""Files a restarted process reads back: written so that a reader sees the old one or the new one.

A process killed mid-write (SIGKILL, the OOM killer, a power loss) must not leave half a file for its
successor: the text goes to a temporary file in the same folder, which then replaces the target in
one ``rename`` (atomic within a file system). Used for the controller's mission checkpoint and the
sim's loaded scenario.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_text(path: Path, text: str, durable: bool = True) -> None:
    """Write ``text`` to ``path`` atomically, making its folder if needed.

    ``durable``: on disk before it replaces the old file (fsync), so a power loss keeps it too; a
    crashed process alone loses nothing the OS already has, so a caller that writes often and only
    fears crashes may pass False (the fsync is milliseconds)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
