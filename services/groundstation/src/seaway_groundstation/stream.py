"""The live stream: each WebSocket client gets the latest of each vessel, at most ``rate_hz``.

Design (a slow client never slows the others or the bus, and gets the latest, not a backlog):

* the bus threads only update the ``Fleet`` and call ``notify(vessel)``, which marks the vessel
  dirty and schedules one wake-up on the event loop however many messages arrive meanwhile;
* each client has one small slot: an ``asyncio.Event`` ("something you watch changed") and the
  change numbers it has already been sent; its own sender task waits on the event, keeps at least
  ``1 / rate_hz`` between frames, then takes what changed since its last frame from the fleet
  (only the latest message of each kind) and sends it;
* a client whose socket is slow is held up in its own ``send`` only; whatever arrives meanwhile
  replaces what it would have been sent, so its next frame is current and nothing queues up.

Frames are JSON text, one per vessel with news (``Fleet.changes`` describes them).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable

from starlette.websockets import WebSocket, WebSocketDisconnect

from seaway_groundstation.fleet import Fleet

log = logging.getLogger("seaway_groundstation.stream")


class StreamClient:
    """One client's latest-value slot and its sender."""

    def __init__(self, vessels: frozenset[str] | None) -> None:
        self.vessels = vessels
        self.seen: dict[tuple[str, str], int] = {}
        self.wake = asyncio.Event()
        self.wake.set()  # the first frame: everything known now
        self.frames_sent = 0

    def wants(self, dirty: set[str]) -> bool:
        return self.vessels is None or not self.vessels.isdisjoint(dirty)

    async def run(self, websocket: WebSocket, fleet: Fleet, period_s: float,
                  clock: Callable[[], float]) -> None:
        """Send frames until the socket closes or the task is cancelled."""
        loop = asyncio.get_running_loop()
        next_ok = loop.time()
        while True:
            await self.wake.wait()
            delay = next_ok - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            self.wake.clear()  # what arrived during the wait is in this frame
            frames = fleet.changes(self.seen, self.vessels, clock())
            next_ok = loop.time() + period_s
            for frame in frames:
                await websocket.send_text(frame)
                self.frames_sent += 1


class StreamHub:
    """The set of stream clients and the hand-off from bus threads to the event loop."""

    def __init__(self, fleet: Fleet, rate_hz: float = 20.0, max_clients: int = 256,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self.fleet, self.period_s, self.max_clients, self.clock = fleet, 1.0 / rate_hz, max_clients, clock
        self._clients: set[StreamClient] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._lock = threading.Lock()
        self._dirty: set[str] = set()
        self._scheduled = False

    @property
    def clients(self) -> int:
        return len(self._clients)

    def bind(self, loop: asyncio.AbstractEventLoop | None) -> None:
        """The event loop the clients live on (None: unbound, notifications are dropped)."""
        with self._lock:
            self._loop, self._dirty, self._scheduled = loop, set(), False

    def notify(self, vessel: str) -> None:
        """``vessel`` changed (from any thread): wake the clients watching it, once per burst."""
        with self._lock:
            self._dirty.add(vessel)
            if self._scheduled or self._loop is None:
                return
            self._scheduled = True
            loop = self._loop
        try:
            loop.call_soon_threadsafe(self._wake)
        except RuntimeError:  # the loop closed while the bus still delivers
            with self._lock:
                self._scheduled = False

    def _wake(self) -> None:
        with self._lock:
            dirty, self._dirty, self._scheduled = self._dirty, set(), False
        for client in self._clients:
            if client.wants(dirty):
                client.wake.set()

    async def serve(self, websocket: WebSocket, vessels: frozenset[str] | None) -> None:
        """Accept ``websocket`` and stream to it until it closes."""
        if len(self._clients) >= self.max_clients:
            await websocket.close(code=1013, reason=f"too many stream clients ({self.max_clients})")
            return
        await websocket.accept()
        client = StreamClient(vessels)
        self._clients.add(client)
        sender = asyncio.create_task(client.run(websocket, self.fleet, self.period_s, self.clock))
        try:
            while True:  # the client sends nothing we need; this notices it going away
                message = await websocket.receive()
                if message["type"] == "websocket.disconnect":
                    break
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            self._clients.discard(client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
