"""Fetch the autopilot's events metadata over MAVLink: COMPONENT_METADATA, then MAVLink FTP.

The descriptions of an autopilot's EVENT messages (``autopilot_events.py``) live on the autopilot,
matching its firmware. The component metadata protocol says where: MAV_CMD_REQUEST_MESSAGE for
COMPONENT_METADATA (#397) gives the URI of the *general* metadata file (``mftp://...``, usually
xz-compressed JSON), whose ``metadataTypes`` entry of type 4 (COMP_METADATA_TYPE_EVENTS) gives the
events file's URI; both are read with MAVLink FTP (FILE_TRANSFER_PROTOCOL #110): OpenFileRO,
ReadFile in 239-byte pieces until the size OpenFileRO reported, TerminateSession. On PX4 SITL the
two files are 364 B and 17 kB (about 75 round trips, well under a second on a local link; on a
57600-baud radio a few seconds, all in the background).

Pure: ``start``, ``on_*`` and ``tick`` return the messages to send; time comes in as monotonic
nanoseconds. A request unanswered for ``REPLY_TIMEOUT_NS`` is sent again (same sequence number, so
a late reply still matches), ``ATTEMPTS`` times in all, then the fetch fails with the reason.
"""

from __future__ import annotations

import json
import lzma
import struct
from dataclasses import dataclass

MAV_CMD_REQUEST_MESSAGE = 512
MSG_ID_COMPONENT_METADATA = 397
COMP_METADATA_TYPE_EVENTS = 4
FTP_DATA_MAX = 239  # FILE_TRANSFER_PROTOCOL.payload (251) less the 12-byte header
FTP_HEADER = struct.Struct("<HBBBBBBI")  # seq, session, opcode, size, req_opcode, burst, pad, offset
OP_TERMINATE, OP_OPEN_RO, OP_READ = 1, 4, 5
OP_ACK, OP_NAK = 128, 129
NAK_ERRORS = {0: "none", 1: "fail", 2: "errno", 3: "invalid data size", 4: "invalid session",
              5: "no sessions available", 6: "end of file", 7: "unknown command",
              8: "file exists", 9: "file protected", 10: "file not found"}
NAK_FILE_NOT_FOUND = 10
REPLY_TIMEOUT_NS = 500_000_000
ATTEMPTS = 6
MAX_FILE_BYTES = 4 * 1024 * 1024  # a metadata file larger than this is not one
MAX_UNPACKED_BYTES = 32 * 1024 * 1024  # PX4's events: 17 kB packed, 0.3 MB unpacked
XZ_MAGIC = b"\xfd7zXZ\x00"


@dataclass(frozen=True)
class SendRequestMessage:
    """MAV_CMD_REQUEST_MESSAGE (param1 = message id) as a COMMAND_LONG."""

    target_system: int
    target_component: int
    message_id: int


@dataclass(frozen=True)
class SendFileTransfer:
    """FILE_TRANSFER_PROTOCOL with this payload (header + data, at most 251 bytes)."""

    target_system: int
    target_component: int
    payload: bytes


def ftp_path(uri: str) -> tuple[int | None, str]:
    """``mftp://[;comp=N]path`` -> (component to ask or None, path); ValueError otherwise."""
    if not uri.startswith("mftp://"):
        raise ValueError(f"not a MAVLink FTP URI (mftp://...): {uri!r}")
    rest = uri[len("mftp://"):]
    component = None
    if rest.startswith("[;comp="):
        end = rest.find("]")
        if end < 0:
            raise ValueError(f"unterminated [;comp=N] in {uri!r}")
        text = rest[len("[;comp="):end]
        component = int(text) if text.isdigit() else -1
        if not 1 <= component <= 255:
            raise ValueError(f"component {text!r} in {uri!r} is not a MAVLink component id (1..255)")
        rest = rest[end + 1:]
    if not rest:
        raise ValueError(f"no path in {uri!r}")
    if len(rest.encode("utf-8")) > FTP_DATA_MAX:
        # OpenFileRO carries the path in one FTP payload; a longer one cannot be asked for.
        raise ValueError(f"path of {len(rest.encode('utf-8'))} bytes in {uri[:80]!r}...: MAVLink FTP "
                         f"takes at most {FTP_DATA_MAX}")
    return component, rest


def unpack_file(data: bytes) -> bytes:
    """A metadata file's content: xz-decompressed when it is xz (LZMAError when that is not
    readable or would exceed ``MAX_UNPACKED_BYTES``)."""
    if not data.startswith(XZ_MAGIC):
        return data
    unpacker = lzma.LZMADecompressor()
    out = unpacker.decompress(data, max_length=MAX_UNPACKED_BYTES)
    if not unpacker.eof:
        raise lzma.LZMAError(f"truncated, or larger than {MAX_UNPACKED_BYTES} bytes unpacked")
    return out


def events_uri(general: bytes) -> str:
    """The events metadata URI in a general metadata file; ValueError if it has none."""
    try:
        doc = json.loads(unpack_file(general))
        for entry in doc.get("metadataTypes", []):
            if int(entry.get("type", -1)) == COMP_METADATA_TYPE_EVENTS and entry.get("uri"):
                return str(entry["uri"])
    except (lzma.LZMAError, ValueError, AttributeError, TypeError) as err:
        raise ValueError(f"general metadata unreadable: {err}") from None
    raise ValueError("the general metadata lists no events metadata (type 4)")


class FtpRead:
    """One file read with MAVLink FTP (pure): open, read piece by piece, terminate."""

    def __init__(self, path: str, seq: int) -> None:
        self.path = path
        self.seq = seq & 0xFFFF
        self.session = 0
        self.size: int | None = None
        self.data = bytearray()
        self.done = False
        self.error: str | None = None
        self.error_code: int | None = None  # the NAK's code, when a NAK ended the read
        self._pending: tuple[int, bytes] | None = None  # (opcode, the request as sent)

    def _request(self, opcode: int, offset: int = 0, data: bytes = b"", size: int = 0) -> bytes:
        self.seq = (self.seq + 1) & 0xFFFF
        payload = FTP_HEADER.pack(self.seq, self.session, opcode, size or len(data), 0, 0, 0,
                                  offset) + data
        self._pending = (opcode, payload)
        return payload

    def open(self) -> bytes:
        return self._request(OP_OPEN_RO, data=self.path.encode("utf-8"))

    def resend(self) -> bytes | None:
        return None if self._pending is None else self._pending[1]

    def on_reply(self, payload: bytes) -> bytes | None:
        """A FILE_TRANSFER_PROTOCOL reply; returns the next request (None: nothing to send, this
        reply was not for us, or the read ended: see ``done``/``error``)."""
        if len(payload) < FTP_HEADER.size or self._pending is None:
            return None
        seq, session, opcode, size, req_opcode, _, _, offset = FTP_HEADER.unpack_from(payload)
        sent_opcode = self._pending[0]
        if seq != (self.seq + 1) & 0xFFFF or req_opcode != sent_opcode:
            return None  # a late duplicate, or another client's exchange
        body = payload[FTP_HEADER.size:FTP_HEADER.size + size]
        if opcode == OP_NAK:
            code = body[0] if body else 1
            if sent_opcode == OP_TERMINATE:  # the data is read; a session already gone is fine
                self._pending = None
                self.done = True
                return None
            if sent_opcode == OP_READ and code == 6:  # EOF: the file ended before the size said
                return self._finish()
            self._pending = None
            self.error = f"{NAK_ERRORS.get(code, f'error {code}')} ({self._what(sent_opcode)})"
            self.error_code = code
            return None
        if opcode != OP_ACK:
            return None
        if sent_opcode == OP_OPEN_RO:
            if len(body) < 4:
                self._pending = None
                self.error = "OpenFileRO ACK without the file size"
                return None
            self.session = session
            self.size = struct.unpack_from("<I", body)[0]
            if self.size > MAX_FILE_BYTES:
                self._pending = None
                self.error = f"file of {self.size} bytes (more than {MAX_FILE_BYTES})"
                return None
        elif sent_opcode == OP_READ:
            if offset != len(self.data):
                return None
            self.data += body
        elif sent_opcode == OP_TERMINATE:
            self._pending = None
            self.done = True
            return None
        if self.size is not None and len(self.data) >= self.size:
            return self._finish()
        return self._request(OP_READ, offset=len(self.data), size=FTP_DATA_MAX)

    def _finish(self) -> bytes:
        return self._request(OP_TERMINATE)

    def _what(self, opcode: int) -> str:
        return {OP_OPEN_RO: f"opening {self.path}", OP_READ: f"reading {self.path} at "
                f"{len(self.data)}", OP_TERMINATE: "closing the session"}.get(opcode, str(opcode))


class MetadataFetch:
    """COMPONENT_METADATA -> general metadata -> events metadata, from one autopilot component."""

    def __init__(self, target_system: int, target_component: int) -> None:
        self.target_system = target_system
        self.target_component = target_component
        self.stage = "idle"  # idle, uri, general, events, done, failed
        self.error: str | None = None
        self.events_uri: str | None = None
        self.result: bytes | None = None  # the events metadata (decompressed)
        self.bytes_read = 0
        self.unsupported = False  # the autopilot said it has no component metadata
        self._read: FtpRead | None = None
        self._candidates: list[str] = []
        self._sent_ns = 0
        self._attempts = 0
        self._seq = 0

    @property
    def finished(self) -> bool:
        return self.stage in ("done", "failed")

    def start(self, now_ns: int) -> list[SendRequestMessage | SendFileTransfer]:
        self.stage = "uri"
        return self._sent(now_ns, SendRequestMessage(self.target_system, self.target_component,
                                                     MSG_ID_COMPONENT_METADATA), fresh=True)

    def _sent(self, now_ns: int, out: SendRequestMessage | SendFileTransfer | None,
              fresh: bool) -> list[SendRequestMessage | SendFileTransfer]:
        if out is None:
            return []
        self._sent_ns = now_ns
        self._attempts = 1 if fresh else self._attempts + 1
        self._last = out
        return [out]

    def _ftp(self, payload: bytes | None) -> SendFileTransfer | None:
        if payload is None:
            return None
        return SendFileTransfer(self.target_system, self.target_component, payload)

    def _fail(self, why: str) -> list[SendRequestMessage | SendFileTransfer]:
        self.stage = "failed"
        self.error = why
        return []

    def on_request_ack(self, result: int) -> list[SendRequestMessage | SendFileTransfer]:
        """The COMMAND_ACK of our MAV_CMD_REQUEST_MESSAGE: anything but ACCEPTED (0) or
        IN_PROGRESS (5) means no COMPONENT_METADATA is coming."""
        if self.stage == "uri" and result not in (0, 5):
            self.unsupported = True
            return self._fail(f"the autopilot answered MAV_CMD_REQUEST_MESSAGE(COMPONENT_METADATA) "
                              f"with result {result}")
        return []

    def on_component_metadata(self, uri: str, now_ns: int,
                              ) -> list[SendRequestMessage | SendFileTransfer]:
        if self.stage != "uri":
            return []
        self.stage = "general"
        return self._open(uri, now_ns)

    def _open(self, uri: str, now_ns: int) -> list[SendRequestMessage | SendFileTransfer]:
        try:
            component, path = ftp_path(uri)
        except ValueError as err:
            return self._fail(str(err))
        if component is not None:
            self.target_component = component
        # PX4 names files relative to its FTP root ("mftp://etc/extras/..."); other servers may
        # want an absolute path: try the path as given, then with a leading "/".
        self._candidates = [path, "/" + path] if not path.startswith("/") else [path]
        return self._open_next(now_ns)

    def _open_next(self, now_ns: int) -> list[SendRequestMessage | SendFileTransfer]:
        path = self._candidates.pop(0)
        self._read = FtpRead(path, self._seq)
        return self._sent(now_ns, self._ftp(self._read.open()), fresh=True)

    def on_ftp(self, payload: bytes, now_ns: int) -> list[SendRequestMessage | SendFileTransfer]:
        read = self._read
        if read is None or self.finished:
            return []
        out = self._sent(now_ns, self._ftp(read.on_reply(payload)), fresh=True)
        self._seq = read.seq
        if read.error is not None:
            if read.error_code == NAK_FILE_NOT_FOUND and self._candidates:
                return self._open_next(now_ns)
            return self._fail(f"MAVLink FTP: {read.error}")
        if not read.done:
            return out
        self.bytes_read += len(read.data)
        self._read = None
        try:
            content = unpack_file(bytes(read.data))
        except lzma.LZMAError as err:
            return self._fail(f"{read.path}: not readable xz: {err}")
        if self.stage == "general":
            try:
                self.events_uri = events_uri(content)
            except ValueError as err:
                return self._fail(str(err))
            self.stage = "events"
            return self._open(self.events_uri, now_ns)
        self.result = content
        self.stage = "done"
        return []

    def tick(self, now_ns: int) -> list[SendRequestMessage | SendFileTransfer]:
        """Resend what went unanswered; fail after ``ATTEMPTS``."""
        if self.finished or self.stage == "idle" or now_ns - self._sent_ns < REPLY_TIMEOUT_NS:
            return []
        if self._attempts >= ATTEMPTS:
            what = ("no COMPONENT_METADATA in reply to MAV_CMD_REQUEST_MESSAGE"
                    if self.stage == "uri" else f"no MAVLink FTP reply ({self.stage} metadata)")
            return self._fail(f"{what} after {ATTEMPTS} attempts")
        again: SendRequestMessage | SendFileTransfer | None = self._last
        if self._read is not None:
            again = self._ftp(self._read.resend())
            if again is None:  # the read holds no request (a reply it could not answer): give up
                return self._fail(f"MAVLink FTP: nothing to send again ({self.stage} metadata)")
        return self._sent(now_ns, again, fresh=False)

    def next_due_ns(self) -> int | None:
        return None if self.finished or self.stage == "idle" else self._sent_ns + REPLY_TIMEOUT_NS
