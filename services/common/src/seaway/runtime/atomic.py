"""Files a restarted process reads back: written so that a reader sees the old one or the new one.

A process killed mid-write (SIGKILL, the OOM killer, a power loss) must not leave half a file for its
successor: the text goes to a temporary file in the same folder, which then replaces the target in
one ``rename`` (atomic within a file system). Read back as the typed model it was written from
(``read_model``), a file that cannot be used says why. Used for the controller's mission
checkpoint and the sim's loaded scenario.
"""

from __future__ import annotations

import os
import tempfile
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
