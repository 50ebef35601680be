"""A thin typed layer over zenoh-python: sessions, publishers, subscribers, requests, liveliness.

* ``open_session``: a Zenoh session from a config file (default: the packaged peer-on-loopback
  config, multicast scouting off; ``SEAWAY_ZENOH_CONFIG`` names another file).
* ``Bus.publisher(spec)``: typed; refuses a message of the wrong type or with a non-finite field.
* ``Bus.subscribe(spec, mode=...)``: ``latest`` keeps only the newest sample (a controller wants the
  freshest state), ``fifo`` keeps every sample in order up to a bound (a recorder, an estimator), or a
  ``callback``. A malformed payload is logged with its key, counted and dropped; the process goes on.
* ``Bus.queryable`` / ``Bus.request``: a request is answered by a ``Reply`` that accepts or refuses
  with a reason; a malformed request is refused, never crashes the server; no answer is a refusal
  that says so.
* liveliness tokens under ``seaway/<vessel>/health/<service>``.
"""

from __future__ import annotations

import collections
import json
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Generic, Literal, TypeVar

import zenoh

from seaway.contract import keys
from seaway.contract.messages import Message, MessageError, Reply

log = logging.getLogger("seaway.runtime.bus")

M = TypeVar("M", bound=Message)
ENV_CONFIG = "SEAWAY_ZENOH_CONFIG"
ENV_RENDEZVOUS = "SEAWAY_ZENOH_RENDEZVOUS"
DEFAULT_RENDEZVOUS = "tcp/127.0.0.1:7447"


def default_config_text() -> str:
    return resources.files("seaway.runtime").joinpath("zenoh/peer-loopback.json5").read_text()


def load_zenoh_config(path: str | Path | None = None) -> zenoh.Config:
    """Zenoh config from ``path``, else ``$SEAWAY_ZENOH_CONFIG``, else the packaged default.

    ``$SEAWAY_ZENOH_RENDEZVOUS`` replaces the rendezvous endpoint of the packaged default only.
    """
    path = path or os.environ.get(ENV_CONFIG) or None
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"Zenoh config {p} does not exist")
        try:
            return zenoh.Config.from_file(str(p))
        except Exception as err:  # zenoh raises its own ZError with the parse position
            raise ValueError(f"Zenoh config {p} is invalid: {err}") from None
    conf = zenoh.Config.from_json5(default_config_text())
    rendezvous = os.environ.get(ENV_RENDEZVOUS)
    if rendezvous:
        conf.insert_json5("listen/endpoints", json.dumps([rendezvous, "tcp/127.0.0.1:0"]))
        conf.insert_json5("connect/endpoints", json.dumps([rendezvous]))
    return conf


def open_session(config_path: str | Path | None = None) -> zenoh.Session:
    return zenoh.open(load_zenoh_config(config_path))


@dataclass
class BusStats:
    """Counters a service publishes in its status and tests assert on."""

    published: int = 0
    received: int = 0
    malformed: int = 0
    malformed_by_key: dict[str, int] = field(default_factory=dict)
    last_error: str = ""

    def count_malformed(self, key: str, error: str) -> None:
        self.malformed += 1
        self.malformed_by_key[key] = self.malformed_by_key.get(key, 0) + 1
        self.last_error = f"{key}: {error}"


class TypedPublisher(Generic[M]):
    """Publishes one message type on one key."""

    def __init__(self, bus: Bus, spec: keys.KeySpec, key: str) -> None:
        assert spec.message is not None
        self.spec, self.key, self._bus = spec, key, bus
        self._type = spec.message
        encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(spec.message.SCHEMA)
        self._pub = bus.session.declare_publisher(key, encoding=encoding)

    def put(self, msg: M) -> None:
        if type(msg) is not self._type:
            raise TypeError(f"{self.key} carries {self._type.__name__}, not {type(msg).__name__}")
        self._pub.put(msg.encode())
        self._bus.stats.published += 1

    def undeclare(self) -> None:
        self._pub.undeclare()


class TypedSubscriber(Generic[M]):
    """Receives one message type: the latest sample, every sample in order, or by callback."""

    def __init__(
        self,
        bus: Bus,
        spec: keys.KeySpec,
        keyexpr: str,
        mode: Literal["latest", "fifo"],
        capacity: int,
        callback: Callable[[str, M], None] | None,
    ) -> None:
        assert spec.message is not None
        self.spec, self.keyexpr, self._bus = spec, keyexpr, bus
        self._type: type[M] = spec.message  # type: ignore[assignment]
        self._callback = callback
        self._queue: collections.deque[tuple[str, M]] = collections.deque(
            maxlen=1 if mode == "latest" else capacity
        )
        self._cond = threading.Condition()
        self.dropped_overflow = 0
        self._sub = bus.session.declare_subscriber(keyexpr, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        try:
            msg = self._type.decode(sample.payload.to_bytes())
        except MessageError as err:
            self._bus.stats.count_malformed(key, str(err))
            log.warning("dropped malformed payload on %s: %s", key, err)
            return
        self._bus.stats.received += 1
        if self._callback is not None:
            try:
                self._callback(key, msg)
            except Exception:  # a bug in a handler must not kill Zenoh's delivery thread
                log.exception("handler for %s failed", key)
            return
        with self._cond:
            if len(self._queue) == self._queue.maxlen and self._queue.maxlen != 1:
                self.dropped_overflow += 1
            self._queue.append((key, msg))
            self._cond.notify_all()

    def latest(self) -> M | None:
        """The newest message not yet taken, or None."""
        with self._cond:
            if not self._queue:
                return None
            _key, msg = self._queue.pop()
            self._queue.clear()
            return msg

    def get(self, timeout_s: float | None = None) -> M | None:
        """The oldest message not yet taken, waiting up to ``timeout_s``; None on timeout."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._cond:
            while not self._queue:
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._cond.wait(remaining)
            return self._queue.popleft()[1]

    def drain(self) -> list[M]:
        """Every message not yet taken, oldest first."""
        with self._cond:
            out = [msg for _, msg in self._queue]
            self._queue.clear()
            return out

    def drain_with_keys(self) -> list[tuple[str, M]]:
        with self._cond:
            out = list(self._queue)
            self._queue.clear()
            return out

    def undeclare(self) -> None:
        self._sub.undeclare()


class Bus:
    """One service's Zenoh session with typed access to the registered keys of one vessel."""

    def __init__(self, session: zenoh.Session, vessel: str) -> None:
        self.session = session
        self.vessel = keys.check_vessel(vessel)
        self.stats = BusStats()
        self._tokens: list[Any] = []
        self._entities: list[Any] = []
        self._closed = False

    @classmethod
    def open(cls, vessel: str, config_path: str | Path | None = None) -> Bus:
        return cls(open_session(config_path), vessel)

    def key(self, spec: keys.KeySpec, vessel: str | None = None) -> str:
        return spec.key(vessel or self.vessel)

    def publisher(self, spec: keys.KeySpec, vessel: str | None = None) -> TypedPublisher[Any]:
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        pub: TypedPublisher[Any] = TypedPublisher(self, spec, self.key(spec, vessel))
        self._entities.append(pub)
        return pub

    def subscribe(
        self,
        spec: keys.KeySpec,
        mode: Literal["latest", "fifo"] = "latest",
        capacity: int = 10_000,
        callback: Callable[[str, Any], None] | None = None,
        vessel: str | None = None,
    ) -> TypedSubscriber[Any]:
        """Subscribe to ``spec`` on this vessel (or ``vessel``, which may be ``*``)."""
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        keyexpr = spec.wildcard() if vessel == "*" else self.key(spec, vessel)
        sub: TypedSubscriber[Any] = TypedSubscriber(self, spec, keyexpr, mode, capacity, callback)
        self._entities.append(sub)
        return sub

    def subscribe_raw(self, keyexpr: str, callback: Callable[[zenoh.Sample], None]) -> Any:
        """Untyped subscriber for tools that keep bytes unchanged (the recorder)."""
        sub = self.session.declare_subscriber(keyexpr, callback)
        self._entities.append(sub)
        return sub

    def queryable(self, spec: keys.KeySpec, handler: Callable[[Any], Reply],
                  vessel: str | None = None) -> Any:
        """Serve requests on ``spec``: ``handler(request) -> Reply``. Bad requests are refused."""
        if spec.kind != "query" or spec.message is None:
            raise ValueError(f"{spec.suffix} is not a query key")
        req_type = spec.message
        key = self.key(spec, vessel)

        def on_query(query: zenoh.Query) -> None:
            now = time.time_ns()
            try:
                if query.payload is None:
                    raise MessageError(f"{req_type.__name__}: empty request")
                request = req_type.decode(query.payload.to_bytes())
            except MessageError as err:
                self.stats.count_malformed(key, str(err))
                log.warning("refused malformed request on %s: %s", key, err)
                reply = Reply.refuse(now, f"malformed request: {err}")
            else:
                try:
                    reply = handler(request)
                except Exception as err:  # the server keeps running; the caller learns why
                    log.exception("request handler for %s failed", key)
                    reply = Reply.refuse(now, f"internal error: {type(err).__name__}: {err}")
            query.reply(key, reply.encode(), encoding=zenoh.Encoding.APPLICATION_JSON)

        q = self.session.declare_queryable(key, on_query)
        self._entities.append(q)
        return q

    def request(self, spec: keys.KeySpec, request: Message, timeout_s: float = 2.0,
                vessel: str | None = None) -> Reply:
        """Send a request and wait for its Reply; no answer in time is a refusal saying so."""
        if spec.kind != "query" or spec.message is None:
            raise ValueError(f"{spec.suffix} is not a query key")
        if type(request) is not spec.message:
            raise TypeError(f"{spec.suffix} takes {spec.message.__name__}, not {type(request).__name__}")
        key = self.key(spec, vessel)
        replies = self.session.get(key, payload=request.encode(), timeout=timeout_s)
        for r in replies:
            if r.ok is not None:
                try:
                    return Reply.decode(r.ok.payload.to_bytes())
                except MessageError as err:
                    return Reply.refuse(time.time_ns(), f"malformed reply from {key}: {err}")
            return Reply.refuse(time.time_ns(), f"error reply from {key}: {r.err.payload.to_string()}")
        return Reply.refuse(time.time_ns(), f"no reply from {key} within {timeout_s:g} s "
                                            "(is the service running?)")

    # -- liveliness ---------------------------------------------------------------------------

    def declare_alive(self, service: str) -> None:
        """Declare this process's health token ``seaway/<vessel>/health/<service>``."""
        self._tokens.append(self.session.liveliness().declare_token(keys.health_key(self.vessel, service)))

    def alive_services(self, vessel: str | None = None, timeout_s: float = 1.0) -> set[str]:
        """Services whose health token is present now."""
        out = set()
        selector = keys.health_wildcard(vessel or self.vessel)
        for r in self.session.liveliness().get(selector, timeout=timeout_s):
            if r.ok is not None:
                out.add(str(r.ok.key_expr).rsplit("/", 1)[-1])
        return out

    def watch_health(self, callback: Callable[[str, bool], None], vessel: str | None = None) -> Any:
        """``callback(service, alive)`` on every health change; starts with the current set."""

        def on_sample(sample: zenoh.Sample) -> None:
            service = str(sample.key_expr).rsplit("/", 1)[-1]
            callback(service, sample.kind == zenoh.SampleKind.PUT)

        sub = self.session.liveliness().declare_subscriber(
            keys.health_wildcard(vessel or self.vessel), on_sample, history=True
        )
        self._entities.append(sub)
        return sub

    def close(self) -> None:
        """Undeclare everything and close the session. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for t in self._tokens:
            try:
                t.undeclare()
            except Exception:
                log.debug("token undeclare failed", exc_info=True)
        self.session.close()

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def iterate(sub: TypedSubscriber[M], stop: threading.Event, poll_s: float = 0.1) -> Iterator[M]:
    """Yield messages in order until ``stop`` is set."""
    while not stop.is_set():
        msg = sub.get(poll_s)
        if msg is not None:
            yield msg
