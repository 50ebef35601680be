"""A run's process events: ``<run_dir>/events.jsonl``, one ``ProcessEvent`` per line.

The launcher's supervisor appends a line whenever a process starts, exits, is found hung
(``liveness``) or is stopped. The recorder, given the file (``seaway-recorder --events FILE``),
copies each line into the recording on ``launcher/events`` with this schema, so a recording tells
what happened to the processes as well as what they said.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

from seaway.runtime.disk import AllOrNothing

EVENTS_FILE = "events.jsonl"
EVENTS_TOPIC = "launcher/events"
"""The recording's channel of process events (not a bus key: the recorder reads them from the file)."""


class ProcessEvent(BaseModel):
    """One thing that happened to one process of a run."""

    SCHEMA: ClassVar[str] = "seaway.launcher.v1.ProcessEvent"
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    t_unix_s: float = Field(ge=0, description="when [s since epoch, wall clock]")
    process: str = Field(min_length=1, max_length=64, description="the profile's process name")
    event: Literal["start", "exit", "hung", "stopped"]
    pid: int | None = Field(default=None, ge=0, description="start: the new process's id")
    code: int | None = Field(default=None, description="exit, stopped: its exit code (-N: signal N)")
    reason: str = Field(default="", max_length=1000, description="hung: what it failed to do")

    def line(self) -> str:
        return self.model_dump_json(exclude_defaults=True) + "\n"


UNWRITTEN_EVENTS_KEPT = 10_000
"""Process events kept per events file while the disk has no room for them (a few MB at most)."""


class EventsFiles:
    """The events files a launcher appends to, on a disk that may fill up: ``append`` never
    raises. A line that finds no room waits in memory (at most ``UNWRITTEN_EVENTS_KEPT`` per file,
    the oldest then dropped and counted in ``lost``) and goes out, in order and whole, with the
    next line that finds room. ``say`` gets a line for the launcher's terminal when a file first
    cannot be written."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say
        self.lost = 0
        self._unwritten: dict[Path, list[str]] = {}

    def append(self, path: Path, line: str) -> bool:
        """Append ``line`` (and every line before it still waiting) to ``path``; False if it
        waits for room."""
        pending = self._unwritten.setdefault(path, [])
        pending.append(line)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "ab", buffering=0) as raw:
                AllOrNothing(raw).write("".join(pending).encode())
        except OSError as err:
            if len(pending) == 1:
                self.say(f"{path}: {err}: process events wait in memory until they can be written")
            if len(pending) > UNWRITTEN_EVENTS_KEPT:
                self.lost += len(pending) - UNWRITTEN_EVENTS_KEPT
                del pending[:-UNWRITTEN_EVENTS_KEPT]
            return False
        pending.clear()
        return True

    def waiting(self, path: Path) -> int:
        """Lines waiting for room in ``path``."""
        return len(self._unwritten.get(path, ()))
