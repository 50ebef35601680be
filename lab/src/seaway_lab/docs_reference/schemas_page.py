"""The message reference: every message type on the bus, its keys, its fields and its JSON Schema.

The schema is the wire form's (``Message.json_schema``), the one recordings carry and
``seaway schemas DIR`` writes.
"""

from __future__ import annotations

import json

from seaway.contract import keys
from seaway.contract.messages import ALL_MESSAGES, Message

from seaway_lab.docs_reference.markdown import (
    GENERATED_NOTE,
    anchor,
    describe,
    field_table,
    schema_sections,
)


def _keys_of(message: type[Message]) -> str:
    found = sorted(s.suffix for s in keys.REGISTRY if s.message is message)
    if not found:
        return ""
    links = ", ".join(f"`{s}`" for s in found)
    return f"Keys: {links} ([keys](keys.md)).\n\n"


def _schema_block(schema: dict) -> str:
    text = json.dumps(schema, indent=2, sort_keys=True)
    body = "\n".join("    " + line if line else "" for line in text.splitlines())
    return f'??? note "JSON Schema of `{schema.get("title", "")}`"\n\n    ```json\n{body}\n    ```\n\n'


def section(message: type[Message]) -> str:
    schema = message.json_schema()
    return "".join([
        f"## {message.__name__}\n\n",
        f"`{message.SCHEMA}`: {describe(message.__doc__)}\n\n",
        _keys_of(message),
        field_table(schema), "\n",
        schema_sections(schema, level=3),
        _schema_block(schema),
    ])


def page() -> str:
    """``docs/reference/messages.md``."""
    ordered = sorted(ALL_MESSAGES, key=lambda m: m.__name__)
    index = ", ".join(f"[{m.__name__}](#{anchor(m.__name__)})" for m in ordered)
    return "".join([
        GENERATED_NOTE, "# Messages\n\n",
        "Every message on the bus: one pydantic type per key (`seaway.contract.messages`), JSON on "
        "the wire, SI units in the field names, `stamp_ns` on every one. NaN and infinity are "
        "refused, naming the field; decoding ignores unknown fields except in requests, which refuse "
        "them. A field that may be unknown is left out of the wire form rather than sent as null. "
        "`seaway schemas DIR` writes the same JSON Schemas to files.\n\n",
        index, "\n\n",
        *(section(m) for m in ordered),
    ])
