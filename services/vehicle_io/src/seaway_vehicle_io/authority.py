"""Who may speak for the autopilot: MAVLink sources, and the bookkeeping of the ones refused.

Pure (time passed in, no socket). A *source* is what a message claims and where it came from:
``(system id, component id, address)``, the address being the UDP/TCP peer ``(host, port)`` the
bytes arrived from, or None on a serial link (the port is the source) and for datagrams whose
header could not be read (ids None). The core locks to one source (``core.py``); everything else
is refused, counted here per reason and per source, and logged once per source.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

log = logging.getLogger("seaway.vehicle_io")

Address = tuple[str, int] | None
Source = tuple[int | None, int | None, Address]

# Why a message was refused (VehicleStatus.refused_messages keys).
FOREIGN_SOURCE = "foreign_source"  # not the locked autopilot: other address, system id (or, before
#                                    the lock, a HEARTBEAT from an address we do not talk to)
UNSIGNED = "unsigned"  # signing is on and the message carries no signature
BAD_SIGNATURE = "bad_signature"  # signed, but not with our key (or altered)
REPLAYED = "replayed"  # authentic, but its timestamp is not newer than the stream's last

REASON_TEXT = {
    FOREIGN_SOURCE: "not the autopilot vehicle_io is locked to",
    UNSIGNED: "unsigned, and signing is on",
    BAD_SIGNATURE: "signature does not match our key",
    REPLAYED: "replayed or stale signing timestamp",
}

MAX_SOURCES = 64  # per-source counters kept; beyond, new sources are pooled under OTHER
OTHER: Source = (None, None, ("other sources", 0))
NEW_SOURCE_LOG_EVERY_NS = 1_000_000_000  # at most one "new source" line a second


def describe(source: Source) -> str:
    """'system 1 component 1 at 127.0.0.1:5000' (question marks for what is unknown)."""
    sysid, compid, address = source
    if source == OTHER:
        return "further sources"
    where = "on the link" if address is None else f"at {address[0]}:{address[1]}"
    return (f"system {'?' if sysid is None else sysid} component {'?' if compid is None else compid} "
            f"{where}")


def address_key(address: Address) -> str:
    return "serial" if address is None else f"{address[0]}:{address[1]}"


@dataclass
class Refusals:
    """Messages refused, by reason and by (reason, source); each new pair logged once.

    A flood from ever new addresses cannot grow memory or the log: at most ``MAX_SOURCES`` pairs
    are kept (the rest pooled under ``OTHER``), and new-source lines come at most one a second: a
    pair first seen meanwhile waits its turn (``flush``, and every later refusal, log the next).
    """

    by_reason: dict[str, int] = field(default_factory=dict)
    by_source: dict[tuple[str, Source], int] = field(default_factory=dict)
    _last_log_ns: int | None = None
    _unlogged: list[tuple[str, Source]] = field(default_factory=list)

    @property
    def total(self) -> int:
        return sum(self.by_reason.values())

    def add(self, reason: str, source: Source, count: int, now_ns: int) -> None:
        """Count ``count`` messages from ``source`` refused for ``reason`` at ``now_ns``."""
        if count <= 0:
            return
        self.by_reason[reason] = self.by_reason.get(reason, 0) + count
        key = (reason, source)
        if key not in self.by_source and len(self.by_source) >= MAX_SOURCES:
            key = (reason, OTHER)
        if key in self.by_source:
            self.by_source[key] += count
        else:
            self.by_source[key] = count
            self._unlogged.append(key)
        self.flush(now_ns)

    def flush(self, now_ns: int) -> None:
        """Log the oldest source not logged yet, if a line is allowed at ``now_ns``."""
        if not self._unlogged or (self._last_log_ns is not None
                                  and now_ns - self._last_log_ns < NEW_SOURCE_LOG_EVERY_NS):
            return
        reason, source = key = self._unlogged.pop(0)
        self._last_log_ns = now_ns
        waiting = f"; {len(self._unlogged)} more new source(s) waiting" if self._unlogged else ""
        log.warning("refusing MAVLink from %s: %s (%d so far; counted in "
                    "VehicleStatus.refused_messages, logged once per source%s)",
                    describe(source), REASON_TEXT.get(reason, reason), self.by_source[key],
                    waiting)

    def summary(self, limit: int = 10) -> str:
        """The busiest refused sources, one line (for the exit log)."""
        top = sorted(self.by_source.items(), key=lambda kv: -kv[1])[:limit]
        return "; ".join(f"{n} {reason} from {describe(src)}" for (reason, src), n in top)


@dataclass(frozen=True)
class SourcePolicy:
    """What may lock the link before any HEARTBEAT has: the peer address the transport chose.

    ``expected_address`` is set when the transport itself names the autopilot: ``udpout:HOST:PORT``
    (we send there, so the autopilot answers from there) and ``tcp:`` (the connected peer). Then a
    HEARTBEAT from any other address is refused even when no link is up, which is what makes
    re-locking after a link loss safe on those transports. ``udpin`` and serial have none: the
    first valid autopilot HEARTBEAT wins (see the README's "Source lock").
    """

    expected_address: Address = None

    def may_lock(self, address: Address) -> bool:
        return self.expected_address is None or address == self.expected_address
