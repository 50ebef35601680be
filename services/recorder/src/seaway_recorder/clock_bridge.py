"""A forward step of the wall clock, bridged in a recording's messages (``seaway report``).

A boat's computer without a real-time clock starts on a wrong time (1970, or its last shutdown's)
until NTP or GPS time sets it, maybe mid-mission: every wall time its processes give after that is
on the new clock, the ones before on the old. The recorder says each step it sees on
``recorder/clock_step`` (``schemas.CLOCK_STEP_SCHEMA``: when, on the new clock, and by how much).

A forward step of ``step_ns`` seen at ``stamp_ns`` is bridged by moving every wall time before it
on by the step: every field named ``*_ns`` but the durations (``NS_DURATION_FIELDS``), at any depth,
and the log time. Before it means earlier than ``stamp_ns - step_ns / 2``: the old clock read at
most ``stamp_ns - step_ns`` plus the 50 ms between the recorder's looks, and the new one at least
``stamp_ns`` less those 50 ms, so a step of a second or more (the least the recorder says) leaves
the two apart. A time given on another machine's clock (the shore's) is on its own and is left
alone: after the step the boat's clock agrees with it.

A backward step is not bridged: the times before and after it overlap, and a value does not say
on which clock it was given. Pure but for reading the files.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seaway.contract.messages import MAX_STAMP_NS, NS_DURATION_FIELDS, Message
from seaway.recording import reader
from seaway.runtime.clock import WALL_STEP_MIN_NS

from seaway_recorder.schemas import CLOCK_STEP_TOPIC


@dataclass(frozen=True)
class ClockStep:
    """One step the recorder saw: at ``stamp_ns`` (the new clock) by ``step_ns`` (+ forward)."""

    stamp_ns: int
    step_ns: int

    @property
    def before_ns(self) -> int:
        """A wall time earlier than this is on the clock before the step (module docstring)."""
        return self.stamp_ns - self.step_ns // 2


def steps_in(files: Iterable[Path], topics: Mapping[str, int] | None = None
             ) -> tuple[list[ClockStep], int]:
    """The steps the recorder said in ``files``, in the order it saw them, and how many records
    of the channel are no step (``step_of``: left out, counted). ``topics``: the files' topics as
    already read (``RecordingInfo.topics``); without this one, nothing is read (a filtered read of
    a file without the channel still walks its chunks: 0.3 s for paper-c1's)."""
    if topics is not None and CLOCK_STEP_TOPIC not in topics:
        return [], 0
    steps, bad = [], 0
    for path in files:
        for _schema, _channel, msg in reader.iter_file_records(path, [CLOCK_STEP_TOPIC]):
            step = step_of(msg.data)
            if step is None:
                bad += 1
            else:
                steps.append(step)
    return steps, bad


def step_of(data: bytes) -> ClockStep | None:
    """A record of ``recorder/clock_step`` as a step, or None if it is none the recorder writes:
    not JSON, integers missing, a time outside the stamps' range (0 to ``MAX_STAMP_NS``), a step
    under ``WALL_STEP_MIN_NS``, or a forward step from before 1970 (the old clock then read
    negative): moving times by such a thing would only corrupt them."""
    try:
        d = json.loads(data)
        stamp_ns, step_ns = d["stamp_ns"], d["step_ns"]
    except (ValueError, TypeError, KeyError):
        return None
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (stamp_ns, step_ns)):
        return None
    if not (0 <= stamp_ns <= MAX_STAMP_NS and WALL_STEP_MIN_NS <= abs(step_ns) <= MAX_STAMP_NS):
        return None
    if step_ns > stamp_ns:
        return None
    return ClockStep(stamp_ns, step_ns)


def bridge(dec: reader.Decoded, steps: Iterable[ClockStep]) -> list[ClockStep]:
    """Move the wall times in ``dec`` (in place) across each forward step of ``steps``, the
    earliest first (a later step's time is on the clock the earlier one set); the steps bridged."""
    done = []
    for step in steps:
        if step.step_ns <= 0:
            continue
        before, by = step.before_ns, step.step_ns
        for suffix, msgs in dec.by_suffix.items():
            logs = dec.log_ns[suffix]
            for i, msg in enumerate(msgs):
                if logs[i] < before:
                    logs[i] += by
                msgs[i] = shifted(msg, before, by)
        done.append(step)
    return done


def shifted(msg: Message, before_ns: int, by_ns: int) -> Message:
    """``msg`` with every wall time earlier than ``before_ns`` moved on by ``by_ns`` (``msg``
    itself when it has none)."""
    d = msg.model_dump()
    if not _shift(d, before_ns, by_ns):
        return msg
    return type(msg).model_validate(d)


def _shift(node: Any, before_ns: int, by_ns: int) -> bool:
    changed = False
    if isinstance(node, dict):
        for k, v in node.items():
            if (isinstance(v, int) and not isinstance(v, bool) and k.endswith("_ns")
                    and k not in NS_DURATION_FIELDS):
                if v < before_ns:
                    node[k] = v + by_ns
                    changed = True
            elif isinstance(v, dict | list):
                changed = _shift(v, before_ns, by_ns) or changed
    elif isinstance(node, list):
        for v in node:
            changed = _shift(v, before_ns, by_ns) or changed
    return changed
