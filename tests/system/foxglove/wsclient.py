"""A minimal client of the Foxglove WebSocket protocol, for tests.

The protocol is ``foxglove.websocket.v1``; foxglove-sdk's server (0.30) accepts it only under its new
name ``foxglove.sdk.v1`` (the same messages; a client offering only the old name gets HTTP 400), so
this client offers both, the new one first, as Foxglove and Lichtblick (since its PR #819) do.

There is no Python client library of the protocol (``foxglove-websocket`` and ``foxglove-sdk`` are
servers only; the reference client is the JavaScript ``@foxglove/ws-protocol``), so this speaks the
documented protocol over the ``websockets`` library, as Foxglove's own client does:

* the server sends JSON text: ``serverInfo``, ``advertise`` (``channels``: ``id``, ``topic``,
  ``encoding``, ``schemaName``, ``schema``, ``schemaEncoding``), ``unadvertise``, ``status``;
* the client sends ``{"op": "subscribe", "subscriptions": [{"id", "channelId"}]}``;
* the server then sends binary Message Data: opcode ``0x01`` (1 byte), subscription id (uint32 LE),
  log time (uint64 LE, ns), the message's bytes.
"""

from __future__ import annotations

import base64
import functools
import json
import socket
import struct
from dataclasses import dataclass
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, json_format, message_factory
from websockets.sync.client import ClientConnection, connect

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
MESSAGE_DATA = 0x01
_HEADER = struct.Struct("<BIQ")


@dataclass(frozen=True)
class Received:
    """One message: the channel it came on (as advertised), its log time (ns) and its bytes."""

    channel: dict[str, Any]
    log_time_ns: int
    data: bytes


@functools.cache
def _protobuf_class(schema_name: str, file_descriptor_set: bytes) -> Any:
    pool = descriptor_pool.DescriptorPool()
    for f in descriptor_pb2.FileDescriptorSet.FromString(file_descriptor_set).file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def decode_protobuf(schema_name: str, file_descriptor_set: bytes, data: bytes) -> dict[str, Any]:
    """A protobuf message read with the schema its channel carries (a FileDescriptorSet), as a
    Foxglove client reads it; raises on bytes that are not such a message."""
    msg = _protobuf_class(schema_name, file_descriptor_set).FromString(data)
    return json_format.MessageToDict(msg, preserving_proto_field_name=True)


def channel_schema_bytes(channel: dict[str, Any]) -> bytes:
    """An advertised channel's schema as bytes: the protocol sends binary schemas (protobuf) in
    base64, text ones (jsonschema) as they are."""
    if channel.get("schemaEncoding") == "protobuf":
        return base64.b64decode(channel["schema"])
    return channel["schema"].encode()


class FoxgloveClient:
    """Connects, keeps the advertised channels, subscribes, and returns each message as it comes."""

    def __init__(self, url: str, max_queue: int = 16, sock: socket.socket | None = None) -> None:
        # max_queue: frames buffered before the library stops reading the socket (1: a client that
        # does not read stalls its TCP connection almost at once); sock: a connection of one's own.
        # No keepalive pings: a client that stops reading would close itself when its pong is late.
        self.ws: ClientConnection = connect(url, sock=sock, subprotocols=list(SUBPROTOCOLS),
                                            max_queue=max_queue, compression=None, proxy=None,
                                            max_size=None, ping_interval=None, legacy=True)
        if self.ws.subprotocol not in SUBPROTOCOLS:
            raise RuntimeError(f"server chose subprotocol {self.ws.subprotocol!r}, not one of "
                               f"{SUBPROTOCOLS}")
        self.server_info: dict[str, Any] | None = None
        self.channels: dict[int, dict[str, Any]] = {}
        self.statuses: list[dict[str, Any]] = []
        self._subs: dict[int, int] = {}  # subscription id -> channel id
        self._next_sub = 1

    def subscribe(self, channel_ids: list[int]) -> None:
        subs = []
        for cid in channel_ids:
            sid = self._next_sub
            self._next_sub += 1
            self._subs[sid] = cid
            subs.append({"id": sid, "channelId": cid})
        if subs:
            self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def subscribed(self) -> set[int]:
        return set(self._subs.values())

    def poll(self, timeout_s: float) -> Received | None:
        """The next message (control messages are taken in on the way); None after ``timeout_s``
        without a message of either kind."""
        try:
            frame = self.ws.recv(timeout=timeout_s)
        except TimeoutError:
            return None
        if isinstance(frame, str):
            self._control(json.loads(frame))
            return None
        return self._message(frame)

    def drain(self, quiet_s: float) -> list[Received]:
        """Every message until none (nor any control message) came for ``quiet_s``."""
        out = []
        while True:
            try:
                frame = self.ws.recv(timeout=quiet_s)
            except TimeoutError:
                return out
            if isinstance(frame, str):
                self._control(json.loads(frame))
            elif (m := self._message(frame)) is not None:
                out.append(m)

    def _message(self, frame: bytes) -> Received | None:
        op, sid, t_ns = _HEADER.unpack_from(frame)
        if op != MESSAGE_DATA:
            return None
        return Received(self.channels[self._subs[sid]], t_ns, bytes(frame[_HEADER.size:]))

    def _control(self, doc: dict[str, Any]) -> None:
        op = doc.get("op")
        if op == "serverInfo":
            self.server_info = doc
        elif op == "advertise":
            for ch in doc["channels"]:
                self.channels[ch["id"]] = ch
        elif op == "unadvertise":
            for cid in doc["channelIds"]:
                self.channels.pop(cid, None)
        elif op == "status":
            self.statuses.append(doc)

    def close(self) -> None:
        self.ws.close()
