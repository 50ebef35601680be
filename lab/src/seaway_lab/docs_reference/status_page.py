"""The reference of every status value and reason a message can carry: each closed set of names in
the messages (a ``Literal`` type), what each name means where the code says it for a person, and
the fields that carry it; then vehicle_io's failsafe names.

The operator's guide (``docs/operator/warnings.md``) says what to do about them; this page is the
complete list, so a new value shows here as soon as the code has it.
"""

from __future__ import annotations

import typing
from typing import Any, Literal, get_args, get_origin

from pydantic import BaseModel
from seaway.contract import messages

from seaway_lab.docs_reference.markdown import GENERATED_NOTE, cell, code, constant_docs, describe, table


def _literal_values(annotation: Any) -> tuple[str, ...]:
    if get_origin(annotation) is Literal:
        return tuple(str(v) for v in get_args(annotation))
    return ()


def _closed_sets() -> dict[str, tuple[str, ...]]:
    """Every module-level ``Name = Literal[...]`` of the messages package, by name."""
    return {name: values for name, value in sorted(vars(messages).items())
            if (values := _literal_values(value)) and not name.startswith("_")}


def _texts() -> dict[str, dict[str, str]]:
    """The messages package's ``*_TEXT`` dicts: each value's words for a person."""
    return {name: value for name, value in vars(messages).items()
            if name.endswith("_TEXT") and isinstance(value, dict)}


def _mentions(annotation: Any, target: Any) -> bool:
    if annotation is target:
        return True
    return any(_mentions(a, target) for a in get_args(annotation))


def _models() -> list[type[BaseModel]]:
    """Every message type, and every type a message nests (``AutopilotFence``, ``Waypoint``, ...)."""
    return sorted((v for v in vars(messages).values() if isinstance(v, type) and issubclass(v, BaseModel)
                   and v.__module__.startswith(f"{messages.__name__}.") and v.model_fields),
                  key=lambda m: m.__name__)


def _fields_using(alias: Any) -> list[str]:
    out = []
    for message in _models():
        hints = typing.get_type_hints(message)
        for name in message.model_fields:
            if _mentions(hints.get(name), alias):
                out.append(f"{message.__name__}.{name}")
    return out


def _field_docs(fields: list[str]) -> str:
    parts = []
    for path in fields:
        cls_name, field = path.split(".")
        info = getattr(messages, cls_name).model_fields[field]
        if info.description:
            parts.append(f"`{path}`: {describe(info.description)}")
    return "\n\n".join(parts)


def _vehicle_io_failsafes() -> list[list[str]]:
    from seaway_vehicle_io import core_status, watchdog

    rows = []
    for module, name in ((core_status, "FAILSAFE_AUTOPILOT_CONFIG"), (watchdog, "FAILSAFE_THRUST_STALE")):
        doc = constant_docs(module).get(name, "")
        rows.append([code(getattr(module, name)), code(f"{module.__name__}.{name}"), cell(describe(doc))])
    return sorted(rows)


def page() -> str:
    """``docs/reference/status-values.md``."""
    docs = {name: doc for module in messages.MODULES for name, doc in constant_docs(module).items()}
    texts = _texts()
    parts = [GENERATED_NOTE, "# Status values and reasons\n\n",
             "Every closed set of names a message carries (`seaway.contract.messages`), what each "
             "name means, and the message fields that carry it. What an operator does about them: "
             "[Warnings](../operator/warnings.md).\n\n"]
    for name, values in _closed_sets().items():
        alias = getattr(messages, name)
        text = next((t for t in texts.values() if set(t) == set(values)), None)
        parts.append(f"## {name}\n\n")
        if docs.get(name):
            parts.append(describe(docs[name]) + "\n\n")
        rows = [[code(v), cell(text[v]) if text else ""] for v in values]
        parts.append(table(["value", "meaning"], rows) if text else
                     "Values: " + ", ".join(code(v) for v in values) + ".\n")
        fields = _fields_using(alias)
        if fields:
            parts.append("\nCarried by " + ", ".join(code(f) for f in fields) + ".\n\n")
            notes = _field_docs(fields)
            if notes:
                parts.append(notes + "\n\n")
        else:
            parts.append("\n")
    parts.append("## VehicleStatus.failsafe\n\n"
                 "The failsafe vehicle_io itself reports (`VehicleStatus.failsafe`), most serious "
                 "first:\n\n" + table(["value", "defined in", "meaning"], _vehicle_io_failsafes()))
    return "".join(parts)
