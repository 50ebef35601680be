"""The autopilot's STATUSTEXT messages, kept briefly so a refusal can say why.

ArduPilot refuses an arm with ``COMMAND_ACK`` FAILED and says why in STATUSTEXT ("PreArm: EKF3 not
started", "Arm: Gyros inconsistent"); measured against Rover SITL, the text comes in the same few
milliseconds as the ACK, sometimes just after it. So the texts are kept with their arrival time,
and a refused request picks those that arrived since it was sent and match the profile's prefixes.

MAVLink 2 may split a long text into chunks (``id`` != 0, ``chunk_seq`` 0, 1, ...; the last chunk
is shorter than the 50-character field); those are joined before they are kept. PX4 numbers its
texts from 0 on each link (``MavlinkStreamStatustext``: ``msg.id = _id++``), so its first text
after a link comes up, when longer than 50 characters, arrives as chunks of ``id`` 0, which the
specification reserves for a text of one chunk. So a full-length text of ``id`` 0 is held: joined
with the ``chunk_seq`` 1, 2, ... of ``id`` 0 that follow, and kept as it is when anything else
comes or ``ID0_HOLD_NS`` passes (``due``). Pure: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

TEXT_FIELD_LEN = 50  # STATUSTEXT.text: a shorter chunk ends its text
KEEP = 32  # texts remembered (a refusal reads the last second or so)
PENDING = 8
ID0_HOLD_NS = 200_000_000
"""How long a full-length text of ``id`` 0 waits for a continuation [ns]: an autopilot sends a
text's chunks back to back, within milliseconds."""
MAX_CHUNKS = 8
"""Chunks joined into one text at most (400 characters); the text is kept as it is then."""
"""Chunked texts being joined at once: an autopilot sends one text's chunks back to back, so more
unfinished ones are texts whose last chunk was lost; the oldest is dropped (each id could otherwise
hold its chunks until the link drops: 65535 ids, about 58 MB)."""


EVENT_TAG = "\t"
"""PX4 ends a STATUSTEXT with a tab when it says the same in an EVENT (its events interface's
backward compatibility: a ground station that decodes the events ignores the tagged text)."""


@dataclass(frozen=True)
class StatusText:
    mono_ns: int
    severity: int  # MAV_SEVERITY: 0 emergency ... 4 warning ... 7 debug
    text: str
    """Without the ``EVENT_TAG``."""
    also_an_event: bool = False
    """It ended with ``EVENT_TAG``: the autopilot says it in an EVENT too."""


def decode_text(raw: str | bytes) -> str:
    """STATUSTEXT.text as pymavlink gives it (str or bytes, NUL-padded) -> clean text."""
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8", errors="replace")
    return raw.split("\x00", 1)[0]


class StatusTexts:
    """The last ``KEEP`` complete texts, in arrival order, at most ``PENDING`` being joined, and
    the held full-length text of ``id`` 0 (PX4's first after a link comes up)."""

    def __init__(self) -> None:
        self._texts: deque[StatusText] = deque(maxlen=KEEP)
        self._chunks: dict[int, list[str]] = {}
        self._held: tuple[int, list[str], int] | None = None
        """(severity, chunks so far, arrival [ns]) of a full-length text of id 0."""

    def add(self, severity: int, raw: str | bytes, now_ns: int, text_id: int = 0,
            chunk_seq: int = 0) -> list[StatusText]:
        """One STATUSTEXT; returns the texts it completed, oldest first (a held text of ``id`` 0
        that this one does not continue, then this one's if it completed a text)."""
        part = decode_text(raw)
        complete = len(part) < TEXT_FIELD_LEN
        if text_id == 0 and chunk_seq > 0 and self._held is not None \
                and chunk_seq == len(self._held[1]):
            parts = self._held[1]
            parts.append(part)
            if complete or len(parts) >= MAX_CHUNKS:
                return [self._keep_held()]
            return []
        out = [self._keep_held()] if self._held is not None else []
        if text_id == 0:
            if not complete and chunk_seq == 0:
                self._held = (severity, [part], now_ns)
                return out
            return [*out, self._keep(StatusText(now_ns, severity, part))]
        parts = self._chunks.get(text_id)
        if parts is None:
            while len(self._chunks) >= PENDING:
                del self._chunks[next(iter(self._chunks))]  # the oldest unfinished (insertion order)
            parts = self._chunks[text_id] = []
        if chunk_seq != len(parts):  # a chunk lost or repeated: keep what can be read
            parts.clear()
        parts.append(part)
        if not complete and len(parts) < MAX_CHUNKS:
            return out
        text = "".join(self._chunks.pop(text_id))
        return [*out, self._keep(StatusText(now_ns, severity, text))]

    def due(self, now_ns: int) -> list[StatusText]:
        """The held text of ``id`` 0, kept as it is, once ``ID0_HOLD_NS`` passed with no
        continuation (a text of exactly 50 characters)."""
        if self._held is not None and now_ns - self._held[2] >= ID0_HOLD_NS:
            return [self._keep_held()]
        return []

    def _keep_held(self) -> StatusText:
        assert self._held is not None
        severity, parts, at_ns = self._held
        self._held = None
        return self._keep(StatusText(at_ns, severity, "".join(parts)))

    def _keep(self, item: StatusText) -> StatusText:
        if item.text.endswith(EVENT_TAG):
            item = StatusText(item.mono_ns, item.severity, item.text.rstrip(EVENT_TAG), True)
        self._texts.append(item)
        return item

    def since(self, mono_ns: int) -> list[StatusText]:
        """The texts that arrived from ``mono_ns`` on, the held one (as far as it came) too: a
        refusal names it at once."""
        kept = [t for t in self._texts if t.mono_ns >= mono_ns]
        if self._held is not None and self._held[2] >= mono_ns:
            kept.append(StatusText(self._held[2], self._held[0], "".join(self._held[1])))
        return kept

    def clear(self) -> None:
        self._texts.clear()
        self._chunks.clear()
        self._held = None


def matching(texts: list[StatusText], prefixes: tuple[str, ...]) -> list[str]:
    """The texts that start with one of ``prefixes`` (case-sensitive, as the autopilot writes
    them), without repeats, in arrival order."""
    out: list[str] = []
    for t in texts:
        if t.text.startswith(prefixes) and t.text not in out:
            out.append(t.text)
    return out
