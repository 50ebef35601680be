"""What a ``Bus`` hands out for one key: a typed publisher, the subscribers and readers.

* ``TypedPublisher``: one message type on one key; refuses a message of the wrong type or with a
  non-finite field.
* ``TypedSubscriber``: ``latest``, ``fifo`` or a ``callback``, on the key published alone and, in
  lockstep, in its producer's bundle (``BundleTap``: one subscription per bundle key, shared).
* ``Newest`` (the newest sample's bytes, decoded when read), ``Every`` (every sample since the last
  read), ``RawRing`` (the last samples' bytes, taken when the reader looks).

A malformed payload is counted and logged by the bus (``Bus.decode_counted``) and dropped.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, Literal, Protocol, TypeVar

from seaway.contract import bundle, keys
from seaway.contract.messages import Message, message_encoding
from seaway.runtime.bus_raw import REJOIN_CACHE_SAMPLES, RawSample, carrying_put

if TYPE_CHECKING:
    from seaway.runtime.bus import Bus

M = TypeVar("M", bound=Message)

class TypedPublisher(Generic[M]):
    """Publishes one message type on one key."""

    def __init__(self, bus: Bus, spec: keys.KeySpec, key: str, lockstep: bool = False,
                 express: bool = False) -> None:
        assert spec.message is not None
        self.spec, self.key, self._bus = spec, key, bus
        self._type = spec.message
        # Real time: kept for a recorder that restarts (lockstep has its own catch-up, bundles
        # sent again, and every message of it counts: no copies on its hot path).
        self._pub = bus.raw_publisher(key, message_encoding(spec.message), block=lockstep,
                                      express=express, cache=0 if lockstep else REJOIN_CACHE_SAMPLES)
        self._put = carrying_put(self._pub)

    def put(self, msg: M) -> None:
        if type(msg) is not self._type:
            raise TypeError(f"{self.key} carries {self._type.__name__}, not {type(msg).__name__}")
        self._put(msg.encode(), msg)  # encoded first: a non-finite field is refused here
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
        inline: bool = False,
        bundles: bool = True,
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
        self._sub = bus.subscribe_raw(keyexpr, self._on_sample, inline=inline)
        # In lockstep the key travels in its producer's bundle (seaway.contract.bundle): hear it there.
        self._tap = bus.bundle_tap(spec, keyexpr, inline) if bundles else None
        if self._tap is not None:
            self._tap.add(spec.suffix, self._on_sample)

    def _on_sample(self, sample: RawSample) -> None:
        key = sample.key
        msg = self._bus.decode_counted(self._type, key, sample.payload, sample.carried)
        if msg is None:
            return
        if self._callback is not None:
            try:
                self._callback(key, msg)
            except Exception:  # a bug in a handler must not kill the transport's delivery thread
                self._bus.ratelog.exception(("handler", key), "handler for %s failed", key)
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
        if self._tap is not None:
            self._tap.remove(self.spec.suffix, self._on_sample)


class RawRing(Protocol):
    """A transport's ring of the last samples on a key expression (``Bus.ring_raw``): full, the
    oldest is dropped, never the transport held up."""

    def take(self) -> bytes | None:
        """The oldest payload held (removed from the ring), or None when it is empty."""

    def take_carried(self) -> tuple[bytes, Any] | None:
        """``take``, with what the payload was encoded from where the transport hands it along
        (``RawSample.carried``; None on Zenoh)."""

    def undeclare(self) -> None: ...


class RingByCallback:
    """``RawRing`` over ``subscribe_raw`` (a transport with no cheaper way: the in-memory bus)."""

    def __init__(self, bus: Bus, keyexpr: str, capacity: int) -> None:
        self._items: collections.deque[tuple[bytes, Any]] = collections.deque(maxlen=capacity)
        self._sub = bus.subscribe_raw(
            keyexpr, lambda s: self._items.append((s.payload, s.carried)), inline=True)

    def take(self) -> bytes | None:
        item = self.take_carried()
        return None if item is None else item[0]

    def take_carried(self) -> tuple[bytes, Any] | None:
        try:
            return self._items.popleft()
        except IndexError:
            return None

    def undeclare(self) -> None:
        self._sub.undeclare()


class BundleTap:
    """One subscription to a lockstep member's bundles (``seaway.contract.bundle``) on one key
    expression, handing each line on a routed key to that key's subscribers as a sample of its own.

    Shared by every typed subscriber of a process to the keys that member bundles, so a bundle is
    heard once however many of its keys are wanted. Only keys the member produces are routed
    (``bundle.bundled_by``), so a line of another member's key is never handed on."""

    def __init__(self, bus: Bus, keyexpr: str, inline: bool) -> None:
        self._routes: dict[str, list[Callable[[RawSample], None]]] = {}
        self._lock = threading.Lock()
        self._sub = bus.subscribe_raw(keyexpr, self._on_bundle, inline=inline)

    def add(self, suffix: str, callback: Callable[[RawSample], None]) -> None:
        with self._lock:
            self._routes = {**self._routes, suffix: [*self._routes.get(suffix, ()), callback]}

    def remove(self, suffix: str, callback: Callable[[RawSample], None]) -> None:
        with self._lock:
            left = [c for c in self._routes.get(suffix, ()) if c is not callback]
            self._routes = {k: v for k, v in {**self._routes, suffix: left}.items() if v}

    def _on_bundle(self, sample: RawSample) -> None:
        routes = self._routes  # replaced, never changed in place: no lock on the receive path
        if not routes or bundle.is_resent(sample.payload, sample.carried):  # a copy for a restarted recorder
            return
        prefix = sample.key[: sample.key.rfind("/lockstep/") + 1]
        carried = bundle.carried_lines(sample.payload, sample.carried, routes.keys())
        for suffix, data, msg in carried or ((s, d, None) for s, d in
                                             bundle.lines_of(sample.payload, routes.keys())):
            spec = keys.spec_for_suffix(suffix)
            assert spec is not None and spec.message is not None  # routed keys are registered
            for callback in routes[suffix]:
                callback(RawSample(prefix + suffix, data, message_encoding(spec.message),
                                   carried=msg))


def bundle_keyexpr(spec: keys.KeySpec, keyexpr: str) -> str | None:
    """The bundle key expression that carries ``spec`` where ``keyexpr`` (``seaway/<v>/<suffix>``,
    ``<v>`` possibly ``*``) names it, or None if no lockstep bundle carries it."""
    member = bundle.bundled_by(spec)
    if member is None or not keyexpr.endswith("/" + spec.suffix):
        return None
    return keyexpr[: -len(spec.suffix)] + keys.lockstep_spec(member).suffix


def _news(ring: RawRing) -> list[bytes]:
    """Every bundle ``ring`` holds, oldest first, but the copies sent again for a restarted
    recorder (``bundle.is_resent``): a reader of keys has had those."""
    out = []
    while (payload := ring.take()) is not None:
        if not bundle.is_resent(payload):
            out.append(payload)
    return out


NEWEST_BUNDLES = 64
"""Bundles a ``Newest`` keeps between reads, searched newest first for its key: a read finds a key
sent every period in the newest, and one sent in fewer periods if it came in the last 64."""


class Newest(Generic[M]):
    """The newest sample on one key, decoded only when read (``get``), and once per sample.

    The transport keeps only the newest sample's bytes (Zenoh: a ring of one, filled by its own
    threads without running any Python): a reader that looks a few times a second (the launcher's
    status line) pays nothing for the hundreds of samples a second between its looks in lockstep.
    A malformed sample is counted and logged when read, and the last good message stays the answer.
    """

    def __init__(self, bus: Bus, spec: keys.KeySpec, keyexpr: str) -> None:
        assert spec.message is not None
        self._bus, self.keyexpr = bus, keyexpr
        self._type: type[M] = spec.message  # type: ignore[assignment]
        self._msg: M | None = None
        self._lock = threading.Lock()
        self._src = bus.ring_raw(keyexpr, 1)
        self._suffix = spec.suffix
        tap = bundle_keyexpr(spec, keyexpr)
        self._bundles = bus.ring_raw(tap, NEWEST_BUNDLES) if tap is not None else None

    def get(self) -> M | None:
        """The newest well-formed message heard, or None before the first."""
        with self._lock:
            raw = self._src.take()
            if self._bundles is not None:  # lockstep: in the newest bundle that carries it
                for payload in reversed(_news(self._bundles)):
                    lines = bundle.lines_of(payload, (self._suffix,))
                    if lines:
                        raw = lines[-1][1]
                        break
            if raw is not None:  # a malformed one leaves the last good message the answer
                self._msg = self._bus.decode_counted(self._type, self.keyexpr, raw) or self._msg
            return self._msg

    def undeclare(self) -> None:
        self._src.undeclare()
        if self._bundles is not None:
            self._bundles.undeclare()


EVERY_CAPACITY = 4096
"""Samples (or bundles) an ``Every`` holds between reads: some 10 s of lockstep periods."""


class Every(Generic[M]):
    """Every sample on one key since the last read, decoded only when read (``take``), in order.

    Like ``Newest``, the transport holds the bytes (a ring filled by its own threads, no Python per
    sample), for a reader that looks a few times a second but must miss none (the launcher's energy
    budgets: the one of the period a decision was taken). In lockstep the key comes in its
    producer's bundles; those are held and searched the same way. Past ``capacity`` between two
    reads the oldest are lost (a reader that stopped reading for seconds).
    """

    def __init__(self, bus: Bus, spec: keys.KeySpec, keyexpr: str,
                 capacity: int = EVERY_CAPACITY) -> None:
        assert spec.message is not None
        self._bus, self.keyexpr, self._suffix = bus, keyexpr, spec.suffix
        self._type: type[M] = spec.message  # type: ignore[assignment]
        self._src = bus.ring_raw(keyexpr, capacity)
        tap = bundle_keyexpr(spec, keyexpr)
        self._bundles = bus.ring_raw(tap, capacity) if tap is not None else None

    def take(self) -> list[M]:
        """The well-formed messages heard since the last call, oldest first (malformed ones are
        counted and logged)."""
        raws = []
        while (raw := self._src.take()) is not None:
            raws.append(raw)
        if self._bundles is not None:
            for payload in _news(self._bundles):
                raws += [data for _, data in bundle.lines_of(payload, (self._suffix,))]
        out = [self._bus.decode_counted(self._type, self.keyexpr, raw) for raw in raws]
        return [m for m in out if m is not None]

    def undeclare(self) -> None:
        self._src.undeclare()
        if self._bundles is not None:
            self._bundles.undeclare()
