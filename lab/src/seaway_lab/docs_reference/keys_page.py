"""The key reference: every registered key with its message type, producer and who may use it.

From the key registry (``seaway.contract.keys``) and the access rules generated from it
(``seaway.contract.access``): a topic is published only by its producers and read by every identity
of the stack; a request is served only by its producer and asked only by the operator identities.
"""

from __future__ import annotations

from seaway.contract import access, keys

from seaway_lab.docs_reference.markdown import (
    GENERATED_NOTE,
    anchor,
    cell,
    code,
    constant_docs,
    describe,
    table,
)


def _message_link(spec: keys.KeySpec) -> str:
    if spec.message is None:
        return "(none)"
    name = spec.message.__name__
    return f"[`{name}`](messages.md#{anchor(name)})"


def _what(spec: keys.KeySpec) -> str:
    """The registry's note on a key, else the first paragraph of its message type's docstring."""
    if spec.doc:
        return describe(spec.doc)
    doc = (spec.message.__doc__ or "") if spec.message is not None else ""
    return describe(doc.strip().split("\n\n")[0])


def _who(spec: keys.KeySpec) -> tuple[str, str]:
    """(who produces, who uses) a key under the access rules of one stack."""
    producers = ", ".join(access.producers()[spec.suffix])
    if spec.kind == "query":
        return producers + " (serves)", ", ".join(access.OPERATORS) + " (ask)"
    return producers, "all (read)"


def page() -> str:
    """``docs/reference/keys.md``."""
    rows = []
    for spec in sorted(keys.REGISTRY, key=lambda s: s.suffix):
        producer, users = _who(spec)
        rows.append([code(spec.suffix), spec.kind, _message_link(spec),
                     cell(producer), cell(users), cell(_what(spec))])
    other = [
        [code(f"{keys.HEALTH}/<service>"), "liveliness", "(none)",
         "the service it names", "all (read)",
         cell(_doc("HEALTH"))],
        [code(f"{keys.RUN}/<service>"), "query",
         "[`RunDescription`](files.md#run-description)", "the service it names (serves)",
         "all (ask)", cell(_doc("RUN"))],
        [code(f"{keys.REFUSALS}/<identity>"), "topic and query",
         f"[`Refusals`](messages.md#{anchor('Refusals')})", "the identity it names",
         "all (read, ask)", cell(_doc("REFUSALS"))],
    ]
    ident_rows = [[code(i), cell(_role(i))] for i in access.IDENTITIES]
    ident_rows.append([code(access.HARNESS), cell(describe(_access_doc("HARNESS")))])
    return "".join([
        GENERATED_NOTE, "# Keys\n\n",
        "Every key on the bus is `seaway/<vessel>/<what>`; the registry "
        "(`seaway.contract.keys`) is the only place one is spelled. Zenoh's access control, "
        "generated from the registry (`seaway.contract.access`), drops what an identity may not do: "
        "only a key's producer publishes it or serves it, only the operator identities ask a "
        "request that moves or resets, and only the service a health token names declares it. "
        "A profile narrows a key with several possible producers to the one it runs. Each key below "
        "is under `seaway/<vessel>/`; \"all\" is every identity of the stack.\n\n",
        "## Registered keys\n\n",
        table(["key", "kind", "message", "producer", "who may use it", "what"], rows),
        "\n## Keys outside the registry's topics\n\n",
        table(["key", "kind", "message", "producer", "who may use it", "what"], other),
        "\n## Identities\n\n",
        "Each process of a stack has one identity, the common name of its certificate "
        "(`seaway.runtime.credentials`).\n\n",
        table(["identity", "what it is"], ident_rows),
        "\nOperator identities (may ask the requests that move or reset): "
        + ", ".join(code(i) for i in access.OPERATORS) + ". A shore computer runs "
        + ", ".join(code(i) for i in access.SHORE_IDENTITIES) + ".\n",
    ])


def _doc(name: str) -> str:
    """The docstring that follows a module constant in ``seaway.contract.keys``."""
    return describe(constant_docs(keys).get(name, ""))


def _access_doc(name: str) -> str:
    return constant_docs(access).get(name, "")


def _role(identity: str) -> str:
    if identity == access.RELAY:
        return describe(_access_doc("RELAY"))
    if identity == "operator":
        return "the `seaway` operator commands (`mission`, `vehicle`, `health`, `echo`, ...)"
    if identity == "replay":
        return "`seaway replay`: republishes a recording's keys in the producers' place"
    if identity == "launcher":
        return "`seaway launch`: starts the processes, makes the start-up requests"
    return f"the {identity} service"
