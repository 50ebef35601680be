"""The run's logs (producer: the recorder, from the files it tails; ``seaway_recorder.logtail``)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from seaway.contract.messages.base import Message

MAX_LOG_MESSAGE_CHARS = 8300
"""A log line's text as the recorder passes it on: 8,192 characters and its note of what was cut."""


class LogRecord(Message):
    """One line of one process's log, as the recorder read it from the run folder.

    So a viewer that is not on the machine of the run's files (``seaway foxglove`` on the shore)
    shows the same log as the recording. ``stamp_ns`` is the wall-clock time the line was logged
    (the time the line carries, else the line before's), also in lockstep: a log line is an event
    in the world, not in the simulation.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.LogRecord"
    process: str = Field(min_length=1, max_length=64, description="the profile's process name")
    level: str = Field(default="", max_length=16, description="Python's level name (INFO, ...); "
                       "'' when the line says none")
    logger: str = Field(default="", max_length=200, description="the logger's name")
    message: str = Field(max_length=MAX_LOG_MESSAGE_CHARS)
