"""Test helper: read a recording's Foxglove channels back with Google's protobuf library, against
the schemas foxglove-sdk ships (not a test module: used by the unit and system tests)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import foxglove.messages as fg
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader

SDK_SCHEMAS: dict[str, Any] = {}
"""Schema name -> the SDK's ``Schema`` (name, encoding, file descriptor set), for every message type
foxglove-sdk ships."""
for _name in dir(fg):
    _cls = getattr(fg, _name)
    if isinstance(_cls, type) and hasattr(_cls, "get_schema"):
        _s = _cls.get_schema()
        SDK_SCHEMAS[_s.name] = _s

_CLASSES: dict[tuple[str, bytes], type] = {}


def message_class(name: str, descriptor_set: bytes) -> type:
    """The protobuf class of ``name`` built from a file descriptor set (a channel's schema data)."""
    key = (name, descriptor_set)
    cls = _CLASSES.get(key)
    if cls is None:
        pool = descriptor_pool.DescriptorPool()
        for fd in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file:
            pool.Add(fd)
        cls = _CLASSES[key] = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
    return cls


def decode_strict(name: str, descriptor_set: bytes, data: bytes) -> Any:
    """``data`` as a ``name`` message; AssertionError unless every byte is a field the schema
    declares with its declared wire type (re-encoding gives the same bytes back)."""
    msg = message_class(name, descriptor_set).FromString(data)
    assert msg.SerializeToString(deterministic=True) == data, f"{name}: fields the schema lacks"
    return msg


def foxglove_messages(path: Path) -> list[tuple[str, str, int, Any]]:
    """Every message on a protobuf channel of the file, checked: (topic, schema name, log time,
    decoded message). The channel's schema must be byte for byte the SDK's of that name."""
    out = []
    with open(path, "rb") as fh:
        for schema, channel, m in make_reader(fh).iter_messages(log_time_order=True):
            if channel.message_encoding != "protobuf":
                continue
            assert schema is not None and schema.encoding == "protobuf", channel.topic
            sdk = SDK_SCHEMAS.get(schema.name)
            assert sdk is not None, f"{channel.topic}: {schema.name} is not a schema foxglove-sdk ships"
            assert bytes(schema.data) == bytes(sdk.data), f"{channel.topic}: not the SDK's {schema.name}"
            out.append((channel.topic, schema.name, m.log_time,
                        decode_strict(schema.name, bytes(schema.data), bytes(m.data))))
    return out


def t_ns(stamp: Any) -> int:
    """A decoded ``google.protobuf.Timestamp`` in ns."""
    return stamp.seconds * 1_000_000_000 + stamp.nanos
