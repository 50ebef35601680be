"""Who may do what on the bus: identities and the Zenoh access rules, generated from the key registry.

Every process of a stack has an identity (the common name of its certificate,
``seaway.runtime.credentials``): a service's own name, or one of the tools below. The rules are
Zenoh's own access control (``access_control`` in a Zenoh config), enforced by each receiving
process on what arrives from each other process (``ingress``), so a forged message is dropped by
Zenoh before any Seaway code sees it:

* **publish** a key (put/delete): only its producer (``KeySpec.producers``, narrowed by the
  profile to exactly one);
* **serve** a request (declare the queryable, send its replies): only the key's producer;
* **ask** a request that actuates or resets (every registered ``query`` key: arm, mode, mission,
  scenario, navigation reset): only the operator identities (:data:`OPERATORS`);
* **declare** a health or lockstep-membership token: only the service it names;
* **read** (subscribe, liveliness queries, the run descriptions and refusal counts): everyone in the
  stack.

What leaves a process (``egress``) is not restricted: the receiver decides. An identity without a
certificate from the stack's authority cannot connect at all.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from seaway.contract import keys

OPERATORS: tuple[str, ...] = ("launcher", "operator", "groundstation")
"""Identities whose requests move the vessel or reset the stack: the launcher, the ``seaway``
operator commands and the ground station."""
TOOLS: tuple[str, ...] = ("operator", "replay")
"""Identities that are not services: the operator commands and ``seaway replay``."""
IDENTITIES: tuple[str, ...] = (*keys.SERVICES, *TOOLS)
"""Every identity a stack's authority issues a certificate to."""
HARNESS = "harness"
"""The test harness: may do everything. Issued only when asked for (tests, benchmarks); the
launcher never issues it."""

# Messages a reader needs: its subscriptions and liveliness interest must reach the producers.
_READ = ["declare_subscriber", "liveliness_query", "declare_liveliness_subscriber"]
_EVERYTHING = ["put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
               "liveliness_token", "liveliness_query", "declare_liveliness_subscriber"]


class AccessError(ValueError):
    """A producer assignment the registry does not allow."""


def producers(overrides: Mapping[str, str] | None = None) -> dict[str, tuple[str, ...]]:
    """Who may produce each registered key: ``suffix -> identities``.

    Without ``overrides`` every producer the registry allows; ``overrides`` (``suffix -> identity``,
    a profile's ``produces``) narrows a key to the one identity the profile runs, which must be
    one of the registry's.
    """
    out = {spec.suffix: spec.producers for spec in keys.REGISTRY}
    for suffix, identity in (overrides or {}).items():
        spec = keys.spec_for_suffix(suffix)
        if spec is None:
            raise AccessError(f"{suffix!r} is not a registered key")
        if identity not in spec.producers:
            raise AccessError(f"{identity!r} may not produce {suffix!r}; its producers are "
                              f"{', '.join(spec.producers)}")
        out[suffix] = (identity,)
    return out


def _wild(suffix: str) -> str:
    return f"{keys.ROOT}/*/{suffix}"


def _rule(rid: str, messages: list[str], exprs: Iterable[str],
          flows: list[str] | None = None) -> dict[str, Any]:
    return {"id": rid, "permission": "allow", "flows": flows or ["ingress"], "messages": messages,
            "key_exprs": sorted(set(exprs))}


def acl(overrides: Mapping[str, str] | None = None, *, harness: bool = False) -> dict[str, Any]:
    """The ``access_control`` section of every process's Zenoh config in one stack.

    ``overrides``: the profile's producers (:func:`producers`); ``harness``: admit the test
    harness identity with every right.
    """
    who = producers(overrides)
    identities = [*IDENTITIES, *([HARNESS] if harness else [])]
    rules = [
        _rule("read", _READ, [f"{keys.ROOT}/**"], ["ingress", "egress"]),
        # Open requests: the run descriptions and the refusal counts (read-only answers).
        _rule("ask-open", ["query"], [_wild(f"{keys.RUN}/*"), _wild(f"{keys.REFUSALS}/*")]),
        _rule("send", _EVERYTHING, ["**"], ["egress"]),
        _rule("ask-actuate", ["query"], [_wild(s.suffix) for s in keys.REGISTRY if s.kind == "query"]),
    ]
    policies = [
        {"id": "stack", "rules": ["read", "ask-open", "send"], "subjects": identities},
        {"id": "operators", "rules": ["ask-actuate"],
         "subjects": [*OPERATORS, *([HARNESS] if harness else [])]},
    ]
    for ident in identities:
        if ident == HARNESS:
            rules.append(_rule(f"all-{ident}", _EVERYTHING, [f"{keys.ROOT}/**"]))
            policies.append({"id": ident, "rules": [f"all-{ident}"], "subjects": [ident]})
            continue
        mine_specs = [spec for spec in keys.REGISTRY if ident in who[spec.suffix]]
        topics = [_wild(spec.suffix) for spec in mine_specs if spec.kind == "topic"]
        topics.append(_wild(f"{keys.REFUSALS}/{ident}"))
        served = [_wild(spec.suffix) for spec in mine_specs if spec.kind == "query"]
        served += [_wild(f"{keys.RUN}/{ident}"), _wild(f"{keys.REFUSALS}/{ident}")]
        tokens = [_wild(f"{keys.HEALTH}/{ident}")] + [_wild(spec.suffix) for spec in mine_specs
                                                       if spec.suffix.startswith("lockstep/")]
        mine = [f"pub-{ident}", f"serve-{ident}", f"alive-{ident}"]
        rules.append(_rule(mine[1], ["declare_queryable", "reply"], served))
        rules.append(_rule(mine[2], ["liveliness_token"], tokens))
        rules.append(_rule(mine[0], ["put", "delete"], topics))
        policies.append({"id": ident, "rules": mine, "subjects": [ident]})
    subjects = [{"id": i, "cert_common_names": [i]} for i in identities]
    # A policy names subjects by id: the stack-wide policies list every identity's subject.
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}
