"""Files a restarted process reads back: written so that a reader sees the old one or the new one.

A process killed mid-write (SIGKILL, the OOM killer, a power loss) must not leave half a file for its
successor: the text goes to a temporary file in the same folder, which then replaces the target in
one ``rename`` (atomic within a file system). Read back as the typed model it was written from
(``read_model``), a file that cannot be used says why. Used for the controller's mission
checkpoint and the sim's loaded scenario; ``LatestWriter`` writes from a thread of its own for a
caller that must not wait for the disk.
"""

from __future__ import annotations

import os
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from pydantic import BaseModel, ValidationError

from seaway.contract.config import describe_validation_error

M = TypeVar("M", bound=BaseModel)


class StateFileError(ValueError):
    """A kept file exists but cannot be used; the text names it and says what is wrong."""


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


class LatestWriter:
    """Keeps one file up to date with the latest text given, written (``write_text``, durable) on a
    thread of its own, so that the caller never waits for the disk.

    A control loop must not: an fsync of even a small file waits for whatever else the disk is
    writing, which beside another process's large write can be longer than a control period, and
    the vessel would be without a command meanwhile. Texts given faster than the disk takes them
    are coalesced: only the latest is written, which is all a file read back at a restart needs.
    ``on_error(err)`` is called (on the writer's thread) for a write that failed; the next text is
    tried all the same. ``close`` writes what is still pending before it returns (bounded by its
    timeout).
    """

    def __init__(self, path: Path, on_error: Callable[[OSError], None],
                 name: str = "file-writer") -> None:
        self.path = path
        self.on_error = on_error
        self.written = 0  # texts written (coalesced ones not counted)
        self._name = name
        self._pending: str | None = None
        self._busy = False  # a text taken, being written
        self._closed = False
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None

    def submit(self, text: str) -> None:
        """Write ``text`` soon, in place of any text given before and not yet written."""
        with self._cond:
            if self._closed:
                raise RuntimeError(f"{self.path}: writer closed")
            self._pending = text
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def flush(self, timeout_s: float) -> bool:
        """Wait until every text given is written (or failed); whether it was within ``timeout_s``."""
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._busy, timeout_s)

    def close(self, timeout_s: float = 5.0) -> bool:
        """Write what is pending, then stop the thread; whether all was written in time."""
        done = self.flush(timeout_s)
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout_s)
        return done

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                text, self._pending = self._pending, None
                if text is None:  # closed, nothing left
                    return
                self._busy = True
            try:
                write_text(self.path, text)
                self.written += 1
            except OSError as err:
                self.on_error(err)
            finally:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()


def read_model(path: Path, model: type[M]) -> M | None:
    """The ``model`` kept at ``path`` (its JSON); None if there is no file; StateFileError if it
    cannot be read or is not a valid ``model``."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError as err:
        raise StateFileError(f"{path}: cannot read it: {err}") from None
    try:
        return model.model_validate_json(text)
    except ValidationError as err:
        raise StateFileError(describe_validation_error(err, str(path))) from None
