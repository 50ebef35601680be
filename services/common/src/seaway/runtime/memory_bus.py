"""The bus in memory: ``MemoryBus`` instances on one ``MemoryHub`` act like processes on one network.

For unit tests of service loops: no network, no discovery delay, nothing to clean up. The typed layer
(encoding on put, decoding and counting on delivery, request refusals) is ``Bus``'s own, the same
code the Zenoh bus runs; only the moving of bytes is done here:

* ``put`` delivers synchronously: when it returns, every matching subscriber has the sample (queued
  for ``latest``/``fifo``, or its callback has run), so a test needs no sleeps. A put made by a
  subscriber's callback while it is handed a sample (on the delivering thread) is delivered once
  that sample has reached every subscriber, in the order put: a reaction never reaches anybody
  before its cause (a lockstep member's ring holds the sim's bundle before the estimator's answer
  to it reaches the controller), and the outermost put returns once all of it is delivered;
* a query runs the queryable's handler on a thread of its own and waits up to ``timeout_s`` for it,
  so a slow handler gives the same "no reply within" refusal as on Zenoh;
* key expressions match as on Zenoh (``zenoh.KeyExpr`` decides: one definition of ``*`` and ``**``);
* health tokens come and go with ``declare_alive`` and ``close``, and watchers hear both.

Differences to keep in mind: delivery runs in the publishing thread, so a callback that takes a lock
the publisher holds deadlocks here (on Zenoh it would wait for a delivery thread); nothing is ever
dropped or reordered; ``block`` and ``inline`` change nothing; a typed publisher's sample (and a
lockstep member's bundle) carries the object its bytes were encoded from (``RawSample.carried``), so
a receiver takes that object instead of decoding the bytes again (a raw publisher's bytes carry
nothing and are decoded, and refused if malformed, as on Zenoh).
"""

from __future__ import annotations

import collections
import functools
import logging
import queue
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

import zenoh

from seaway.contract.messages import JSON_ENCODING
from seaway.runtime import host
from seaway.runtime.bus import Bus
from seaway.runtime.bus_raw import RAW_ENCODING, Declared, RawPublisher, RawReply, RawSample
from seaway.runtime.service import DEFAULT_VESSEL

log = logging.getLogger("seaway.runtime.memory_bus")


@functools.lru_cache(maxsize=4096)
def _keyexpr(expr: str) -> zenoh.KeyExpr:
    """The parsed key expression; raises on an invalid one, as declaring it on Zenoh would."""
    return zenoh.KeyExpr(expr)


@functools.lru_cache(maxsize=16384)
def intersects(a: str, b: str) -> bool:
    """Whether key expressions ``a`` and ``b`` have a key in common (Zenoh's rule)."""
    return _keyexpr(a).intersects(_keyexpr(b))


class _Declaration:
    """One subscriber, queryable or token watcher in a hub; ``undeclare`` withdraws it."""

    def __init__(self, hub: MemoryHub, table: list[_Declaration], owner: MemoryBus, expr: str,
                 fn: Callable[..., Any]) -> None:
        self.hub, self.table, self.owner, self.expr, self.fn = hub, table, owner, expr, fn

    def undeclare(self) -> None:
        self.hub._remove(self)


class _Token:
    """A liveliness token; ``undeclare`` withdraws it once."""

    def __init__(self, hub: MemoryHub, key: str) -> None:
        self.hub, self.key, self.live = hub, key, True

    def undeclare(self) -> None:
        if self.live:
            self.live = False
            self.hub._drop_token(self.key)


class _Publisher:
    def __init__(self, bus: MemoryBus, key: str, encoding: str) -> None:
        self.bus, self.key, self.encoding = bus, key, encoding
        self.declared = True

    def put(self, payload: bytes) -> None:
        self.put_carrying(payload, None)

    def put_carrying(self, payload: bytes, carried: Any) -> None:
        """``put``, handing ``carried`` (what ``payload`` was encoded from) to the receivers
        (``RawSample.carried``): in one process they need not decode the bytes again."""
        if self.bus.closed or not self.declared:
            raise RuntimeError(f"publisher on {self.key}: the bus is closed or the publisher undeclared")
        self.bus.hub._publish(RawSample(self.key, bytes(payload), self.encoding, carried=carried))

    def undeclare(self) -> None:
        self.declared = False


class MemoryHub:
    """The in-process network: who subscribes, who serves, which tokens are alive."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._subscribers: list[_Declaration] = []
        self._targets: dict[str, list[Callable[[RawSample], None]]] = {}
        """Key -> the callbacks of the subscribers matching it, made on the first put on the key
        and forgotten whenever a subscriber comes or goes."""
        self._delivering = threading.local()
        """Per thread, while it delivers: the samples its subscribers put meanwhile (``_publish``)."""
        self._queryables: list[_Declaration] = []
        self._watchers: list[_Declaration] = []
        self._tokens: collections.Counter[str] = collections.Counter()

    def bus(self, vessel: str = DEFAULT_VESSEL) -> MemoryBus:
        """A new bus on this hub: one more "process" on the same network."""
        return MemoryBus(vessel, self)

    # -- declarations --------------------------------------------------------------------------------

    def _declare(self, table: list[_Declaration], owner: MemoryBus, expr: str,
                 fn: Callable[..., Any]) -> _Declaration:
        _keyexpr(expr)
        d = _Declaration(self, table, owner, expr, fn)
        with self._lock:
            table.append(d)
            self._targets = {}
        return d

    def _remove(self, d: _Declaration) -> None:
        with self._lock:
            if d in d.table:
                d.table.remove(d)
                self._targets = {}

    def _drop_owner(self, owner: MemoryBus) -> None:
        with self._lock:
            for table in (self._subscribers, self._queryables, self._watchers):
                table[:] = [d for d in table if d.owner is not owner]
            self._targets = {}

    # -- data -----------------------------------------------------------------------------------------

    def _publish(self, sample: RawSample) -> None:
        delivering = self._delivering
        pending: collections.deque[RawSample] | None = getattr(delivering, "pending", None)
        if pending is not None:  # put by a subscriber: once what is being delivered is
            pending.append(sample)
            return
        pending = delivering.pending = collections.deque((sample,))
        try:
            while pending:
                self._deliver(pending.popleft())
        finally:
            delivering.pending = None

    def _deliver(self, sample: RawSample) -> None:
        with self._lock:
            targets = self._targets.get(sample.key)
            if targets is None:
                targets = self._targets[sample.key] = [
                    d.fn for d in self._subscribers if intersects(d.expr, sample.key)]
        for fn in targets:  # outside the lock: a callback may publish or declare in turn
            try:
                fn(sample)
            except Exception:  # as on Zenoh, a subscriber's bug does not reach the publisher
                log.exception("subscriber callback for %s failed", sample.key)

    def _query(self, selector: str, payload: bytes | None, timeout_s: float,
               every: bool) -> Iterator[RawReply]:
        with self._lock:
            targets = [d for d in self._queryables if intersects(d.expr, selector)]
        if not every:
            targets = targets[:1]  # Zenoh's default target: one (the best-matching) queryable
        answers: queue.Queue[RawReply | None] = queue.Queue()

        def serve(d: _Declaration) -> None:
            try:
                answers.put(RawReply(d.expr, d.fn(payload)))
            except Exception:  # no reply, as when a Zenoh queryable callback raises
                log.exception("queryable %s failed", d.expr)
                answers.put(None)

        for d in targets:
            t = threading.Thread(target=serve, args=(d,), name=f"memory-query {d.expr}", daemon=True)
            host.adopt(t, d.owner.node)  # the server's work, whoever asked (composed output)
            t.start()
        return self._answers(answers, len(targets), time.monotonic() + timeout_s)

    @staticmethod
    def _answers(answers: queue.Queue[RawReply | None], n: int, deadline: float) -> Iterator[RawReply]:
        for _ in range(n):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            try:
                reply = answers.get(timeout=remaining)
            except queue.Empty:
                return
            if reply is not None:
                yield reply

    # -- liveliness ------------------------------------------------------------------------------------

    def _add_token(self, key: str) -> _Token:
        _keyexpr(key)
        with self._lock:
            self._tokens[key] += 1
            appeared = self._tokens[key] == 1
        if appeared:
            self._notify(key, True)
        return _Token(self, key)

    def _drop_token(self, key: str) -> None:
        with self._lock:
            self._tokens[key] -= 1
            gone = self._tokens[key] <= 0
            if gone:
                del self._tokens[key]
        if gone:
            self._notify(key, False)

    def _live(self, selector: str) -> list[str]:
        with self._lock:
            return [k for k in self._tokens if intersects(selector, k)]

    def _watch(self, owner: MemoryBus, selector: str, callback: Callable[[str, bool], None]) -> _Declaration:
        d = self._declare(self._watchers, owner, selector, callback)
        for key in self._live(selector):  # history: the tokens already present
            callback(key, True)
        return d

    def _notify(self, key: str, alive: bool) -> None:
        with self._lock:
            targets = [d.fn for d in self._watchers if intersects(d.expr, key)]
        for fn in targets:
            try:
                fn(key, alive)
            except Exception:
                log.exception("health watcher for %s failed", key)


class MemoryBus(Bus):
    """A bus on a ``MemoryHub`` (a private one unless given): see the module's description."""

    delivers_in_put = True

    def __init__(self, vessel: str = DEFAULT_VESSEL, hub: MemoryHub | None = None) -> None:
        super().__init__(vessel)
        self.hub = hub if hub is not None else MemoryHub()
        self.node = host.Host.current()
        """The composed node this bus was opened for (``seaway.runtime.host``), else None."""

    @property
    def closed(self) -> bool:
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the bus is closed")

    def raw_publisher(self, key: str, encoding: str = RAW_ENCODING, *, block: bool = False,
                      express: bool = False, cache: int = 0) -> RawPublisher:
        # ``cache``: nothing to keep, no subscriber of one process joins late.
        self._check_open()
        _keyexpr(key)
        return _Publisher(self, key, encoding)

    def subscribe_raw(self, keyexpr: str, callback: Callable[[RawSample], None], *,
                      inline: bool = False, history_s: float = 0.0) -> Declared:
        self._check_open()
        return self.hub._declare(self.hub._subscribers, self, keyexpr, callback)

    def queryable_raw(self, key: str, serve: Callable[[bytes | None], bytes],
                      encoding: str = JSON_ENCODING) -> Declared:
        self._check_open()
        return self.hub._declare(self.hub._queryables, self, key, serve)

    def query_raw(self, selector: str, payload: bytes | None = None, timeout_s: float = 2.0, *,
                  every: bool = False) -> Iterator[RawReply]:
        self._check_open()
        _keyexpr(selector)
        return self.hub._query(selector, payload, timeout_s, every)

    def _declare_token(self, key: str) -> Declared:
        self._check_open()
        return self.hub._add_token(key)

    def _live_tokens(self, selector: str, timeout_s: float) -> Iterable[str]:
        self._check_open()
        return self.hub._live(selector)

    def _watch_tokens(self, selector: str, callback: Callable[[str, bool], None]) -> Declared:
        self._check_open()
        return self.hub._watch(self, selector, callback)

    def _close_transport(self) -> None:
        self.hub._drop_owner(self)
