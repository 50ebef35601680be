"""The MAVLink transport: one pymavlink connection, opened from a URL, reopened when it breaks.

This is the only module that reads or writes MAVLink bytes. It turns the core's ``Send*`` outputs
into packets and hands back every decoded message, of every type (there is no
``recv_match(type=...)`` anywhere: the core sees all traffic, which is how it counts rates and
garbage).

URLs are pymavlink's: ``udpin:HOST:PORT`` (listen; we reply to whoever sent to us),
``udpout:HOST:PORT`` (we send first; the autopilot replies to our source port), ``tcp:HOST:PORT``,
or a serial device path with ``baud``.

Every message comes with the peer address it arrived from (plain data for the core's source lock).
Once the core has locked to the autopilot (``LockPeer``), the autopilot's UDP datagrams get a
socket of their own: a second socket bound to the same local address and ``connect``-ed to the
autopilot, which the kernel prefers for that one source. A flood to our port then fills only the
first socket's buffer; the kernel never drops the autopilot's datagrams to make room for it, however
long the receive thread is kept off the CPU. What reaches the first socket from any other address
is refused *before parsing* and only tallied by the ids its header claims (a refusal costs about a
microsecond, parsing tens), so the refusals are counted for as much of a flood as the machine can
read. Each read takes at most ``MAX_DATAGRAMS_PER_READ`` from each socket, so a flood can never keep
the receive thread from handing what it has to the core.

Signing: our messages are packed by our own ``MAVLink`` object (``_tx``), which signs them when a
``SigningClock`` is given (``signing.py``: the key, link id and a timestamp that never goes back).
pymavlink's ``conn.mav`` only parses, without a key: signatures are checked by the core
(``seaway.mavlink.signing``), not by pymavlink's parser, whose check can be poisoned.
"""

from __future__ import annotations

import importlib.util
import ipaddress
import logging
import select
import socket
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from seaway.mavlink.wire import frame_ids

from seaway_vehicle_io.authority import Address, Source, SourcePolicy
from seaway_vehicle_io.component_metadata import (
    MAV_CMD_REQUEST_MESSAGE,
    SendFileTransfer,
    SendRequestMessage,
)
from seaway_vehicle_io.core import (
    Output,
    SendCommandLong,
    SendHeartbeat,
    SendManualControl,
    SendParamRequestRead,
    SendRequestDataStream,
)
from seaway_vehicle_io.dialect import events as events_dialect
from seaway_vehicle_io.events_channel import SendRequestEvent
from seaway_vehicle_io.fence_sync import SendParamRead, SendParamSet
from seaway_vehicle_io.mav import DIALECT, mavlink, mavutil
from seaway_vehicle_io.mission_transfer import (
    SendMissionAck,
    SendMissionCount,
    SendMissionItemInt,
    SendMissionRequestInt,
    SendMissionRequestList,
)
from seaway_vehicle_io.signing import SigningClock

FTP_PAYLOAD_LEN = 251  # FILE_TRANSFER_PROTOCOL.payload

log = logging.getLogger("seaway.vehicle_io.link")

SERIAL_PREFIXES = ("/dev/", "COM")
SUPPORTED_PREFIXES = ("udpin:", "udpout:", "tcp:", *SERIAL_PREFIXES)

LOOPBACK, ANY_INTERFACE = "127.0.0.1", "0.0.0.0"
MAX_DATAGRAMS_PER_READ = 256  # UDP: at most this many datagrams per read from each socket
MAX_MESSAGES_PER_READ = 256  # TCP / serial: at most this many messages per read
# Asked of the kernel for UDP (it caps this at net.core.rmem_max): room for a few milliseconds of
# a flood while the receive thread is descheduled, so the autopilot's datagrams are not dropped.
RECEIVE_BUFFER_BYTES = 1 << 20


class LinkClosedError(ConnectionError):
    """The transport ended (TCP EOF, serial unplugged); the loop reopens it."""


@dataclass
class Received:
    """One bounded read: the messages with the address each came from, and what was refused
    unparsed (datagrams from an address other than the locked peer) by claimed source."""

    messages: list[tuple[Any, Address]] = field(default_factory=list)
    refused: dict[Source, int] = field(default_factory=dict)


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
                 udp_client_timeout_s: float = 3.0, signing: SigningClock | None = None,
                 bind_host: str | None = None) -> None:
        self.url = check_url(url)
        self.conn: Any = mavutil.mavlink_connection(
            url, baud=baud, source_system=source_system, source_component=source_component,
            dialect=DIALECT, autoreconnect=False, retries=0, udp_timeout=udp_client_timeout_s,
        )
        # The heartbeat's `mavlink_version` and our framing are MAVLink 2 from the first packet.
        self.conn.WIRE_PROTOCOL_VERSION = "2.0"
        self.is_tcp = isinstance(self.conn, mavutil.mavtcp)
        self.is_udp = isinstance(self.conn, mavutil.mavudp)
        self._tx = mavlink.MAVLink(self.conn, srcSystem=source_system, srcComponent=source_component)
        self.clock = signing
        self.signing = signing is not None
        if signing is not None:
            signing.attach(self._tx)
        self.peer: Address = None  # UDP: the locked autopilot's address; None hears everyone
        # UDP: the socket connected to ``peer`` and the address it is connected to. Opened and
        # closed only by the receive thread (``wait_readable``), never under its select.
        self._peer_sock: socket.socket | None = None
        self._peer_sock_address: Address = None
        self.stream_address: Address = None  # TCP: the connected peer; serial: None
        if self.is_tcp:
            self.stream_address = _address(self.conn.port.getpeername())
        if self.is_udp:
            try:
                self.conn.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
            except OSError:
                log.debug("SO_RCVBUF not set", exc_info=True)
            if self.conn.port.getsockname()[1] == 0:
                # udpout: the port the first send would pick, picked now so the log can name it,
                # on no more interfaces than the autopilot needs (``udpout_bind_host``). Shared
                # with the autopilot's own socket (``_sync_peer_socket``), and only with sockets of
                # this user (SO_REUSEPORT; udpin's pymavlink socket has SO_REUSEADDR already).
                self.conn.port.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
                self.conn.port.bind((bind_host or udpout_bind_host(self._expected_address()), 0))
        self.policy = SourcePolicy(self._expected_address())
        self.sent = 0
        self.truncated_datagrams = 0

    def _expected_address(self) -> Address:
        """Where the autopilot must be, if the URL says: udpout's destination, TCP's peer."""
        if self.is_tcp:
            return self.stream_address
        if self.is_udp and not self.conn.udp_server:
            host, port = self.conn.destination_addr
            try:
                ip = socket.gethostbyname(host)
            except OSError:
                return None
            # A wildcard or broadcast destination answers from an address we cannot predict.
            return None if ip in ("0.0.0.0", "255.255.255.255") else (ip, int(port))
        return None

    def local_address(self) -> str:
        """Our end of the link (host:port) for the log; the device for serial."""
        if self.is_udp or self.is_tcp:
            host, port = self.conn.port.getsockname()[:2]
            return f"{host}:{port}"
        return self.url

    def lock_peer(self, address: Address) -> None:
        """Refuse UDP datagrams from anywhere but ``address`` unparsed (None: hear everyone again).
        Listening (udpin), answer only the autopilot from now on, not every address ever heard."""
        if not self.is_udp:
            return
        self.peer = address
        if address is not None and self.conn.udp_server:
            # Rebound, not mutated: pymavlink's write iterates these on another thread.
            self.conn.clients_last_alive = {address: time.time()}
            self.conn.clients = {address}

    def fileno(self) -> int:
        return self.conn.fd if self.conn.fd is not None else self.conn.port.fileno()

    @property
    def peer_socket_open(self) -> bool:
        """The locked autopilot's datagrams arrive on a socket of their own (UDP, once locked)."""
        return self._peer_sock is not None

    def wait_readable(self, timeout_s: float) -> bool:
        """Wait until something can be read (receive thread only)."""
        if self.is_udp:
            self._sync_peer_socket()
        fds = [self.fileno()]
        if self._peer_sock is not None:
            fds.append(self._peer_sock.fileno())
        try:
            ready, _, _ = select.select(fds, [], [], timeout_s)
        except (OSError, ValueError) as err:  # closed under us
            raise LinkClosedError(f"{self.url}: {err}") from err
        return bool(ready)

    def _sync_peer_socket(self) -> None:
        """Give the locked peer its own connected socket, or close it once the lock is released.

        The kernel delivers a datagram to the bound socket that matches it best, and a connected
        socket matches its one source better than the unconnected one. Should the socket not open
        (a kernel without SO_REUSEPORT, say), the peer's datagrams keep sharing the first socket:
        correct, but a flood can then crowd them out of its buffer, which the warning says.
        """
        want = self.peer
        if want == self._peer_sock_address:
            return
        if self._peer_sock is not None:
            self._peer_sock.close()
            self._peer_sock, self._peer_sock_address = None, None
        if want is None:
            return
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            sock.bind(self.conn.port.getsockname())
            sock.connect(want)
            sock.setblocking(False)
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
            except OSError:
                log.debug("SO_RCVBUF not set", exc_info=True)
        except OSError as err:
            sock.close()
            self._peer_sock_address = want  # tried once per lock, not at every wait
            log.warning("the autopilot at %s:%d shares the socket with every other sender (%s): a "
                        "flood to %s can crowd its datagrams out", want[0], want[1], err,
                        self.local_address())
            return
        self._peer_sock, self._peer_sock_address = sock, want

    def read_available(self) -> Received:
        """What has arrived, decoded, without blocking and bounded per call (see the module)."""
        if self.is_udp:
            return self._read_datagrams()
        return self._read_stream()

    def _read_stream(self) -> Received:
        """TCP or serial: one peer, so nothing to refuse by address."""
        if self.is_tcp:
            try:
                peek = self.conn.port.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT)
            except BlockingIOError:
                return []
            except OSError as err:
                raise LinkClosedError(f"{self.url}: {err}") from err
            if peek == b"":
                raise LinkClosedError(f"{self.url}: connection closed by the autopilot")
        got = Received()
        try:
            for _ in range(MAX_MESSAGES_PER_READ):
                msg = self.conn.recv_msg()
                if msg is None:
                    return got
                got.messages.append((msg, self.stream_address))
        except OSError as err:
            raise LinkClosedError(f"{self.url}: {err}") from err
        except Exception as err:  # pyserial's SerialException is not an OSError
            if type(err).__name__ == "SerialException":
                raise LinkClosedError(f"{self.url}: {err}") from err
            raise
        return got

    def _read_datagrams(self) -> Received:
        """UDP: parse each datagram on its own.

        pymavlink's own UDP path keeps one parser buffer across datagrams, so a datagram of
        garbage that happens to contain a frame start (0xFD) followed by a large length byte makes
        the parser wait for that many bytes and swallow the *next* datagrams' real messages
        (heartbeats included). A datagram is a unit: whatever partial frame is left at its end is
        reported as bad data and discarded, and the next datagram starts clean.

        At most ``MAX_DATAGRAMS_PER_READ`` datagrams from each socket; from a locked peer's other
        addresses they are tallied by claimed source and not parsed. The shared socket is read
        first: until the peer's own socket opened, its datagrams arrived there, and they are older.
        """
        got = Received()
        peer = self.peer
        for data, addr in self._recv_some(self.conn.port):
            if peer is not None and addr != peer:
                source = (*frame_ids(data), addr)
                got.refused[source] = got.refused.get(source, 0) + 1
                continue
            self._take_datagram(data, addr, got)
        if self._peer_sock is not None:
            for data, addr in self._recv_some(self._peer_sock):
                self._take_datagram(data, addr, got)
        return got

    def _recv_some(self, sock: socket.socket) -> Iterator[tuple[bytes, Address]]:
        """Up to ``MAX_DATAGRAMS_PER_READ`` datagrams waiting on ``sock``, without blocking. The
        address as ``recvfrom`` gives it (IPv4: (host, port)): this is a flood's hot path."""
        for _ in range(MAX_DATAGRAMS_PER_READ):
            try:
                data, addr = sock.recvfrom(mavutil.UDP_MAX_PACKET_LEN)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionRefusedError:
                continue  # ICMP port unreachable for an earlier send (autopilot not up): harmless
            except OSError as err:
                raise LinkClosedError(f"{self.url}: {err}") from err
            yield data, addr

    def _take_datagram(self, data: bytes, addr: Address, got: Received) -> None:
        """Parse one datagram from the autopilot (or from anyone, before the lock) into ``got``."""
        conn, mav = self.conn, self.conn.mav
        if conn.udp_server:  # udpin: reply to whoever talks to us (pymavlink's bookkeeping)
            if addr not in conn.clients:
                conn.clients = conn.clients | {addr}  # rebound: write() iterates it elsewhere
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
            got.messages.append((m, addr))

    def send(self, out: Output) -> None:
        try:
            self._send(out)
        except OSError as err:  # TCP reset, serial gone (UDP errors are swallowed by pymavlink)
            raise LinkClosedError(f"{self.url}: {err}") from err
        finally:
            if self.clock is not None:
                self.clock.note_sent(self._tx)
        self.sent += 1

    def _send(self, out: Output) -> None:
        mav = self._tx
        if self.clock is not None:  # a restarted autopilot takes our stream only near its clock
            self.clock.before_send(mav, time.time_ns(), time.monotonic_ns())
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
        elif isinstance(out, SendRequestDataStream):
            mav.request_data_stream_send(out.target_system, out.target_component, out.stream_id,
                                         out.rate_hz, 1)
        elif isinstance(out, SendRequestEvent):
            mav.send(events_dialect.MAVLink_request_event_message(
                out.target_system, out.target_component, out.first_sequence, out.last_sequence))
        elif isinstance(out, SendRequestMessage):
            mav.command_long_send(out.target_system, out.target_component, MAV_CMD_REQUEST_MESSAGE,
                                  0, float(out.message_id), 0, 0, 0, 0, 0, 0)
        elif isinstance(out, SendFileTransfer):
            mav.file_transfer_protocol_send(0, out.target_system, out.target_component,
                                            list(out.payload.ljust(FTP_PAYLOAD_LEN, b"\0")))
        elif isinstance(out, SendParamRequestRead | SendParamRead):
            mav.param_request_read_send(out.target_system, out.target_component,
                                        out.param_id.encode("ascii"), -1)
        elif isinstance(out, SendParamSet):
            mav.param_set_send(out.target_system, out.target_component,
                               out.param_id.encode("ascii"), out.value, out.param_type)
        elif isinstance(out, SendMissionCount):
            mav.mission_count_send(out.target_system, out.target_component, out.count,
                                   out.mission_type)
        elif isinstance(out, SendMissionItemInt):
            i = out.item
            mav.mission_item_int_send(out.target_system, out.target_component, out.seq, i.frame,
                                      i.command, 0, 1, i.param1, 0, 0, 0, i.lat_e7, i.lon_e7, i.z,
                                      out.mission_type)
        elif isinstance(out, SendMissionRequestList):
            mav.mission_request_list_send(out.target_system, out.target_component,
                                          out.mission_type)
        elif isinstance(out, SendMissionRequestInt):
            mav.mission_request_int_send(out.target_system, out.target_component, out.seq,
                                         out.mission_type)
        elif isinstance(out, SendMissionAck):
            mav.mission_ack_send(out.target_system, out.target_component, out.result,
                                 out.mission_type)
        else:
            raise TypeError(f"not a MAVLink output: {out!r}")

    def close(self) -> None:
        if self._peer_sock is not None:
            self._peer_sock.close()
        try:
            self.conn.close()
        except OSError:
            log.debug("close failed", exc_info=True)


def udpout_bind_host(autopilot: Address) -> str:
    """Where a udpout socket listens for the autopilot's answers, by default: loopback when the
    autopilot is on this machine (nothing elsewhere can then reach the socket), else every interface
    (the route to the autopilot picks one)."""
    if autopilot is not None and ipaddress.ip_address(autopilot[0]).is_loopback:
        return LOOPBACK
    return ANY_INTERFACE


def _address(sockaddr: Any) -> Address:
    """(host, port) of a socket address (IPv6 addresses carry two more fields)."""
    return (str(sockaddr[0]), int(sockaddr[1]))
