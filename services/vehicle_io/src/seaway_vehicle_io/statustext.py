"""The autopilot's STATUSTEXT messages, kept briefly so a refusal can say why.

ArduPilot refuses an arm with ``COMMAND_ACK`` FAILED and says why in STATUSTEXT ("PreArm: EKF3 not
started", "Arm: Gyros inconsistent"); measured against Rover SITL, the text comes in the same few
milliseconds as the ACK, sometimes just after it. So the texts are kept with their arrival time,
and a refused request picks those that arrived since it was sent and match the profile's prefixes.

MAVLink 2 may split a long text into chunks (``id`` != 0, ``chunk_seq`` 0, 1, ...; the last chunk
is shorter than the 50-character field); those are joined before they are kept. Pure: time comes
in as monotonic nanoseconds.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

TEXT_FIELD_LEN = 50  # STATUSTEXT.text: a shorter chunk ends its text
KEEP = 32  # texts remembered (a refusal reads the last second or so)
PENDING = 8
"""Chunked texts being joined at once: an autopilot sends one text's chunks back to back, so more
unfinished ones are texts whose last chunk was lost; the oldest is dropped (each id could otherwise
hold its chunks until the link drops: 65535 ids, about 58 MB)."""


@dataclass(frozen=True)
class StatusText:
    mono_ns: int
    severity: int  # MAV_SEVERITY: 0 emergency ... 4 warning ... 7 debug
    text: str


def decode_text(raw: str | bytes) -> str:
    """STATUSTEXT.text as pymavlink gives it (str or bytes, NUL-padded) -> clean text."""
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8", errors="replace")
    return raw.split("\x00", 1)[0]


class StatusTexts:
    """The last ``KEEP`` complete texts, in arrival order, and at most ``PENDING`` being joined."""

    def __init__(self) -> None:
        self._texts: deque[StatusText] = deque(maxlen=KEEP)
        self._chunks: dict[int, list[str]] = {}

    def add(self, severity: int, raw: str | bytes, now_ns: int, text_id: int = 0,
            chunk_seq: int = 0) -> StatusText | None:
        """One STATUSTEXT; returns the complete text when this message completed one."""
        part = decode_text(raw)
        complete = len(part) < TEXT_FIELD_LEN
        if text_id == 0:
            text = part
        else:
            parts = self._chunks.get(text_id)
            if parts is None:
                while len(self._chunks) >= PENDING:
                    del self._chunks[next(iter(self._chunks))]  # the oldest unfinished (insertion order)
                parts = self._chunks[text_id] = []
            if chunk_seq != len(parts):  # a chunk lost or repeated: keep what can be read
                parts.clear()
            parts.append(part)
            if not complete and len(parts) < 8:
                return None
            text = "".join(self._chunks.pop(text_id))
        item = StatusText(now_ns, severity, text)
        self._texts.append(item)
        return item

    def since(self, mono_ns: int) -> list[StatusText]:
        return [t for t in self._texts if t.mono_ns >= mono_ns]

    def clear(self) -> None:
        self._texts.clear()
        self._chunks.clear()


def matching(texts: list[StatusText], prefixes: tuple[str, ...]) -> list[str]:
    """The texts that start with one of ``prefixes`` (case-sensitive, as the autopilot writes
    them), without repeats, in arrival order."""
    out: list[str] = []
    for t in texts:
        if t.text.startswith(prefixes) and t.text not in out:
            out.append(t.text)
    return out
