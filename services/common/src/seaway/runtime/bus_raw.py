"""What a transport moves under the bus (``seaway.runtime.bus``): samples of bytes, the publishers and
replies of bytes, and what is declared on it.

Every transport (``zenoh_bus``, ``memory_bus``) gives these; the typed layer (``bus_typed``, and the
``Bus`` itself) is written over them once.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

RAW_ENCODING = "zenoh/bytes"
"""Encoding of raw bytes published without one (Zenoh's default, so both transports report it)."""


class RawSample(NamedTuple):
    """One sample as the transport delivered it: bytes unchanged, with their key and encoding.
    ``published_ns``: when it was published [ns since epoch, the publisher's clock], where the
    transport says (Zenoh's timestamp), else None.

    ``carried``: on the in-process bus only, what the publisher encoded ``payload`` from (a
    ``Message`` from a typed publisher, a ``bundle.Carried`` from a lockstep member), so that a
    receiver in the same process need not decode the bytes again (``Bus.decode_counted``; the
    messages are frozen). None from a transport that moves bytes (Zenoh): a payload from another
    process is always decoded and validated. The bytes travel all the same (a recorder writes
    them)."""

    key: str
    payload: bytes
    encoding: str
    published_ns: int | None = None
    carried: Any = None


REJOIN_CACHE_SAMPLES = 512
"""Samples a real-time topic publisher keeps for a subscriber that joins late (a restarted
recorder) to ask for: 10 s of the fastest sensor topic at 50 Hz, more of the others."""
REJOIN_HISTORY_S = 10.0
"""How far back such a subscriber asks [s]: longer than a recorder's restart by the launcher."""


class RawReply(NamedTuple):
    """One answer to ``query_raw``: the replier's key and bytes, or an error reply's text."""

    key: str
    payload: bytes
    error: str | None = None  # set for an error reply (which has no key; ``key`` is then "")


class RawPublisher(Protocol):
    """Publishes bytes on one key with the encoding it was declared with."""

    def put(self, payload: bytes) -> None: ...

    def undeclare(self) -> None: ...


PutCarrying = Callable[[bytes, Any], None]
"""``put(payload, carried)``: publish ``payload``, and on an in-process bus hand ``carried`` (what
it was encoded from) along with it (``RawSample.carried``)."""


def carrying_put(pub: RawPublisher) -> PutCarrying:
    """``pub``'s put that hands the encoded object along where its transport can (the in-process
    bus's publishers have ``put_carrying``), else its plain put (the object dropped)."""
    put_carrying = getattr(pub, "put_carrying", None)
    if put_carrying is not None:
        return put_carrying  # type: ignore[no-any-return]
    put = pub.put
    return lambda payload, _carried: put(payload)


class Declared(Protocol):
    """Anything declared on a bus (subscriber, queryable, token): undeclare to withdraw it."""

    def undeclare(self) -> None: ...
