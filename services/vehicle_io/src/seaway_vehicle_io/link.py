"""The MAVLink transport: one pymavlink connection, opened from a URL, reopened when it breaks.

This is the only module that reads or writes MAVLink bytes. It turns the core's ``Send*`` outputs
into packets and hands back every decoded message, of every type (there is no
``recv_match(type=...)`` anywhere: the core sees all traffic, which is how it counts rates and
garbage).

URLs are pymavlink's: ``udpin:HOST:PORT`` (listen; we reply to whoever sent to us),
``udpout:HOST:PORT`` (we send first; the autopilot replies to our source port), ``tcp:HOST:PORT``,
or a serial device path with ``baud``.
"""

from __future__ import annotations

import importlib.util
import logging
import select
import socket
import time
from typing import Any

from seaway_vehicle_io.core import (
    Output,
    SendCommandLong,
    SendHeartbeat,
    SendManualControl,
    SendParamRequestRead,
)
from seaway_vehicle_io.mav import DIALECT, mavlink, mavutil

log = logging.getLogger("seaway.vehicle_io.link")

SERIAL_PREFIXES = ("/dev/", "COM")
SUPPORTED_PREFIXES = ("udpin:", "udpout:", "tcp:", *SERIAL_PREFIXES)


class LinkClosedError(ConnectionError):
    """The transport ended (TCP EOF, serial unplugged); the loop reopens it."""


def check_url(url: str) -> str:
    """Refuse URLs we do not support, with a message that lists the ones we do.

    A serial URL needs pyserial, which pymavlink imports only when it opens the port: checked here
    so that a missing package fails at start-up rather than as an endless reopen loop.
    """
    if not url.startswith(SUPPORTED_PREFIXES):
        raise ValueError(f"unsupported MAVLink URL {url!r}: use udpin:HOST:PORT, udpout:HOST:PORT, "
                         "tcp:HOST:PORT or a serial device (/dev/ttyX)")
    if url.startswith(SERIAL_PREFIXES) and importlib.util.find_spec("serial") is None:
        raise ValueError(f"MAVLink URL {url!r} is a serial port, which needs the pyserial package; "
                         "it is not installed (pip install 'pyserial>=3.5')")
    return url


class MavlinkLink:
    """One open connection. Not thread-safe: the service serialises every call with its lock,
    except ``wait_readable``, which only selects on the descriptor."""

    def __init__(self, url: str, source_system: int, source_component: int, baud: int = 57600,
                 udp_client_timeout_s: float = 3.0) -> None:
        self.url = check_url(url)
        self.conn: Any = mavutil.mavlink_connection(
            url, baud=baud, source_system=source_system, source_component=source_component,
            dialect=DIALECT, autoreconnect=False, retries=0, udp_timeout=udp_client_timeout_s,
        )
        # The heartbeat's `mavlink_version` and our framing are MAVLink 2 from the first packet.
        self.conn.WIRE_PROTOCOL_VERSION = "2.0"
        self.is_tcp = isinstance(self.conn, mavutil.mavtcp)
        self.is_udp = isinstance(self.conn, mavutil.mavudp)
        self.sent = 0
        self.truncated_datagrams = 0

    def fileno(self) -> int:
        return self.conn.fd if self.conn.fd is not None else self.conn.port.fileno()

    def wait_readable(self, timeout_s: float) -> bool:
        try:
            ready, _, _ = select.select([self.fileno()], [], [], timeout_s)
        except (OSError, ValueError) as err:  # closed under us
            raise LinkClosedError(f"{self.url}: {err}") from err
        return bool(ready)

    def read_available(self) -> list[Any]:
        """Every message decodable from what has arrived, without blocking."""
        if self.is_udp:
            return self._read_datagrams()
        if self.is_tcp:
            try:
                peek = self.conn.port.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT)
            except BlockingIOError:
                return []
            except OSError as err:
                raise LinkClosedError(f"{self.url}: {err}") from err
            if peek == b"":
                raise LinkClosedError(f"{self.url}: connection closed by the autopilot")
        out = []
        try:
            while True:
                msg = self.conn.recv_msg()
                if msg is None:
                    break
                out.append(msg)
        except OSError as err:
            raise LinkClosedError(f"{self.url}: {err}") from err
        except Exception as err:  # pyserial's SerialException is not an OSError
            if type(err).__name__ == "SerialException":
                raise LinkClosedError(f"{self.url}: {err}") from err
            raise
        return out

    def _read_datagrams(self) -> list[Any]:
        """UDP: parse each datagram on its own.

        pymavlink's own UDP path keeps one parser buffer across datagrams, so a datagram of
        garbage that happens to contain a frame start (0xFD) followed by a large length byte makes
        the parser wait for that many bytes and swallow the *next* datagrams' real messages
        (heartbeats included). A datagram is a unit: whatever partial frame is left at its end is
        reported as bad data and discarded, and the next datagram starts clean.
        """
        conn, mav = self.conn, self.conn.mav
        out: list[Any] = []
        while True:
            try:
                data, addr = conn.port.recvfrom(mavutil.UDP_MAX_PACKET_LEN)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionRefusedError:
                continue  # ICMP port unreachable for an earlier send (autopilot not up): harmless
            except OSError as err:
                raise LinkClosedError(f"{self.url}: {err}") from err
            if conn.udp_server:  # udpin: reply to whoever talks to us (pymavlink's bookkeeping)
                conn.clients.add(addr)
                conn.clients_last_alive[addr] = time.time()
            msgs = mav.parse_buffer(data) or []
            leftover = mav.buf_len()
            if leftover:
                self.truncated_datagrams += 1
                bad = bytes(mav.buf[mav.buf_index:])
                mav.buf = bytearray()
                mav.buf_index = 0
                mav.expected_length = mavlink.HEADER_LEN_V1 + 2
                msgs.append(mavlink.MAVLink_bad_data(
                    bytearray(bad), f"{leftover} bytes of an incomplete frame at datagram end"))
            for m in msgs:
                conn.post_message(m)  # keeps pymavlink's per-system state coherent
            out.extend(msgs)
        return out

    def send(self, out: Output) -> None:
        try:
            self._send(out)
        except OSError as err:  # TCP reset, serial gone (UDP errors are swallowed by pymavlink)
            raise LinkClosedError(f"{self.url}: {err}") from err
        self.sent += 1

    def _send(self, out: Output) -> None:
        mav = self.conn.mav
        if isinstance(out, SendManualControl):
            a = out.axes
            mav.manual_control_send(out.target_system, a.x, a.y, a.z, a.r, 0)
        elif isinstance(out, SendHeartbeat):
            # GCS type: ArduPilot counts heartbeats from SYSID_MYGCS for its GCS failsafe, and PX4's
            # Commander tracks MAV_TYPE_GCS heartbeats for its datalink-loss check (NAV_DLL_ACT).
            mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                               mavlink.MAV_STATE_ACTIVE)
        elif isinstance(out, SendCommandLong):
            mav.command_long_send(out.target_system, out.target_component, out.command,
                                  out.confirmation, *out.params)
        elif isinstance(out, SendParamRequestRead):
            mav.param_request_read_send(out.target_system, out.target_component,
                                        out.param_id.encode("ascii"), -1)
        else:
            raise TypeError(f"not a MAVLink output: {out!r}")

    def close(self) -> None:
        try:
            self.conn.close()
        except OSError:
            log.debug("close failed", exc_info=True)
