"""The base every message builds on: ``Message`` (validation, the wire's JSON bytes, the
JSON Schema of the wire form) and ``MessageError``; the package's description says the rules."""

from __future__ import annotations

import json
import math
from types import UnionType
from typing import Annotated, Any, ClassVar, Self, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, ValidationError


class MessageError(ValueError):
    """A message could not be built, encoded or decoded; the text names the type and the field."""


def _describe(err: ValidationError, type_name: str) -> str:
    parts = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(message)"
        msg = ("unknown field, refused (a request takes only the fields it defines)"
               if e["type"] == "extra_forbidden" else e["msg"])
        parts.append(f"{type_name}.{loc}: {msg}")
    return "; ".join(parts)


def _first_non_finite(value: Any, path: str) -> str | None:
    """Path of the first NaN or infinity inside ``value`` (a dumped model), or None."""
    if isinstance(value, float):
        return None if math.isfinite(value) else path
    if isinstance(value, dict):
        for k, v in value.items():
            found = _first_non_finite(v, f"{path}.{k}" if path else str(k))
            if found:
                return found
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            found = _first_non_finite(v, f"{path}[{i}]")
            if found:
                return found
    return None


MAX_STAMP_NS = 2**63 - 1
"""The largest stamp a message may carry [ns]: int64's, the year 2262. A stamp past it (a JSON
integer of any length parses) reaches no clock, and only overflows whoever divides it."""


NS_DURATION_FIELDS = frozenset({"period_ns"})
"""Message fields in nanoseconds that are durations. Every other field named ``*_ns``, at any depth
of a message, is a wall-clock time [ns since epoch]: what a step of that clock moves."""


class Message(BaseModel):
    """Base of every bus message: immutable, finite, tolerant of unknown fields when decoded."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True, ser_json_inf_nan="constants")

    SCHEMA: ClassVar[str]
    stamp_ns: int = Field(ge=0, le=MAX_STAMP_NS, description="time the data is valid at [ns since "
                          "epoch], an int64 (what MCAP's log times and every consumer hold)")

    @classmethod
    def make(cls, **fields: Any) -> Self:
        """Build and validate; a bad field raises MessageError naming it (e.g. a NaN)."""
        try:
            return cls(**fields)
        except ValidationError as err:
            raise MessageError(_describe(err, cls.__name__)) from None

    def encode(self) -> bytes:
        """JSON bytes for the wire. Refuses non-finite numbers, naming the field.

        Instances built through the constructor are already finite; this also catches ones made with
        ``model_construct`` (which skips validation). The substring test keeps the common path cheap.
        """
        # The serializer's bytes as they are (``model_dump_json`` is them decoded to a str).
        data = self.__pydantic_serializer__.to_json(self, exclude_none=True)
        if b"NaN" in data or b"Infinity" in data:
            bad = _first_non_finite(self.model_dump(), "")
            if bad:
                raise MessageError(f"{type(self).__name__}.{bad}: not finite; publishing refused")
        return data

    @classmethod
    def decode(cls, data: bytes | bytearray | memoryview | str) -> Self:
        """Parse and validate wire bytes; raises MessageError naming what is wrong."""
        try:
            return cls.model_validate_json(bytes(data) if not isinstance(data, str) else data)
        except ValidationError as err:
            raise MessageError(_describe(err, cls.__name__)) from None

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        """JSON Schema (draft 2020-12) of the wire form, titled with the versioned schema name."""
        return wire_json_schema(cls, cls.SCHEMA)

    @classmethod
    def json_schema_text(cls) -> str:
        return json.dumps(cls.json_schema(), sort_keys=True)


def wire_json_schema(model: type[BaseModel], title: str) -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of ``model``'s wire form, where an unknown field is left out.

    pydantic names a field that may be ``None`` ``anyOf: [X, null]`` with ``default: null``; on the
    wire (``Message.encode``: ``exclude_none``) such a field is X or absent, never null, so its
    property here is X alone, and absent is allowed because it is not ``required``. A field whose
    ``None`` is not its default could not be left out: ``nullable_fields_without_default`` finds
    them (a contract test keeps that list empty). ``None`` inside a list or a map is kept as null
    and stays in the schema.
    """
    schema = model.model_json_schema(mode="serialization")
    for obj in [schema, *schema.get("$defs", {}).values()]:
        for name, prop in obj.get("properties", {}).items():
            alts = prop.get("anyOf")
            if "default" not in prop or prop["default"] is not None or not isinstance(alts, list):
                continue
            rest = [a for a in alts if a != {"type": "null"}]
            if len(rest) == len(alts):
                continue
            del prop["default"], prop["anyOf"]
            obj["properties"][name] = {**rest[0], **prop} if len(rest) == 1 else {"anyOf": rest, **prop}
    schema["title"] = title
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


def nullable_fields_without_default(model: type[BaseModel]) -> list[str]:
    """Fields of ``model`` (and of the models inside it) that admit ``None`` without defaulting to
    it: the wire form leaves ``None`` out, so such a field would not survive a round trip."""
    out: list[str] = []
    seen: set[type[BaseModel]] = set()

    def nested(ann: Any) -> list[type[BaseModel]]:
        found = [ann] if isinstance(ann, type) and issubclass(ann, BaseModel) else []
        for a in get_args(ann):
            found.extend(nested(a))
        return found

    def walk(cls: type[BaseModel], path: str) -> None:
        if cls in seen:
            return
        seen.add(cls)
        for name, field in cls.model_fields.items():
            if _admits_none(field.annotation) and (field.is_required() or field.default is not None):
                out.append(f"{path}.{name}")
            for sub in nested(field.annotation):
                walk(sub, f"{path}.{name}")

    walk(model, model.__name__)
    return out


def _admits_none(ann: Any) -> bool:
    if ann is None or ann is type(None) or ann is Any:
        return True
    origin = get_origin(ann)
    if origin is Annotated:
        return _admits_none(get_args(ann)[0])
    return origin in (Union, UnionType) and any(_admits_none(a) for a in get_args(ann))


JSON_ENCODING = "application/json"
"""Encoding of every typed message and reply on the wire; a typed topic adds its schema name after
``;`` (``message_encoding``)."""


def message_encoding(message: type[Message]) -> str:
    """The encoding a message type is published with: JSON with the versioned schema name."""
    return f"{JSON_ENCODING};{message.SCHEMA}"


MAX_REASON_CHARS = 300
"""Longest ``MissionStatus.reason`` (and ``StateEstimate.motion_fault_detail``)."""
