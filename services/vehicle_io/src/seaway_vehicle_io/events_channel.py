"""The events protocol on one autopilot connection: fetch the catalog, decode, explain refusals.

At each connection to an autopilot whose profile speaks the events protocol (PX4), the events
metadata is fetched from it (``component_metadata.MetadataFetch``) and every EVENT is decoded
with it (``autopilot_events``). EVENTs that arrive before the catalog are counted, not decoded.
Pure, like the core that owns it: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

from typing import Any

from seaway_vehicle_io.autopilot_events import Event, EventCatalog, EventTracker, MetadataError
from seaway_vehicle_io.component_metadata import MetadataFetch, SendFileTransfer, SendRequestMessage

Request = SendRequestMessage | SendFileTransfer


class EventsChannel:
    """What one connection's autopilot says in EVENTs, and where that dictionary comes from."""

    def __init__(self) -> None:
        self.tracker = EventTracker()
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
        return self.fetch.start(now_ns)

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
            return [], None
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

    def on_event(self, msg: Any, now_ns: int) -> Event | None:
        return self.tracker.on_event(int(msg.id), bytes(msg.arguments), int(msg.log_levels),
                                     int(msg.sequence), now_ns)

    def next_due_ns(self) -> int | None:
        return None if self.fetch is None else self.fetch.next_due_ns()
