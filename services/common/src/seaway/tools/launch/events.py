"""A run's process events: ``<run_dir>/events.jsonl``, one ``ProcessEvent`` per line.

The launcher's supervisor appends a line whenever a process starts, exits, is found hung
(``liveness``) or is stopped. The recorder, given the file (``seaway-recorder --events FILE``),
copies each line into the recording on ``launcher/events`` with this schema, so a recording tells
what happened to the processes as well as what they said.
"""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

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
