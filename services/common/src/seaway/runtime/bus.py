"""The bus interface: typed access to one vessel's keys, over a transport that moves bytes.

``Bus`` is what a service loop talks to. Two transports implement it:

* ``seaway.runtime.zenoh_bus.ZenohBus``: the real one, a Zenoh session (``Bus.open``);
* ``seaway.runtime.memory_bus.MemoryBus``: in process, no network, for unit tests of service loops.

The typed layer is written once, here and in ``bus_typed`` (the publisher and the readers a bus
hands out), over a handful of byte-level primitives each transport provides (``bus_raw``), so both
transports encode, validate, refuse and count exactly the same way:

* ``Bus.publisher(spec)``: typed; refuses a message of the wrong type or with a non-finite field.
* ``Bus.subscribe(spec, mode=...)``: ``latest`` keeps only the newest sample (a controller wants the
  freshest state), ``fifo`` keeps every sample in order up to a bound (a recorder, an estimator), or a
  ``callback``. ``Bus.newest(spec)`` keeps the newest sample's bytes and decodes them only when read
  (a display that shows a few a second of what comes hundreds a second in lockstep). A malformed
  payload is logged with its key, counted and dropped; the process goes on.
  Logged once per key and then at most every few seconds with a count (``seaway.runtime.ratelog``):
  a flood of bad samples is counted, not echoed line by line.
* ``Bus.queryable`` / ``Bus.request``: a request is answered by a ``Reply`` that accepts or refuses
  with a reason; a malformed request is refused, never crashes the server; no answer is a refusal
  that says so.
* liveliness tokens under ``seaway/<vessel>/health/<service>``: ``declare_alive``,
  ``alive_services``, ``watch_health``.
* raw bytes on any key, for tools that keep bytes unchanged (the recorder, replay) and for tests
  that send what a typed publisher would refuse: ``raw_publisher``, ``subscribe_raw``,
  ``queryable_raw``, ``query_raw``.
"""

from __future__ import annotations

import abc
import logging
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from seaway.contract import keys
from seaway.contract.messages import JSON_ENCODING, Message, MessageError, Reply
from seaway.runtime.bus_raw import (
    RAW_ENCODING,
    Declared,
    RawPublisher,
    RawReply,
    RawSample,
)
from seaway.runtime.bus_typed import (
    BundleTap,
    Every,
    M,
    Newest,
    RawRing,
    RingByCallback,
    TypedPublisher,
    TypedSubscriber,
    bundle_keyexpr,
)
from seaway.runtime.ratelog import RateLimitedLog

if TYPE_CHECKING:
    pass

log = logging.getLogger("seaway.runtime.bus")

class RuntimeEnvError(ValueError):
    """A bus that cannot open because ``$ZENOH_RUNTIME`` (Zenoh's thread pools, set by the user or,
    in a lockstep run, by ``zenoh_bus.use_lockstep_runtime``) is not something Zenoh can read; the
    message says what it takes."""


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


def _service_of(health_key: str) -> str:
    """``seaway/<vessel>/health/<service>`` -> ``<service>``."""
    return health_key.rsplit("/", 1)[-1]


class Bus(abc.ABC):
    """One service's typed access to the registered keys of one vessel, over some transport.

    Subclasses provide the byte-level primitives (the ``raw`` methods, the three token methods and
    ``_close_transport``); everything typed is implemented here, once.
    """

    delivers_in_put = False
    """Whether ``put`` hands a sample to the subscribers on the publishing thread before it returns
    (the in-memory bus), rather than the transport's own threads doing it later."""

    def __init__(self, vessel: str) -> None:
        self.vessel = keys.check_vessel(vessel)
        self.stats = BusStats()
        self.ratelog = RateLimitedLog(log)
        """The bus's repeated warnings (malformed samples and requests, failing handlers), per key."""
        self.side = "local"
        """Whose stack this bus is in (``seaway.contract.access.SIDES``): a shore's health tokens
        are named as the shore's (``keys.side_service``). Set from the credentials' rules."""
        self._tokens: list[Declared] = []
        self._closed = False
        self._taps: dict[tuple[str, bool], BundleTap] = {}
        self._taps_lock = threading.Lock()

    @classmethod
    def open(cls, vessel: str, config_path: str | Path | None = None, identity: str | None = None,
             credentials: Any = None, rendezvous: str | None = None) -> Bus:
        """The production bus: a Zenoh session from ``config_path`` as ``identity`` of the stack
        (``credentials``: a ``seaway.runtime.credentials.Credentials``; ``rendezvous``: the stack's
        endpoint, else ``$SEAWAY_ZENOH_RENDEZVOUS``; see ``zenoh_bus``). In a process that
        composes its services (``seaway.runtime.host``), a bus on the host's in-memory hub."""
        from seaway.runtime import host  # the interface itself needs neither

        composed = host.active()
        if composed is not None:
            return composed.bus(vessel)
        from seaway.runtime.zenoh_bus import ZenohBus  # the interface itself needs no Zenoh

        return ZenohBus.connect(vessel, config_path, identity, credentials, rendezvous)

    def key(self, spec: keys.KeySpec, vessel: str | None = None) -> str:
        return spec.key(vessel or self.vessel)

    def decode_counted(self, message: type[M], key: str, payload: bytes,
                       carried: Any = None) -> M | None:
        """``payload`` heard on ``key`` as a ``message``, counted as received; None if it is
        malformed: then counted and logged (rate-limited, per key), and dropped. ``carried``: what
        an in-process publisher encoded ``payload`` from (``RawSample.carried``), taken as it is
        when it is a ``message`` (built, so validated, and frozen), else the bytes are decoded."""
        if type(carried) is message:
            self.stats.received += 1
            return carried  # type: ignore[no-any-return]
        try:
            msg = message.decode(payload)
        except MessageError as err:
            self.stats.count_malformed(key, str(err))
            self.ratelog.warning(("malformed", key), "dropped malformed payload on %s: %s "
                                 "(counted in the bus stats)", key, err)
            return None
        self.stats.received += 1
        return msg

    # -- typed topics ------------------------------------------------------------------------------

    def publisher(self, spec: keys.KeySpec, vessel: str | None = None,
                  lockstep: bool = False, express: bool = False) -> TypedPublisher[Any]:
        """A publisher of ``spec``. ``lockstep``: every message counts, so it is never dropped
        under congestion (the publisher blocks instead). ``express``: sent at once, not batched,
        and the batch queued before it goes with it (Zenoh's ``express``).

        A lockstep member publishes its period as one bundle (``seaway.runtime.lockstep_member.Member``),
        not through publishers of its keys."""
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        return TypedPublisher(self, spec, self.key(spec, vessel), lockstep, express)

    def subscribe(
        self,
        spec: keys.KeySpec,
        mode: Literal["latest", "fifo"] = "latest",
        capacity: int = 10_000,
        callback: Callable[[str, Any], None] | None = None,
        vessel: str | None = None,
        inline: bool = False,
        bundles: bool = True,
    ) -> TypedSubscriber[Any]:
        """Subscribe to ``spec`` on this vessel (or ``vessel``, which may be ``*``).

        ``inline``: run ``callback`` on the transport's own receive thread, with no hand-off to a
        Python thread of its own first: the lowest latency, for short handlers that take no lock
        anybody holds for long (vehicle_io's thrust path).

        The key is heard whether published alone or, in lockstep, in its producer's bundle
        (``seaway.contract.bundle``); ``bundles=False`` hears only what is published alone (a
        lockstep member, which hears the bundles through its ``Member`` already).
        """
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        keyexpr = spec.wildcard() if vessel == "*" else self.key(spec, vessel)
        return TypedSubscriber(self, spec, keyexpr, mode, capacity, callback, inline, bundles)

    def bundle_tap(self, spec: keys.KeySpec, keyexpr: str, inline: bool) -> BundleTap | None:
        """The shared subscription to the bundles that carry ``spec`` where ``keyexpr`` names it
        (``BundleTap``), or None if none do."""
        tap_expr = bundle_keyexpr(spec, keyexpr)
        if tap_expr is None:
            return None
        with self._taps_lock:
            tap = self._taps.get((tap_expr, inline))
            if tap is None:
                tap = self._taps[(tap_expr, inline)] = BundleTap(self, tap_expr, inline)
            return tap

    def ring_raw(self, keyexpr: str, capacity: int) -> RawRing:
        """Hold the last ``capacity`` samples' bytes on ``keyexpr`` for a reader that takes them
        when it looks (``RawRing``), not a callback each; transports with a cheaper way override
        it."""
        return RingByCallback(self, keyexpr, capacity)

    def newest(self, spec: keys.KeySpec, vessel: str | None = None) -> Newest[Any]:
        """The newest sample on ``spec`` of this vessel (or ``vessel``), decoded when read."""
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        return Newest(self, spec, self.key(spec, vessel))

    def every(self, spec: keys.KeySpec, vessel: str | None = None) -> Every[Any]:
        """Every sample on ``spec`` of this vessel (or ``vessel``) since the last read (``Every``)."""
        if spec.kind != "topic":
            raise ValueError(f"{spec.suffix} is a {spec.kind}, not a topic")
        return Every(self, spec, self.key(spec, vessel))

    # -- typed requests ----------------------------------------------------------------------------

    def queryable(self, spec: keys.KeySpec, handler: Callable[[Any], Reply],
                  vessel: str | None = None) -> Declared:
        """Serve requests on ``spec``: ``handler(request) -> Reply``. Bad requests are refused."""
        if spec.kind != "query" or spec.message is None:
            raise ValueError(f"{spec.suffix} is not a query key")
        req_type = spec.message
        key = self.key(spec, vessel)

        def serve(payload: bytes | None) -> bytes:
            now = time.time_ns()
            try:
                if payload is None:
                    raise MessageError(f"{req_type.__name__}: empty request")
                request = req_type.decode(payload)
            except MessageError as err:
                self.stats.count_malformed(key, str(err))
                self.ratelog.warning(("request", key), "refused malformed request on %s: %s",
                                     key, err)
                reply = Reply.refuse(now, f"malformed request: {err}")
            else:
                try:
                    reply = handler(request)
                except Exception as err:  # the server keeps running; the caller learns why
                    self.ratelog.exception(("request handler", key), "request handler for %s "
                                           "failed", key)
                    reply = Reply.refuse(now, f"internal error: {type(err).__name__}: {err}")
            return reply.encode()

        return self.queryable_raw(key, serve)

    def request(self, spec: keys.KeySpec, request: Message, timeout_s: float = 2.0,
                vessel: str | None = None) -> Reply:
        """Send a request and wait for its Reply; no answer in time is a refusal saying so."""
        if spec.kind != "query" or spec.message is None:
            raise ValueError(f"{spec.suffix} is not a query key")
        if type(request) is not spec.message:
            raise TypeError(f"{spec.suffix} takes {spec.message.__name__}, not {type(request).__name__}")
        key = self.key(spec, vessel)
        for r in self.query_raw(key, request.encode(), timeout_s):
            if r.error is None:
                try:
                    return Reply.decode(r.payload)
                except MessageError as err:
                    return Reply.refuse(time.time_ns(), f"malformed reply from {key}: {err}")
            return Reply.refuse(time.time_ns(), f"error reply from {key}: {r.error}")
        return Reply.refuse(time.time_ns(), f"no reply from {key} within {timeout_s:g} s "
                                            "(is the service running?)")

    # -- liveliness ---------------------------------------------------------------------------------

    def declare_alive(self, service: str, vessel: str | None = None) -> None:
        """Declare this process's health token ``seaway/<vessel>/health/<service>``, on a shore
        ``health/shore-<service>`` (``vessel``: another than the bus's, for a process serving
        several: the launcher of a fleet)."""
        self._tokens.append(self._declare_token(keys.health_key(vessel or self.vessel, service,
                                                                self.side)))

    def alive_services(self, vessel: str | None = None, timeout_s: float = 1.0) -> set[str]:
        """Services whose health token is present now."""
        selector = keys.health_wildcard(vessel or self.vessel)
        return {_service_of(k) for k in self._live_tokens(selector, timeout_s)}

    def watch_health(self, callback: Callable[[str, bool], None], vessel: str | None = None) -> Declared:
        """``callback(service, alive)`` on every health change; starts with the current set."""
        return self._watch_tokens(keys.health_wildcard(vessel or self.vessel),
                                  lambda key, alive: callback(_service_of(key), alive))

    def watch_fleet_health(self, callback: Callable[[str, str, bool], None]) -> Declared:
        """``callback(vessel, service, alive)`` for every vessel's health tokens, now and on change
        (a ground station watching several vessels)."""

        def on_token(key: str, alive: bool) -> None:
            parts = key.split("/")
            if len(parts) == 4 and parts[0] == keys.ROOT and parts[2] == keys.HEALTH:
                callback(parts[1], parts[3], alive)

        return self._watch_tokens(keys.health_wildcard("*"), on_token)

    def declare_lockstep_member(self, service: str) -> None:
        """Declare ``service`` a lockstep member: a liveliness token on its ``lockstep/<service>``
        key, present while this bus is open (``seaway.runtime.lockstep``)."""
        self._tokens.append(self._declare_token(keys.lockstep_spec(service).key(self.vessel)))

    def watch_lockstep_members(self, callback: Callable[[str, bool], None]) -> Declared:
        """``callback(service, present)`` for every lockstep member token of this vessel; starts
        with the current set."""
        return self._watch_tokens(f"{keys.ROOT}/{self.vessel}/lockstep/*",
                                  lambda key, alive: callback(_service_of(key), alive))

    # -- closing ------------------------------------------------------------------------------------

    def close(self) -> None:
        """Withdraw the health tokens and close the transport. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for t in self._tokens:
            try:
                t.undeclare()
            except Exception:
                log.debug("token undeclare failed", exc_info=True)
        self._close_transport()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- what a transport provides ------------------------------------------------------------------

    @abc.abstractmethod
    def raw_publisher(self, key: str, encoding: str = RAW_ENCODING, *, block: bool = False,
                      express: bool = False, cache: int = 0) -> RawPublisher:
        """Publish bytes on ``key`` with ``encoding``. ``block``: wait rather than drop when the
        network is congested (replay, which must lose nothing). ``cache``: keep the last ``cache``
        samples for a subscriber with ``history_s`` that joins late (a restarted recorder)."""

    @abc.abstractmethod
    def subscribe_raw(self, keyexpr: str, callback: Callable[[RawSample], None], *,
                      inline: bool = False, history_s: float = 0.0) -> Declared:
        """``callback(sample)`` for every sample on ``keyexpr`` (wildcards allowed), bytes unchanged.
        ``history_s`` > 0: also, first, what publishers with a ``cache`` published in the last
        ``history_s`` seconds, each with its ``published_ns`` (also those found later: a
        publisher restarted meanwhile)."""

    @abc.abstractmethod
    def queryable_raw(self, key: str, serve: Callable[[bytes | None], bytes],
                      encoding: str = JSON_ENCODING) -> Declared:
        """Answer every query on ``key`` with ``serve(request payload or None)``."""

    @abc.abstractmethod
    def query_raw(self, selector: str, payload: bytes | None = None, timeout_s: float = 2.0, *,
                  every: bool = False) -> Iterator[RawReply]:
        """Send a query now; iterate its answers as they come, until all came or ``timeout_s``.

        ``every``: ask every matching queryable and keep every answer (a census of services);
        otherwise the transport's default (the best-matching queryable).
        """

    @abc.abstractmethod
    def _declare_token(self, key: str) -> Declared:
        """A liveliness token on ``key``, present until undeclared or the bus closes."""

    @abc.abstractmethod
    def _live_tokens(self, selector: str, timeout_s: float) -> Iterable[str]:
        """Keys of the tokens present now on ``selector``."""

    @abc.abstractmethod
    def _watch_tokens(self, selector: str, callback: Callable[[str, bool], None]) -> Declared:
        """``callback(key, alive)`` for the tokens present now, then on every change."""

    @abc.abstractmethod
    def _close_transport(self) -> None:
        """Release everything this bus declared (the health tokens are already withdrawn)."""


def iterate(sub: TypedSubscriber[M], stop: threading.Event, poll_s: float = 0.1) -> Iterator[M]:
    """Yield messages in order until ``stop`` is set."""
    while not stop.is_set():
        msg = sub.get(poll_s)
        if msg is not None:
            yield msg
