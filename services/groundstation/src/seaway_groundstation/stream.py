"""The live stream: each WebSocket client gets the latest of each vessel, at most ``rate_hz``.

Design (a slow client never slows the others or the bus, and gets the latest, not a backlog):

* the bus threads only update the ``Fleet`` and call ``notify(vessel)``, which marks the vessel
  dirty and schedules one wake-up on the event loop however many messages arrive meanwhile;
* each client has one small slot: an ``asyncio.Event`` ("something you watch changed") and the
  change numbers it has already been sent; its own sender task waits on the event, then takes what
  changed since its last frame from the fleet (only the latest message of each kind) and sends it
  at once. The rate bound is per vessel and kind, a token bucket of ``rate_hz`` with a burst of
  ``KIND_BURST``: a kind over its budget is held back (its latest goes out when a token comes), so
  the state is never delayed behind the solve that came a few milliseconds after it, a flood of any
  kind reaches a client at ``rate_hz``, and a message held once does not push every later one back
  (a plain "at least 1 / rate_hz since the last send" would keep a 20 Hz source late for good);
* a client whose socket is slow is held up in its own ``send`` only; whatever arrives meanwhile
  replaces what it would have been sent, so its next frame is current and nothing queues up;
* a client that takes no frame for ``send_timeout_s`` (it stopped reading: its socket's buffers
  are full) is dropped: closed with 1008 and the reason if the close frame still goes out, and its
  connection cut (``TransportAbort``) a moment later in any case. Without that it kept its place
  for good: the server's close waits for buffers the client never drains (uvicorn's keep-alive
  ping times out but cannot close it either), and ``max_clients`` such clients shut everyone out.

Frames are JSON text, one per vessel with news (``Fleet.changes`` describes them).

The stream takes nothing from a client; ``MAX_CLIENT_MESSAGE_BYTES`` is the bound the server
(``service.server_config``) puts on what a client may send in one message.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from seaway.runtime.ratelog import RateLimitedLog
from starlette.websockets import WebSocket, WebSocketDisconnect

from seaway_groundstation.fleet import Fleet

log = logging.getLogger("seaway_groundstation.stream")


KIND_BURST = 2.0
"""Frames of one vessel and kind a client may get back to back before ``rate_hz`` applies."""
CLOSE_GRACE_S = 2.0
"""How long a dropped client's close frame may take to go out before its connection is cut [s]."""
MAX_CLIENT_MESSAGE_BYTES = 4096
"""The largest message a stream client may send [bytes] (the page sends none; uvicorn's default
of 16 MiB let 16 clients each sending 15 MiB take the server from 71 MB to 1.25 GB); beyond it
the server closes the connection with 1009."""
ABORT = "seaway.abort"
"""The scope key of a WebSocket's ``abort()``: drop its connection at once (``TransportAbort``)."""


class TooSlowError(Exception):
    """A stream client took no frame within the send deadline."""


class TransportAbort:
    """ASGI middleware: puts into each WebSocket's scope (``ABORT``) a callable that drops the
    connection at once, without waiting for its buffers to drain. ASGI has no such message; this
    reaches the server's transport through the ``send`` it is given (uvicorn's protocol), and is a
    no-op under a server that does not expose one (the test client)."""

    def __init__(self, app: Callable[..., Any]) -> None:
        self.app = app

    async def __call__(self, scope: dict[str, Any], receive: Callable[..., Any],
                       send: Callable[..., Any]) -> None:
        if scope["type"] == "websocket":
            transport = getattr(getattr(send, "__self__", None), "transport", None)
            abort = getattr(transport, "abort", None)
            scope[ABORT] = abort if callable(abort) else (lambda: None)
        await self.app(scope, receive, send)


class StreamClient:
    """One client's latest-value slot and its sender."""

    def __init__(self, vessels: frozenset[str] | None) -> None:
        self.vessels = vessels
        self.seen: dict[tuple[str, str], int] = {}
        self.wake = asyncio.Event()
        self.wake.set()  # the first frame: everything known now
        self.frames_sent = 0
        self.budget: dict[tuple[str, str], tuple[float, float]] = {}
        """Per (vessel, kind): tokens left and when they were counted [s, the event loop's clock]."""
        self.forgotten = 0
        """The fleet's ``forgotten`` count when ``seen`` and ``budget`` were last pruned."""

    def wants(self, dirty: set[str]) -> bool:
        return self.vessels is None or not self.vessels.isdisjoint(dirty)

    async def run(self, websocket: WebSocket, fleet: Fleet, period_s: float,
                  clock: Callable[[], float], send_timeout_s: float = math.inf) -> None:
        """Send frames until the socket closes or the task is cancelled; TooSlowError when one frame is
        not taken within ``send_timeout_s`` [s]."""
        loop = asyncio.get_running_loop()
        timeout = None if math.isinf(send_timeout_s) else send_timeout_s
        while True:
            await self.wake.wait()
            self.wake.clear()  # what arrives from now on wakes the next frame
            now = loop.time()
            frames, release_s = self.take(fleet, now, period_s, clock())
            if release_s is not None:  # a kind held back: look again when it may go
                loop.call_later(release_s, self.wake.set)
            for frame in frames:
                try:
                    await asyncio.wait_for(websocket.send_text(frame), timeout)
                except TimeoutError:
                    raise TooSlowError(f"no frame taken for {send_timeout_s:g} s") from None
                self.frames_sent += 1

    def take(self, fleet: Fleet, now: float, period_s: float,
             clock_s: float) -> tuple[list[str], float | None]:
        """The frames due at ``now`` (kinds out of tokens held back) and, if any kind was held back,
        how long until the first of them has a token again [s]."""
        if fleet.forgotten != self.forgotten:  # vessels forgotten: their keys go (else, with names
            self.forgotten = fleet.forgotten   # coming and going, these grew for good)
            names = fleet.names()
            self.seen = {k: v for k, v in self.seen.items() if k[0] in names}
            self.budget = {k: v for k, v in self.budget.items() if k[0] in names}
        tokens = {k: min(KIND_BURST, left + (now - at) / period_s) for k, (left, at) in self.budget.items()}
        # (a microsecond's grace: a wake-up set for exactly the next token must find it there)
        held = {k: left for k, left in tokens.items() if left < 1.0 - 1e-6}
        # Held kinds look already seen to the fleet; their true change numbers are kept.
        view = {**self.seen, **dict.fromkeys(held, sys.maxsize)}
        frames = fleet.changes(view, self.vessels, clock_s)
        for k, seq in view.items():
            if k not in held and seq != self.seen.get(k):
                self.seen[k] = seq
                self.budget[k] = (tokens.get(k, KIND_BURST) - 1.0, now)
        release = min(((1.0 - left) * period_s for left in held.values()), default=None)
        return frames, release


class StreamHub:
    """The set of stream clients and the hand-off from bus threads to the event loop."""

    def __init__(self, fleet: Fleet, rate_hz: float = 20.0, max_clients: int = 256,
                 clock: Callable[[], float] = time.monotonic, send_timeout_s: float = 10.0) -> None:
        """``send_timeout_s``: a client that takes no frame for this long is dropped [s]."""
        if rate_hz <= 0 or not send_timeout_s > 0:
            raise ValueError(f"rate_hz and send_timeout_s must be > 0, got {rate_hz}, {send_timeout_s}")
        self.fleet, self.period_s, self.max_clients, self.clock = fleet, 1.0 / rate_hz, max_clients, clock
        self.send_timeout_s = send_timeout_s
        self.dropped_slow = 0
        """Clients dropped for taking no frame within ``send_timeout_s``."""
        self._log = RateLimitedLog(log, 60.0)
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
            # Accepted, then closed with the code and reason (try again later): a close before
            # the handshake reaches the client as a bare HTTP 403, which says nothing of why.
            await websocket.accept()
            await websocket.close(code=1013, reason=f"too many stream clients ({self.max_clients}); "
                                                    "try again later")
            return
        await websocket.accept()
        client = StreamClient(vessels)
        self._clients.add(client)
        sender = asyncio.create_task(client.run(websocket, self.fleet, self.period_s, self.clock,
                                                self.send_timeout_s))
        listener = asyncio.create_task(_until_closed(websocket))
        try:
            await asyncio.wait((sender, listener), return_when=asyncio.FIRST_COMPLETED)
        finally:
            self._clients.discard(client)
            for task in (sender, listener):
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task
        if not sender.cancelled() and isinstance(sender.exception(), TooSlowError):
            await self._drop(websocket, str(sender.exception()))

    async def _drop(self, websocket: WebSocket, why: str) -> None:
        """Drop a client that stopped taking frames: the close frame with the reason if it goes
        out within ``CLOSE_GRACE_S`` (a slow reader sees why), the connection cut in any case."""
        self.dropped_slow += 1
        client = websocket.client.host if websocket.client else "unknown"
        self._log.warning("slow", "stream client %s dropped: %s (%d dropped so far)", client, why,
                          self.dropped_slow)
        abort = websocket.scope.get(ABORT) or (lambda: None)
        try:
            await asyncio.wait_for(websocket.close(code=1008, reason=f"too slow: {why}; reconnect "
                                                                     "and read the frames"),
                                   CLOSE_GRACE_S)
        except Exception:  # TimeoutError: its buffers are full; or it is already gone
            abort()
            return
        asyncio.get_running_loop().call_later(CLOSE_GRACE_S, abort)  # if it never reads the close


async def _until_closed(websocket: WebSocket) -> None:
    """Read (and discard) what the client sends until it goes away: the stream needs nothing
    from it, and this notices it leaving."""
    try:
        while (await websocket.receive())["type"] != "websocket.disconnect":
            pass
    except (WebSocketDisconnect, RuntimeError):
        pass
