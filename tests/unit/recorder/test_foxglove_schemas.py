"""Bus topics' JSON Schemas in the form Foxglove and Lichtblick read (``foxglove_json_schema``)."""

from __future__ import annotations

import json

import jsonschema
import pytest
from seaway.contract import keys
from seaway.contract.messages import GnssFix, StateEstimate
from seaway_recorder import schemas

from tests.unit.recorder.foxglove_check import foxglove_json_problems

TOPICS = [s for s in keys.REGISTRY if s.kind == "topic" and s.message is not None]


@pytest.mark.parametrize("spec", TOPICS, ids=lambda s: s.suffix)
def test_every_topic_channel_is_one_foxglove_reads(spec: keys.KeySpec) -> None:
    ch = schemas.channel_for_key(spec.key("v1"), "application/json")
    doc = json.loads(ch.schema_data)
    assert foxglove_json_problems(doc) == []
    jsonschema.Draft202012Validator.check_schema(doc)
    assert doc["title"] == spec.message.SCHEMA  # type: ignore[union-attr]


def test_pydantics_own_schemas_are_refused_by_foxglove() -> None:
    # Why the wire form leaves unknown fields out: pydantic's schema of an optional field
    # (anyOf with null) fails in Foxglove; the contract's names its type alone.
    assert "covariance: type None" in foxglove_json_problems(StateEstimate.model_json_schema())
    assert any("horizontal_std_m" in p for p in foxglove_json_problems(GnssFix.model_json_schema()))
    assert foxglove_json_problems(StateEstimate.json_schema()) == []


@pytest.mark.parametrize("spec", TOPICS, ids=lambda s: s.suffix)
def test_the_recorded_schema_refuses_a_null_where_the_wire_never_has_one(spec: keys.KeySpec) -> None:
    # A channel's schema is true to its messages: an optional field is absent, not null, so a null
    # there is refused (it validated nothing before, and the messages carried null).
    doc = json.loads(schemas.channel_for_key(spec.key("v1"), "application/json").schema_data)
    optional = [k for k, f in spec.message.model_fields.items() if f.default is None]  # type: ignore[union-attr]
    for name in optional:
        assert name in doc["properties"], name
        assert doc["properties"][name].get("type") != "null"
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate({name: None}, {**doc, "required": []})


def test_a_message_with_every_field_set_is_valid_in_both_forms() -> None:
    fix = GnssFix(stamp_ns=1, lat_rad=0.1, lon_rad=0.2, alt_m=3.0, fix_type=3, vel_n_mps=0.5,
                  vel_e_mps=-0.5, horizontal_std_m=1.5, satellites=9)
    wire = json.loads(fix.encode())
    jsonschema.validate(wire, schemas.foxglove_json_schema(GnssFix.json_schema()))
    with pytest.raises(jsonschema.ValidationError):  # bounds are kept: a negative std is refused
        jsonschema.validate({**wire, "horizontal_std_m": -1.0},
                            schemas.foxglove_json_schema(GnssFix.json_schema()))


def test_refs_nullables_type_lists_and_maps() -> None:
    src = {
        "type": "object", "title": "T", "description": "d",
        "$defs": {"P": {"type": "object", "properties": {"x_m": {"type": "number"}}},
                  "Loop": {"type": "object", "properties": {"next": {"$ref": "#/$defs/Loop"}}}},
        "properties": {
            "p": {"$ref": "#/$defs/P", "description": "a point"},
            "maybe": {"anyOf": [{"type": "integer", "minimum": 0}, {"type": "null"}], "default": None},
            "one": {"anyOf": [{"type": "integer", "minimum": 0}]},
            "listed": {"type": ["string"]},
            "nullable_listed": {"type": ["string", "null"]},
            "points": {"type": "array", "items": {"$ref": "#/$defs/P"}},
            "rates": {"type": "object", "additionalProperties": {"type": "number"}},
            "either": {"anyOf": [{"type": "integer"}, {"type": "string"}]},
            "grid": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}},
            "loop": {"$ref": "#/$defs/Loop"},
            "level": {"oneOf": [{"const": 1, "title": "A"}, {"const": 2, "title": "B"}]},
        },
    }
    out = schemas.foxglove_json_schema(src)
    props = out["properties"]
    assert props["p"] == {"type": "object", "description": "a point",
                          "properties": {"x_m": {"type": "number"}}}
    assert props["one"] == {"type": "integer", "minimum": 0}
    assert props["listed"] == {"type": "string"}
    assert props["points"]["items"]["properties"] == {"x_m": {"type": "number"}}
    assert props["rates"] == {"type": "object", "additionalProperties": {"type": "number"},
                              "properties": {}}
    assert props["level"] == src["properties"]["level"]
    # No single type Foxglove can name: left out (its values stay in the messages). A null is not
    # one: naming the type alone would refuse the messages that carry it.
    assert not {"either", "grid", "maybe", "nullable_listed"} & set(props)
    # A recursive type ends where it would recur.
    assert props["loop"] == {"type": "object", "properties": {}}
    assert "$defs" not in out and out["description"] == "d"
    assert foxglove_json_problems(out) == []
