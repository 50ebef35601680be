"""The simulated autopilot's MAVLink 2 link: one UDP socket, listening, answering the last peer.

Like PX4's SITL API link, the sim listens (``udpin:HOST:PORT``, default ``udpin:127.0.0.1:14580``)
and sends everything to the address of the last datagram that carried at least one valid MAVLink
message; a datagram of garbage never moves the link. Nothing is sent before a peer is heard.

Each datagram is parsed on its own (a fresh parser per datagram), so garbage or a truncated frame in
one datagram can never swallow the start of the next. Bad frames (prefix, CRC, length), frames of a
message id outside the common dialect (which cannot be CRC-checked) and trailing partial frames are
dropped; each datagram holding any is counted once and logged (at most once a second), and the sim
goes on. Valid frames in the same datagram are still used.

Signing (``signing_key``, ``--signing-key-file``), as PX4 does once it has a key: every message the
sim sends is signed, and an incoming message must carry a valid signature with a newer timestamp
than its stream's last (``seaway.mavlink.signing``); unsigned, wrongly signed and replayed
messages are refused before the autopilot sees them, counted (``refused_<reason>``) and logged once
per source. Like PX4, a few messages are accepted unsigned (HEARTBEAT, RADIO_STATUS, ADSB_VEHICLE,
COLLISION; none of them commands anything here). Only a signed message moves the peer, so nobody
without the key can redirect the sim's telemetry to themselves.
"""

from __future__ import annotations

import logging
import socket
import time
from collections import Counter
from collections.abc import Iterable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink
from seaway.mavlink.signing import (
    ACCEPTED,
    UNSIGNED,
    SignatureVerifier,
    keep_up,
    signing_timestamp,
)
from seaway.runtime.ratelog import RateLimitedLog

log = logging.getLogger("seaway_sim.mavlink")

DEFAULT_ENDPOINT = "udpin:127.0.0.1:14580"
MAX_DATAGRAM = 65535
_WARN_INTERVAL_S = 1.0
SIGNING_LINK_ID = 0  # the sim has one link
# What PX4 accepts unsigned with signing on (PX4 docs, "Unsigned Message Allowlist").
UNSIGNED_ALLOWLIST = frozenset({
    mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_RADIO_STATUS,
    mavlink.MAVLINK_MSG_ID_ADSB_VEHICLE, mavlink.MAVLINK_MSG_ID_COLLISION,
})
MAX_REFUSED_SOURCES = 64  # per-source refusal counters kept (a flood of new ports cannot grow it)
# Datagrams decoded per receive() at most: under a flood the caller still gets what arrived (the
# peer's MANUAL_CONTROL among it) every few milliseconds instead of once the flood stops.
MAX_DATAGRAMS_PER_RECEIVE = 256


def parse_endpoint(text: str) -> tuple[str, int]:
    """``udpin:HOST:PORT`` -> (host, port); port 0 picks a free one. Raises ValueError."""
    scheme, _, rest = text.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme != "udpin" or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"MAVLink endpoint {text!r}: expected udpin:HOST:PORT, "
                         f"e.g. {DEFAULT_ENDPOINT}")
    return host, int(port)


class MavlinkLink:
    """UDP socket + MAVLink 2 framing for one simulated autopilot (sysid, compid), signing with
    ``signing_key`` if one is given."""

    def __init__(self, endpoint: str, sysid: int, compid: int,
                 signing_key: bytes | None = None) -> None:
        host, port = parse_endpoint(endpoint)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.address: tuple[str, int] = self.sock.getsockname()
        self._tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.verifier = SignatureVerifier(signing_key) if signing_key is not None else None
        if signing_key is not None:
            sig = self._tx.signing
            sig.secret_key, sig.sign_outgoing, sig.link_id = signing_key, True, SIGNING_LINK_ID
            sig.timestamp = signing_timestamp(time.time_ns())
        self.peer: tuple[str, int] | None = None
        self.counters: Counter[str] = Counter()
        # (reason, address, sysid, compid) -> messages refused; each new key logged once.
        self.refused: dict[tuple[str, tuple[str, int], int, int], int] = {}
        self._unlogged: list[tuple[tuple[str, tuple[str, int], int, int], str]] = []
        self._warnings = RateLimitedLog(log, every_s=_WARN_INTERVAL_S)
        self._last_refusal_log: float | None = None

    @property
    def signing(self) -> bool:
        return self.verifier is not None

    @property
    def garbage(self) -> int:
        """Datagrams that held garbage so far (SYS_STATUS.errors_comm reports it)."""
        return self.counters["garbage_datagrams"]

    def receive(self, timeout_s: float) -> list[Any]:
        """Wait up to ``timeout_s`` for a datagram, then decode the ones waiting (at most
        ``MAX_DATAGRAMS_PER_RECEIVE``)."""
        self.sock.settimeout(timeout_s)
        out: list[Any] = []
        try:
            data, addr = self.sock.recvfrom(MAX_DATAGRAM)
        except (TimeoutError, BlockingIOError, ConnectionRefusedError):
            # ConnectionRefused: an ICMP "port unreachable" for an earlier send to a vanished peer.
            return out
        self.sock.setblocking(False)
        for _ in range(MAX_DATAGRAMS_PER_RECEIVE - 1):
            out.extend(self._decode(data, addr))
            try:
                data, addr = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError, ConnectionRefusedError):
                return out
        out.extend(self._decode(data, addr))
        return out

    def _decode(self, data: bytes, addr: tuple[str, int]) -> list[Any]:
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True  # bad frames come back as BAD_DATA instead of raising
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception as err:  # pymavlink raises on some malformed payloads even when robust
            self.counters["garbage_datagrams"] += 1
            self._warn(f"garbage from {addr}: undecodable datagram ({len(data)} bytes): {err}")
            return []
        # Frames of an id outside the dialect cannot be CRC-checked (no CRC_EXTRA): garbage too.
        good, dropped = [], []
        for m in msgs:
            unusable = m.get_type() == "BAD_DATA" or isinstance(m, mavlink.MAVLink_unknown)
            (dropped if unusable else good).append(m)
        bad = len(dropped)
        trailing = parser.buf_len()
        if bad or trailing:
            # Good frames in the same datagram still count: garbage costs only itself.
            self.counters["garbage_datagrams"] += 1
            self.counters["bad_frames"] += bad
            self.counters["truncated_frames"] += 1 if trailing else 0
            reasons = sorted({getattr(m, "reason", None) or m.get_type() for m in dropped})
            self._warn(f"garbage from {addr}: {bad} bad frame(s) {reasons}, "
                       f"{trailing} trailing byte(s) of an incomplete frame")
        moves_peer = bool(good)
        if self.verifier is not None and good:
            good, moves_peer = self._authenticate(good, addr)
        if moves_peer:
            if addr != self.peer:
                log.info("MAVLink peer is now %s:%d", *addr)
            self.peer = addr
        self.counters["rx_messages"] += len(good)
        return good

    def _authenticate(self, msgs: list[Any], addr: tuple[str, int]) -> tuple[list[Any], bool]:
        """The messages that pass the signature check (or are allowlisted unsigned), and whether
        any of them was signed (only those may move the peer)."""
        assert self.verifier is not None
        now_ts = signing_timestamp(time.time_ns())
        out, signed = [], False
        for m in msgs:
            verdict = self.verifier.check(m.get_msgbuf(), now_ts)
            if verdict == ACCEPTED:
                out.append(m)
                signed = True
            elif verdict == UNSIGNED and m.get_msgId() in UNSIGNED_ALLOWLIST:
                self.counters["unsigned_allowlisted"] += 1
                out.append(m)
            else:
                self._refuse(verdict, addr, m)
        return out, signed

    def _refuse(self, reason: str, addr: tuple[str, int], msg: Any) -> None:
        """Count a refused message; log each new (reason, source) once, at most one line a second
        (a source first seen meanwhile waits for a later refusal to be logged)."""
        self.counters[f"refused_{reason}"] += 1
        key = (reason, addr, msg.get_srcSystem(), msg.get_srcComponent())
        if key in self.refused:
            self.refused[key] += 1
        elif len(self.refused) < MAX_REFUSED_SOURCES:  # full: counted above only
            self.refused[key] = 1
            self._unlogged.append((key, msg.get_type()))
        now = time.monotonic()
        if not self._unlogged or (self._last_refusal_log is not None
                                  and now - self._last_refusal_log < _WARN_INTERVAL_S):
            return
        (reason, addr, sysid, compid), mtype = self._unlogged.pop(0)
        self._last_refusal_log = now
        log.warning("signing: refused %s %s from system %d component %d at %s:%d (logged once per "
                    "source%s; refused so far: %s)", reason.replace("_", " "), mtype, sysid, compid,
                    *addr, f", {len(self._unlogged)} more waiting" if self._unlogged else "",
                    self._refused_counts())

    def _refused_counts(self) -> dict[str, int]:
        return {k: v for k, v in self.counters.items() if k.startswith("refused_")}

    def _warn(self, text: str) -> None:
        self._warnings.warning("garbage", "%s (dropped so far: %d)", text, self.garbage)

    def send(self, msgs: Iterable[Any]) -> None:
        """Send each message to the peer (a no-op until one has been heard)."""
        if self.peer is None:
            return
        if self.verifier is not None:  # a restarted vehicle_io takes our stream only near its clock
            keep_up(self._tx.signing, time.time_ns())
        for m in msgs:
            try:
                self.sock.sendto(m.pack(self._tx), self.peer)
                self.counters["tx_messages"] += 1
            except OSError as err:  # e.g. ICMP port unreachable reported on a later send
                self.counters["tx_errors"] += 1
                self._warn(f"send to {self.peer} failed: {err}")

    def close(self) -> None:
        self.sock.close()
