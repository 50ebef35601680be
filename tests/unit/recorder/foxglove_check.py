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


# -- JSON Schema channels as Foxglove reads them ------------------------------------------------

_FOXGLOVE_FIELD_TYPES = {"boolean", "string", "number", "integer", "object", "array"}


def foxglove_json_problems(schema: dict[str, Any], path: str = "") -> list[str]:
    """What Foxglove's (and Lichtblick's) JSON Schema reader would refuse in ``schema``: the rules of
    ``parseJsonSchema`` in ``@foxglove/mcap-support`` (an object with ``properties``; each field one
    type of boolean/string/number/integer/object/array, an array's items one of those but array;
    ``oneOf`` only as numeric constants; no ``$ref`` followed). One refused field fails the channel.
    The browser test (tests/system/foxglove/test_foxglove_studio.py) checks the same in Foxglove."""
    out: list[str] = []
    if schema.get("type") != "object":
        return [f"{path or 'root'}: type {schema.get('type')!r}, not 'object'"]
    props = schema.get("properties")
    if not isinstance(props, dict):
        return [f"{path or 'root'}: an object without properties"]
    for name, field in props.items():
        where = f"{path}.{name}" if path else name
        if isinstance(field.get("oneOf"), list):
            if not all(isinstance(a.get("const"), int | float) for a in field["oneOf"]):
                out.append(f"{where}: oneOf other than numeric constants")
            continue
        kind = field.get("type")
        if kind not in _FOXGLOVE_FIELD_TYPES:
            out.append(f"{where}: type {kind!r}")
        elif kind == "object":
            out.extend(foxglove_json_problems(field, where))
        elif kind == "array":
            items = field.get("items") or {}
            if items.get("type") not in _FOXGLOVE_FIELD_TYPES - {"array"}:
                out.append(f"{where}[]: item type {items.get('type')!r}")
            elif items["type"] == "object":
                out.extend(foxglove_json_problems(items, f"{where}[]"))
        elif kind == "string" and field.get("contentEncoding") not in (None, "base64"):
            out.append(f"{where}: contentEncoding {field['contentEncoding']!r}")
    return out


def contract_validator(schema_name: str, schema_data: bytes) -> Any:
    """A validator of a JSON channel's messages against the channel's own schema, as an independent
    reader of the file would (no substitution). A bus topic's channel (``seaway.v1.*``) must also
    carry exactly the Foxglove form of its type's schema, and one Foxglove reads."""
    import json

    import jsonschema
    from seaway_recorder.schemas import foxglove_json_schema

    doc = json.loads(schema_data)
    contract = _contract_types().get(schema_name)
    if contract is not None:
        assert doc == foxglove_json_schema(contract.json_schema()), schema_name
        assert not foxglove_json_problems(doc), (schema_name, foxglove_json_problems(doc))
    cls = jsonschema.validators.validator_for(doc)
    cls.check_schema(doc)
    return cls(doc)


def invalid_messages(path: Path) -> tuple[int, dict[str, list[str]]]:
    """Every message of every JSON channel of the recording at ``path`` validated against the JSON
    Schema its channel carries in the file, with ``jsonschema`` alone: (messages checked, the
    errors by topic). A JSON channel without a ``jsonschema`` schema is an error too."""
    import json

    import jsonschema

    checked, errors, validators = 0, {}, {}
    with open(path, "rb") as fh:
        for schema, channel, m in make_reader(fh).iter_messages(log_time_order=False):
            if channel.message_encoding != "json":
                continue
            checked += 1
            if schema is None or schema.encoding != "jsonschema":
                errors.setdefault(channel.topic, []).append("no jsonschema schema")
                continue
            v = validators.get(schema.id)
            if v is None:
                doc = json.loads(schema.data)
                v = validators[schema.id] = jsonschema.validators.validator_for(doc)(doc)
            for err in v.iter_errors(json.loads(m.data)):
                errors.setdefault(channel.topic, []).append(
                    f"{'.'.join(map(str, err.absolute_path))}: {err.message[:200]}")
    return checked, errors


def _contract_types() -> dict[str, Any]:
    from seaway.contract.messages import ALL_MESSAGES

    return {cls.SCHEMA: cls for cls in ALL_MESSAGES}
