"""Bounds on what a client may send: request body size and encoding (ASGI middleware) and a
command rate.

``BodyLimit`` reads a request's body before the application sees it and answers 413 past
``max_bytes`` (by ``Content-Length`` at once, or by counting a chunked body), so no endpoint ever
holds more, and 422 for a body declared JSON that is not UTF-8 text. Paths in ``streamed`` (a
recording upload) have their own, larger bound: a declared length over it is refused at once, and
the body is passed on unbuffered for the endpoint to write to disk, counting it itself.
``RateLimiter`` is a token bucket per client (pure: time passed in), bounded in the number of
clients it remembers.
"""

from __future__ import annotations

import collections
import json
from collections.abc import Awaitable, Callable, MutableMapping
from dataclasses import dataclass
from typing import Any

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


class BodyLimit:
    """ASGI middleware: HTTP request bodies over ``max_bytes`` are answered 413 and never reach
    the application; smaller ones are buffered and replayed to it unchanged."""

    def __init__(self, app: ASGIApp, max_bytes: int, streamed: dict[str, int] | None = None) -> None:
        if max_bytes <= 0:
            raise ValueError(f"max_bytes must be > 0, got {max_bytes}")
        self.app, self.max_bytes, self.streamed = app, max_bytes, dict(streamed or {})

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        bound = self.streamed.get(scope.get("path", "")) if scope.get("method") == "POST" else None
        length = dict(scope.get("headers") or []).get(b"content-length")
        if length is not None:
            try:
                declared = int(length)
            except ValueError:
                await self._refuse(send, 400, "Content-Length is not a number")
                return
            if declared > (bound or self.max_bytes):
                await self._too_large(send, bound or self.max_bytes)
                return
        if bound is not None:
            await self.app(scope, receive, send)  # the endpoint counts while it writes
            return
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":  # the client went away
                return
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                await self._too_large(send, self.max_bytes)
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        if _declares_json(scope) and not _utf8(body):
            # Starlette's JSON reading fails on it with a bare 400 "error parsing the body".
            await self._refuse(send, 422, [{
                "type": "body_not_utf8", "loc": ["body"], "input": f"<{len(body)} bytes>",
                "msg": f"the body ({len(body)} bytes) is sent as JSON but is not UTF-8 text: send "
                       "a JSON object encoded as UTF-8"}])
            return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)

    async def _too_large(self, send: Send, bound: int) -> None:
        await self._refuse(send, 413, f"request body larger than {bound} bytes")

    @staticmethod
    async def _refuse(send: Send, status: int, detail: str | list[dict[str, Any]]) -> None:
        payload = json.dumps({"detail": detail}).encode()
        await send({"type": "http.response.start", "status": status,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(payload)).encode()),
                                (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": payload})


def _declares_json(scope: Scope) -> bool:
    """Whether the request's Content-Type says JSON (``application/json``, ``...+json``)."""
    ctype = dict(scope.get("headers") or []).get(b"content-type", b"")
    media = ctype.split(b";")[0].strip().lower()
    return media == b"application/json" or (media.startswith(b"application/") and media.endswith(b"+json"))


def _utf8(body: bytes) -> bool:
    try:
        body.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@dataclass
class _Bucket:
    tokens: float
    updated_s: float


class RateLimiter:
    """A token bucket per client: ``burst`` requests at once, then ``rate_per_s`` sustained.

    Remembers at most ``max_clients`` clients (the least recently seen is forgotten first, which
    only ever gives a forgotten client a full bucket again).
    """

    def __init__(self, rate_per_s: float, burst: int, max_clients: int = 4096) -> None:
        if rate_per_s < 0 or burst < 1:
            raise ValueError(f"need rate_per_s >= 0 and burst >= 1, got {rate_per_s}, {burst}")
        self.rate_per_s, self.burst, self.max_clients = rate_per_s, burst, max_clients
        self._buckets: collections.OrderedDict[str, _Bucket] = collections.OrderedDict()

    def allow(self, client: str, now_s: float) -> float:
        """0.0 if ``client`` may make a request at ``now_s`` (and counts it), else the time until
        it may [s] (``inf`` when the rate is 0)."""
        b = self._buckets.pop(client, None) or _Bucket(float(self.burst), now_s)
        b.tokens = min(float(self.burst), b.tokens + max(0.0, now_s - b.updated_s) * self.rate_per_s)
        b.updated_s = now_s
        self._buckets[client] = b
        while len(self._buckets) > self.max_clients:
            self._buckets.popitem(last=False)
        if b.tokens >= 1.0:
            b.tokens -= 1.0
            return 0.0
        return float("inf") if self.rate_per_s == 0 else (1.0 - b.tokens) / self.rate_per_s
