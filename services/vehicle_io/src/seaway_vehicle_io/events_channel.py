"""The events protocol on one autopilot connection: fetch the catalog, decode, explain refusals.

At each connection to an autopilot whose profile speaks the events protocol (PX4), the events
metadata is fetched from it (``component_metadata.MetadataFetch``) and every EVENT is decoded
with it (``autopilot_events``). EVENTs that arrive before the catalog are counted, not decoded.

Events lost on the link (a gap in their sequence numbers, seen in the next EVENT or in
CURRENT_EVENT_SEQUENCE) are asked for again with REQUEST_EVENT once the catalog is there, as
libevents' receiver does: a failsafe's EVENT sent while the link was down (a radio fade) then still
names the failsafe when the link is back. The sequence carries over a reconnection (``resume_after``)
so the gap across the outage is seen; a reboot restarts the count, which asks for nothing.
Pure, like the core that owns it: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from seaway_vehicle_io.autopilot_events import Event, EventCatalog, EventTracker, MetadataError
from seaway_vehicle_io.component_metadata import MetadataFetch, SendFileTransfer, SendRequestMessage
from seaway_vehicle_io.dialect.events import MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET


@dataclass(frozen=True)
class SendRequestEvent:
    """REQUEST_EVENT: the autopilot's events ``first_sequence`` to ``last_sequence`` again."""

    target_system: int
    target_component: int
    first_sequence: int
    last_sequence: int


Request = SendRequestMessage | SendFileTransfer | SendRequestEvent
ASK_AGAIN_NS = 1_000_000_000
"""A REQUEST_EVENT whose events have not all come is sent again after this long [ns]..."""
ASKS = 3
"""... this many times in all (UDP; the autopilot busy with its failsafe)."""


class EventsChannel:
    """What one connection's autopilot says in EVENTs, and where that dictionary comes from."""

    def __init__(self, resume_after: int | None = None) -> None:
        """``resume_after``: the last event sequence heard on the connection before this one (the
        same autopilot, unless it rebooted: then its count restarted and nothing is asked)."""
        self.tracker = EventTracker()
        self.tracker.last_sequence = resume_after
        self._target: tuple[int, int] | None = None
        self._asking: tuple[int, int] | None = None  # the range asked for, until it has come
        self._asked_ns = 0
        self._asks = 0
        self.fetch: MetadataFetch | None = None
        self.fetch_started_ns = 0
        self.fetch_took_ns: int | None = None
        self.source = ""  # where the catalog came from, for the log
        self.unsupported = False  # the autopilot said it serves no component metadata

    @property
    def catalog(self) -> EventCatalog | None:
        return self.tracker.catalog

    def connect(self, target_system: int, target_component: int, now_ns: int) -> list[Request]:
        """A new connection (the core makes a fresh channel at each link loss: the firmware may
        have changed): fetch the catalog from it."""
        self.fetch = MetadataFetch(target_system, target_component)
        self.fetch_started_ns = now_ns
        self._target = (target_system, target_component)
        return self.fetch.start(now_ns)

    def on_current_sequence(self, sequence: int, flags: int, now_ns: int) -> list[Request]:
        """CURRENT_EVENT_SEQUENCE: the autopilot's newest event; a gap to it is asked for. Its
        RESET flag (a reboot) restarts the count."""
        if flags & MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET:
            self.tracker.last_sequence, self.tracker.to_ask = sequence, None
            self.tracker.missing.clear()
            return []
        self.tracker.note_sequence(sequence)
        return self._ask(now_ns)

    def restart_count(self) -> None:
        """The autopilot rebooted: its event count starts again; nothing before is asked for."""
        t = self.tracker
        t.last_sequence, t.to_ask, self._asking = None, None, None
        t.missing.clear()

    def _ask(self, now_ns: int) -> list[Request]:
        """REQUEST_EVENT for what is missing, once the catalog can read it: the newest gap, or the
        one asked for again after ``ASK_AGAIN_NS`` while some of it has not come."""
        t = self.tracker
        if t.catalog is None or self._target is None:
            return []
        if t.to_ask is not None:
            self._asking, self._asks, t.to_ask = t.to_ask, 0, None
        if self._asking is None:
            return []
        first, last = self._asking
        if not any(((first + k) & 0xFFFF) in t.missing for k in range(((last - first) & 0xFFFF) + 1)):
            self._asking = None  # all came
            return []
        if self._asks >= ASKS or (self._asks and now_ns - self._asked_ns < ASK_AGAIN_NS):
            return []
        self._asks += 1
        self._asked_ns = now_ns
        return [SendRequestEvent(*self._target, first, last)]

    def on_component_metadata(self, msg: Any, now_ns: int) -> list[Request]:
        if self.fetch is None:
            return []
        uri = msg.uri if isinstance(msg.uri, str) else bytes(msg.uri).decode("utf-8", "replace")
        return self.fetch.on_component_metadata(uri.split("\x00", 1)[0], now_ns)

    def on_request_ack(self, result: int, now_ns: int) -> str | None:
        """The ACK of the COMPONENT_METADATA request; a line if it ended the fetch."""
        if self.fetch is None or self.fetch.finished:
            return None
        self.fetch.on_request_ack(result)
        return self._ended(now_ns)

    def on_ftp(self, payload: bytes, now_ns: int) -> tuple[list[Request], str | None]:
        """A FILE_TRANSFER_PROTOCOL reply addressed to us: what to send next, and (once) a line
        saying how the fetch ended."""
        fetch = self.fetch
        if fetch is None or fetch.finished:
            return [], None
        out = fetch.on_ftp(payload, now_ns)
        return out, self._ended(now_ns)

    def tick(self, now_ns: int) -> tuple[list[Request], str | None]:
        fetch = self.fetch
        if fetch is None or fetch.finished:
            return self._ask(now_ns), None
        out = fetch.tick(now_ns)
        return out, self._ended(now_ns)

    def _ended(self, now_ns: int) -> str | None:
        fetch = self.fetch
        assert fetch is not None
        if not fetch.finished:
            return None
        self.fetch = None
        self.fetch_took_ns = now_ns - self.fetch_started_ns
        took = self.fetch_took_ns / 1e9
        self.unsupported = fetch.unsupported
        if fetch.stage == "failed" or fetch.result is None:
            return (f"events metadata not fetched ({fetch.error}): the autopilot's EVENTs, among "
                    "them its reasons for refusing to arm, cannot be read")
        try:
            self.tracker.catalog = EventCatalog.from_bytes(fetch.result)
        except MetadataError as err:
            return f"events metadata from {fetch.events_uri} unusable: {err}"
        self.source = str(fetch.events_uri)
        return (f"events metadata: {len(self.tracker.catalog.events)} events from "
                f"{fetch.events_uri} ({fetch.bytes_read} bytes over MAVLink FTP in {took:.2f} s)")

    def on_event(self, msg: Any, now_ns: int) -> tuple[Event | None, list[Request]]:
        """An EVENT: the event decoded (None: no catalog yet, or a repeat), and a REQUEST_EVENT
        for the events its sequence number shows were lost."""
        ev = self.tracker.on_event(int(msg.id), bytes(msg.arguments), int(msg.log_levels),
                                   int(msg.sequence), now_ns)
        return ev, self._ask(now_ns)

    def next_due_ns(self) -> int | None:
        return None if self.fetch is None else self.fetch.next_due_ns()
