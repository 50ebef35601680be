"""The stacks running on this machine: one entry per rendezvous endpoint, written by the launcher.

An entry says which launcher (pid), profile and run folder holds a rendezvous endpoint and where
its credentials are, so that

* a second ``seaway launch`` on the same endpoint refuses to start and names the first;
* an operator command (``seaway mission``, ``seaway health``) started in another shell finds the
  credentials of the stack on its endpoint without being told.

Entries live in ``$XDG_RUNTIME_DIR/seaway/stacks`` (else ``~/.local/state/seaway/stacks``), mode
0700: only the user who runs the stack can read where its credentials are. An entry whose launcher
is gone is stale and ignored (and removed).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from seaway.runtime import private

if TYPE_CHECKING:
    from seaway.runtime.credentials import Credentials

ENV_STACKS_DIR = "SEAWAY_STACKS_DIR"


@dataclass(frozen=True)
class StackEntry:
    """One running stack."""

    rendezvous: str
    pid: int
    profile: str
    run_dir: str
    credentials: str
    vessel: str

    def describe(self) -> str:
        return (f"profile {self.profile!r}, vessel {self.vessel!r}, launcher pid {self.pid}, "
                f"run folder {self.run_dir}")

    def session_credentials(self) -> Credentials | str:
        """What a session of this stack authenticates with: its ``Credentials``, or
        ``credentials.NONE`` for a stack launched without authentication."""
        from seaway.runtime import credentials as creds

        return creds.NONE if self.credentials == creds.NONE else creds.Credentials(Path(self.credentials))


def stacks_dir() -> Path:
    override = os.environ.get(ENV_STACKS_DIR)
    if override:
        return Path(override)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    base = Path(runtime) if runtime and Path(runtime).is_dir() else Path.home() / ".local" / "state"
    return base / "seaway" / "stacks"


def private_folder(folder: Path | None = None) -> Path:
    """The stacks folder (or ``folder`` in it), made 0700 however it came to exist: a stack's
    credentials folder is made in it, and ``mkdir`` gives the parents it makes the umask's mode."""
    return private.private_folder(folder or stacks_dir())


def _path(rendezvous: str) -> Path:
    return stacks_dir() / (re.sub(r"[^A-Za-z0-9.]+", "-", rendezvous).strip("-") + ".json")


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists (someone else's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process: alive
    return True


def lookup(rendezvous: str) -> StackEntry | None:
    """The live stack on ``rendezvous``, or None (a stale entry is removed)."""
    p = _path(rendezvous)
    try:
        entry = StackEntry(**json.loads(p.read_text()))
    except (OSError, ValueError, TypeError):
        return None
    if not alive(entry.pid):
        p.unlink(missing_ok=True)
        return None
    return entry


def register(entry: StackEntry) -> Path:
    """Write ``entry`` (atomically; the folder is made 0700)."""
    private_folder(stacks_dir())
    p = _path(entry.rendezvous)
    tmp = p.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(asdict(entry), indent=1))
    tmp.replace(p)
    return p


def unregister(rendezvous: str, pid: int) -> None:
    """Remove the entry of ``rendezvous`` if it is ``pid``'s."""
    entry = lookup(rendezvous)
    if entry is not None and entry.pid == pid:
        _path(rendezvous).unlink(missing_ok=True)
