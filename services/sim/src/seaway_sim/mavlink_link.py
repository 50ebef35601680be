"""The simulated autopilot's MAVLink 2 link: one UDP socket, listening, answering the last peer.

Like PX4's SITL API link, the sim listens (``udpin:HOST:PORT``, default ``udpin:127.0.0.1:14580``)
and sends everything to the address of the last datagram that carried at least one valid MAVLink
message; a datagram of garbage never moves the link. Nothing is sent before a peer is heard.

Each datagram is parsed on its own (a fresh parser per datagram), so garbage or a truncated frame in
one datagram can never swallow the start of the next. Bad frames (prefix, CRC, length), frames of a
message id outside the common dialect (which cannot be CRC-checked) and trailing partial frames are
dropped; each datagram holding any is counted once and logged (at most once a second), and the sim
goes on. Valid frames in the same datagram are still used.
"""

from __future__ import annotations

import logging
import socket
import time
from collections import Counter
from collections.abc import Iterable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

log = logging.getLogger("seaway_sim.mavlink")

DEFAULT_ENDPOINT = "udpin:127.0.0.1:14580"
MAX_DATAGRAM = 65535
_WARN_INTERVAL_S = 1.0


def parse_endpoint(text: str) -> tuple[str, int]:
    """``udpin:HOST:PORT`` -> (host, port); port 0 picks a free one. Raises ValueError."""
    scheme, _, rest = text.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme != "udpin" or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"MAVLink endpoint {text!r}: expected udpin:HOST:PORT, "
                         f"e.g. {DEFAULT_ENDPOINT}")
    return host, int(port)


class MavlinkLink:
    """UDP socket + MAVLink 2 framing for one simulated autopilot (sysid, compid)."""

    def __init__(self, endpoint: str, sysid: int, compid: int) -> None:
        host, port = parse_endpoint(endpoint)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.address: tuple[str, int] = self.sock.getsockname()
        self._tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.peer: tuple[str, int] | None = None
        self.counters: Counter[str] = Counter()
        self._last_warn = 0.0

    @property
    def garbage(self) -> int:
        """Datagrams that held garbage so far (SYS_STATUS.errors_comm reports it)."""
        return self.counters["garbage_datagrams"]

    def receive(self, timeout_s: float) -> list[Any]:
        """Wait up to ``timeout_s`` for a datagram, then decode every one waiting."""
        self.sock.settimeout(timeout_s)
        out: list[Any] = []
        try:
            data, addr = self.sock.recvfrom(MAX_DATAGRAM)
        except (TimeoutError, BlockingIOError, ConnectionRefusedError):
            # ConnectionRefused: an ICMP "port unreachable" for an earlier send to a vanished peer.
            return out
        self.sock.setblocking(False)
        while True:
            out.extend(self._decode(data, addr))
            try:
                data, addr = self.sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError, ConnectionRefusedError):
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
        if good:
            if addr != self.peer:
                log.info("MAVLink peer is now %s:%d", *addr)
            self.peer = addr
            self.counters["rx_messages"] += len(good)
        return good

    def _warn(self, text: str) -> None:
        now = time.monotonic()
        if now - self._last_warn >= _WARN_INTERVAL_S:
            self._last_warn = now
            log.warning("%s (dropped so far: %d)", text, self.garbage)

    def send(self, msgs: Iterable[Any]) -> None:
        """Send each message to the peer (a no-op until one has been heard)."""
        if self.peer is None:
            return
        for m in msgs:
            try:
                self.sock.sendto(m.pack(self._tx), self.peer)
                self.counters["tx_messages"] += 1
            except OSError as err:  # e.g. ICMP port unreachable reported on a later send
                self.counters["tx_errors"] += 1
                self._warn(f"send to {self.peer} failed: {err}")

    def close(self) -> None:
        self.sock.close()
