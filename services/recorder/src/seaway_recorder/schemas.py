"""What goes into a recording besides the bytes: schemas, channel naming and Foxglove companions.

* every registered key ``seaway/<vessel>/<suffix>`` becomes an MCAP channel whose topic is the key,
  ``message_encoding="json"`` and a ``jsonschema`` schema named with the message's versioned name
  (``seaway.v1.SimTruth``): the JSON Schema its type generates, in the form Foxglove and Lichtblick
  read (``foxglove_json_schema``);
* a key the registry does not know is still recorded, unchanged, on a channel without a schema
  (schema id 0), so nothing on the bus is lost;
* a sample whose bytes do not decode as its key's type goes to the error channel
  ``recorder/malformed`` as a ``seaway.recorder.v1.MalformedSample`` (key, error, the bytes in base64),
  so the file still validates against its schemas and the bytes are kept;
* Foxglove's well-known channels (map positions, the mission, frames and the 3D scene, logs) are
  derived in ``derive.py`` with ``foxglove-sdk``'s schemas;
* the launcher's process events (started, exited, hung, stopped), read from its ``events.jsonl``, go
  to ``launcher/events`` as ``seaway.launcher.v1.ProcessEvent``.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import Message, Refusals, wire_json_schema
from seaway.tools.launch.events import EVENTS_TOPIC, ProcessEvent

JSON = "json"
JSONSCHEMA = "jsonschema"
MALFORMED_TOPIC = "recorder/malformed"
MALFORMED_SCHEMA_NAME = "seaway.recorder.v1.MalformedSample"

MALFORMED_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": MALFORMED_SCHEMA_NAME,
    "description": "A sample that did not decode as its key's message type, kept byte for byte.",
    "type": "object",
    "properties": {
        "key": {"type": "string", "description": "the Zenoh key the sample arrived on"},
        "schema": {"type": "string", "description": "the schema the key's samples must follow"},
        "error": {"type": "string", "description": "why decoding failed"},
        "encoding": {"type": "string", "description": "the sample's Zenoh encoding"},
        "payload_base64": {"type": "string", "description": "the sample's bytes, unchanged"},
        "receive_time_ns": {"type": "integer", "minimum": 0},
    },
    "required": ["key", "schema", "error", "payload_base64", "receive_time_ns"],
}

RESTART_TOPIC = "recorder/restart"
RESTART_SCHEMA_NAME = "seaway.recorder.v1.Restart"
RESTART_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": RESTART_SCHEMA_NAME,
    "description": "A recorder restarted into a run folder whose recording its predecessor left: "
                   "the time it was away, and how far back it asked the publishers' caches for "
                   "what was published meanwhile. A sample published before asked_from_ns (or "
                   "by a publisher without a cache) in that time is not in the recording.",
    "type": "object",
    "properties": {
        "stamp_ns": {"type": "integer", "minimum": 0,
                     "description": "when this recorder started [ns since epoch]"},
        "previous_file": {"type": "string", "description": "the predecessor's recording"},
        "previous_last_ns": {"type": "integer", "minimum": 0,
                             "description": "log time of its last message on disk [ns]"},
        "asked_from_ns": {"type": "integer", "minimum": 0,
                          "description": "the start of what the caches were asked for [ns]"},
        "gap_unrecovered_s": {"type": "number", "minimum": 0,
                              "description": "from previous_last_ns to asked_from_ns, if later: "
                                             "the time nothing could be asked for [s]"},
    },
    "required": ["stamp_ns", "previous_file", "previous_last_ns", "asked_from_ns",
                 "gap_unrecovered_s"],
}

CLOCK_STEP_TOPIC = "recorder/clock_step"
CLOCK_STEP_SCHEMA_NAME = "seaway.recorder.v1.ClockStep"
CLOCK_STEP_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": CLOCK_STEP_SCHEMA_NAME,
    "description": "The wall clock of the recorder's machine stepped while it recorded in real time "
                   "(NTP or GPS time setting a computer without a real-time clock): every wall "
                   "time its processes gave after it is on the new clock. Seen at a flush (50 ms "
                   "apart) as the change of the wall clock's offset from the monotonic one.",
    "type": "object",
    "properties": {
        "stamp_ns": {"type": "integer", "minimum": 0,
                     "description": "when the step was seen, on the new clock [ns since epoch]"},
        "step_ns": {"type": "integer", "description": "the step: forward if positive [ns]"},
    },
    "required": ["stamp_ns", "step_ns"],
}


@dataclass(frozen=True)
class ChannelSpec:
    """How one topic is written: its schema (name, encoding, text) or none, and channel metadata."""

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    message_type: type[Message] | None
    metadata: dict[str, str]


_FOXGLOVE_TYPES = ("boolean", "string", "number", "integer", "object", "array")


def foxglove_json_schema(schema: dict[str, Any]) -> dict[str, Any]:
    """``schema`` (the JSON Schema of a message's wire form) in the form Foxglove and Lichtblick read,
    still true to every message that form validates.

    Their reader (``parseJsonSchema`` of ``@foxglove/mcap-support``, copied by Lichtblick) takes
    one ``type`` per field from boolean, string, number, integer, object (with ``properties``) and
    array (of those, not of arrays), and follows no ``$ref``; any other field fails the whole
    channel ("Unsupported type undefined for cross_track_m"), and with it every plot of the topic.
    So: ``$ref`` is inlined from ``$defs``; ``anyOf``/``oneOf`` of one alternative becomes it; an
    object without ``properties`` (a map) gets empty ones; a field with no single type (an
    alternative, or a value that may be null, which one type cannot say) is dropped from
    ``properties``: its values stay in every message, and an unlisted field is allowed. A
    message's unknown fields are absent on the wire (``seaway.contract.messages.wire_json_schema``),
    so an optional field has its one type. The rest (titles, descriptions, bounds, enums,
    ``required``) is kept.
    """
    defs: dict[str, Any] = schema.get("$defs", {})

    def resolve(node: dict[str, Any], seen: tuple[str, ...]) -> dict[str, Any] | None:
        node = dict(node)
        ref = node.pop("$ref", None)
        if isinstance(ref, str):
            name = ref.rsplit("/", 1)[-1]
            if name in seen or name not in defs:  # a recursive type has no finite form here
                return None
            node = {**defs[name], **node}
            seen = (*seen, name)
        for alt_key in ("anyOf", "oneOf"):
            alts = node.get(alt_key)
            if not isinstance(alts, list):
                continue
            if alt_key == "oneOf" and all(isinstance(a.get("const"), int | float) for a in alts):
                return node  # Foxglove's own numeric enum form
            if len(alts) != 1:
                return None
            del node[alt_key]
            inner = resolve(alts[0], seen)
            if inner is None:
                return None
            node = {**inner, **{k: v for k, v in node.items() if k != "type"}}
        kind = node.get("type")
        if isinstance(kind, list):
            if len(kind) != 1:
                return None
            node["type"] = kind = kind[0]
        if kind not in _FOXGLOVE_TYPES:
            return None
        if kind == "object":
            props = {}
            for name, sub in node.get("properties", {}).items():
                done = resolve(sub, seen)
                if done is not None:
                    props[name] = done
            node["properties"] = props
        elif kind == "array":
            items = resolve(node.get("items", {}), seen)
            if items is None or items["type"] == "array":
                return None
            node["items"] = items
        return node

    out = resolve({k: v for k, v in schema.items() if k != "$defs"}, ())
    if out is None:
        raise ValueError(f"schema {schema.get('title')!r} has no object form Foxglove reads")
    return out


def foxglove_schema_text(schema: dict[str, Any]) -> bytes:
    """``foxglove_json_schema`` as the bytes of an MCAP schema record."""
    return json.dumps(foxglove_json_schema(schema), sort_keys=True).encode()


def channel_for_key(key: str, zenoh_encoding: str = "") -> ChannelSpec:
    """The channel a bus key is recorded on (registered keys get their JSON Schema)."""
    spec = keys.spec_for_key(key)
    meta = {"zenoh_encoding": zenoh_encoding} if zenoh_encoding else {}
    reporter = keys.refusals_identity(key)
    if reporter is not None:  # one key per identity: a family, not one registered key
        meta.update({"registered": "true", "producer": reporter, "vessel": key.split("/", 2)[1]})
        return ChannelSpec(key, Refusals.SCHEMA, JSONSCHEMA,
                           foxglove_schema_text(Refusals.json_schema()), JSON, Refusals, meta)
    if spec is None or spec.message is None or spec.kind != "topic":
        meta["registered"] = "false"
        return ChannelSpec(key, "", "", b"", JSON if "json" in zenoh_encoding else "", None, meta)
    meta.update({"registered": "true", "producer": spec.producer, "vessel": key.split("/", 2)[1]})
    return ChannelSpec(key, spec.message.SCHEMA, JSONSCHEMA,
                       foxglove_schema_text(spec.message.json_schema()), JSON, spec.message, meta)


def _own_channel(topic: str, name: str, schema: dict[str, Any], role: str) -> ChannelSpec:
    """A channel of the recorder's own JSON records, with its JSON Schema."""
    return ChannelSpec(topic, name, JSONSCHEMA, json.dumps(schema, sort_keys=True).encode(), JSON,
                       None, {"role": role})


def malformed_channel() -> ChannelSpec:
    return _own_channel(MALFORMED_TOPIC, MALFORMED_SCHEMA_NAME, MALFORMED_SCHEMA, "errors")


def restart_channel() -> ChannelSpec:
    return _own_channel(RESTART_TOPIC, RESTART_SCHEMA_NAME, RESTART_SCHEMA, "recorder")


def clock_step_channel() -> ChannelSpec:
    return _own_channel(CLOCK_STEP_TOPIC, CLOCK_STEP_SCHEMA_NAME, CLOCK_STEP_SCHEMA, "recorder")


def events_channel() -> ChannelSpec:
    """The launcher's process events (``seaway.tools.launch.events``), copied from its log."""
    return ChannelSpec(EVENTS_TOPIC, ProcessEvent.SCHEMA, JSONSCHEMA,
                       foxglove_schema_text(wire_json_schema(ProcessEvent, ProcessEvent.SCHEMA)),
                       JSON, None,
                       {"role": "events", "source": "launcher"})


def malformed_record(key: str, schema: str, error: str, encoding: str, payload: bytes,
                     receive_time_ns: int) -> bytes:
    return json.dumps({
        "key": key, "schema": schema, "error": error, "encoding": encoding,
        "payload_base64": base64.b64encode(payload).decode(), "receive_time_ns": receive_time_ns,
    }).encode()
