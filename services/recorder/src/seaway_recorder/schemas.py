"""What goes into a recording besides the bytes: schemas, channel naming and Foxglove companions.

* every registered key ``seaway/<vessel>/<suffix>`` becomes an MCAP channel whose topic is the key,
  ``message_encoding="json"`` and a ``jsonschema`` schema named with the message's versioned name
  (``seaway.v1.SimTruth``), the JSON Schema its type generates;
* a key the registry does not know is still recorded, unchanged, on a channel without a schema
  (schema id 0), so nothing on the bus is lost;
* a sample whose bytes do not decode as its key's type goes to the error channel
  ``recorder/malformed`` as a ``seaway.recorder.v1.MalformedSample`` (key, error, the bytes in base64),
  so the file still validates against its schemas and the bytes are kept;
* Foxglove's well-known ``foxglove.LocationFix`` is derived from ``sim/truth``, ``nav/state`` (through
  the last ``nav/origin``) and ``sensors/gnss``, on ``foxglove/<vessel>/<source>``, for the Map panel;
* the launcher's process events (started, exited, hung, stopped), read from its ``events.jsonl``, go
  to ``launcher/events`` as ``seaway.launcher.v1.ProcessEvent``.
"""

from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import GnssFix, Message, NavOrigin, Refusals, SimTruth, StateEstimate
from seaway.contract.units import NS_PER_S
from seaway.tools.launch.events import EVENTS_TOPIC, ProcessEvent
from seaway.vessel.frames import GeoOrigin

JSON = "json"
JSONSCHEMA = "jsonschema"
MALFORMED_TOPIC = "recorder/malformed"
MALFORMED_SCHEMA_NAME = "seaway.recorder.v1.MalformedSample"
LOCATION_FIX_SCHEMA_NAME = "foxglove.LocationFix"
FOXGLOVE_ROOT = "foxglove"

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

# Foxglove's well-known geographic fix (the fields Foxglove's Map panel reads; the optional ones we do
# not fill are omitted). Field meanings follow the Foxglove schema of the same title.
_TIME_SCHEMA = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}
LOCATION_FIX_SCHEMA: dict[str, Any] = {
    "title": LOCATION_FIX_SCHEMA_NAME,
    "description": "A navigation satellite fix for any Global Navigation Satellite System",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME_SCHEMA, "description": "Timestamp of the message"},
        "frame_id": {"type": "string", "description": "Frame for the sensor"},
        "latitude": {"type": "number", "description": "Latitude in degrees"},
        "longitude": {"type": "number", "description": "Longitude in degrees"},
        "altitude": {"type": "number", "description": "Altitude in meters"},
        "position_covariance": {
            "type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9,
            "description": "Position covariance (m^2), East-North-Up, row-major",
        },
        "position_covariance_type": {
            "title": "foxglove.PositionCovarianceType",
            "oneOf": [
                {"title": "UNKNOWN", "const": 0},
                {"title": "APPROXIMATED", "const": 1},
                {"title": "DIAGONAL_KNOWN", "const": 2},
                {"title": "KNOWN", "const": 3},
            ],
        },
        "heading": {"type": "number", "description": "Heading [rad], clockwise from north"},
    },
    "required": ["timestamp", "frame_id", "latitude", "longitude", "altitude",
                 "position_covariance", "position_covariance_type"],
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


def channel_for_key(key: str, zenoh_encoding: str = "") -> ChannelSpec:
    """The channel a bus key is recorded on (registered keys get their JSON Schema)."""
    spec = keys.spec_for_key(key)
    meta = {"zenoh_encoding": zenoh_encoding} if zenoh_encoding else {}
    reporter = keys.refusals_identity(key)
    if reporter is not None:  # one key per identity: a family, not one registered key
        meta.update({"registered": "true", "producer": reporter, "vessel": key.split("/", 2)[1]})
        return ChannelSpec(key, Refusals.SCHEMA, JSONSCHEMA, Refusals.json_schema_text().encode(),
                           JSON, Refusals, meta)
    if spec is None or spec.message is None or spec.kind != "topic":
        meta["registered"] = "false"
        return ChannelSpec(key, "", "", b"", JSON if "json" in zenoh_encoding else "", None, meta)
    meta.update({"registered": "true", "producer": spec.producer, "vessel": key.split("/", 2)[1]})
    return ChannelSpec(key, spec.message.SCHEMA, JSONSCHEMA, spec.message.json_schema_text().encode(),
                       JSON, spec.message, meta)


def malformed_channel() -> ChannelSpec:
    return ChannelSpec(MALFORMED_TOPIC, MALFORMED_SCHEMA_NAME, JSONSCHEMA,
                       json.dumps(MALFORMED_SCHEMA, sort_keys=True).encode(), JSON, None,
                       {"role": "errors"})


def events_channel() -> ChannelSpec:
    """The launcher's process events (``seaway.tools.launch.events``), copied from its log."""
    return ChannelSpec(EVENTS_TOPIC, ProcessEvent.SCHEMA, JSONSCHEMA,
                       ProcessEvent.json_schema_text().encode(), JSON, None,
                       {"role": "events", "source": "launcher"})


def location_fix_channel(topic: str, derived_from: str) -> ChannelSpec:
    return ChannelSpec(topic, LOCATION_FIX_SCHEMA_NAME, JSONSCHEMA,
                       json.dumps(LOCATION_FIX_SCHEMA, sort_keys=True).encode(), JSON, None,
                       {"derived_from": derived_from, "role": "foxglove"})


def malformed_record(key: str, schema: str, error: str, encoding: str, payload: bytes,
                     receive_time_ns: int) -> bytes:
    return json.dumps({
        "key": key, "schema": schema, "error": error, "encoding": encoding,
        "payload_base64": base64.b64encode(payload).decode(), "receive_time_ns": receive_time_ns,
    }).encode()


def location_fix(stamp_ns: int, frame_id: str, lat_rad: float, lon_rad: float, alt_m: float,
                 heading_rad: float | None = None, std_m: float | None = None) -> bytes:
    """A ``foxglove.LocationFix`` JSON document (degrees, as Foxglove wants them)."""
    var = std_m * std_m if std_m is not None else 0.0
    doc: dict[str, Any] = {
        "timestamp": {"sec": stamp_ns // NS_PER_S, "nsec": stamp_ns % NS_PER_S},
        "frame_id": frame_id,
        "latitude": math.degrees(lat_rad),
        "longitude": math.degrees(lon_rad),
        "altitude": alt_m,
        "position_covariance": [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, 0.0],
        "position_covariance_type": 2 if std_m is not None else 0,
    }
    if heading_rad is not None:
        doc["heading"] = heading_rad
    return json.dumps(doc).encode()


class LocationFixDeriver:
    """Turns decoded position messages into ``(topic, LocationFix bytes)`` for the Map panel.

    The topic is ``foxglove/<vessel>/<source>`` with the source key's suffix, ``/`` replaced by ``-``
    (``foxglove/vessel1/sim-truth``).

    Local NED positions need the geodetic origin: ``nav/origin`` from the bus, else the one given
    (the scenario's). Positions before any origin is known produce nothing.
    """

    SOURCES: tuple[keys.KeySpec, ...] = (keys.SIM_TRUTH, keys.NAV_STATE, keys.NAV_ORIGIN, keys.GNSS)
    """The keys ``feed`` uses; the writer decodes only these for it."""

    def __init__(self, default_origin: GeoOrigin | None = None) -> None:
        self._default = default_origin
        self._origins: dict[str, GeoOrigin] = {}

    def feed(self, key: str, msg: Message) -> tuple[str, bytes] | None:
        parts = key.split("/", 2)
        if len(parts) != 3:
            return None
        vessel, suffix = parts[1], parts[2]
        if isinstance(msg, NavOrigin):
            self._origins[vessel] = GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m)
            return None
        if isinstance(msg, GnssFix):
            return (f"{FOXGLOVE_ROOT}/{vessel}/{suffix.replace('/', '-')}",
                    location_fix(msg.stamp_ns, vessel, msg.lat_rad, msg.lon_rad, msg.alt_m,
                                 std_m=msg.horizontal_std_m))
        if isinstance(msg, SimTruth | StateEstimate):
            origin = self._origins.get(vessel, self._default)
            if origin is None:
                return None
            lat, lon, alt = origin.to_geodetic(msg.x_m, msg.y_m, 0.0)
            source = suffix.replace("/", "-")
            return (f"{FOXGLOVE_ROOT}/{vessel}/{source}",
                    location_fix(msg.stamp_ns, vessel, lat, lon, alt, heading_rad=msg.psi_rad))
        return None
