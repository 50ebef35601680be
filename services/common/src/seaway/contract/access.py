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
  scenario, navigation reset): only the operator identities (:data:`OPERATORS`); and, in a stack
  made with ``ros2_writes``, the ROS 2 face (identity ``ros2``) the mission's requests alone
  (:data:`ROS2_REQUESTS`: a mission, pause/resume/abort), never arming, modes or resets;
* **declare** a health or lockstep-membership token: only the service it names (on a shore, as
  the shore's: ``health/shore-<service>``, ``keys.side_service``);
* **read** (subscribe, liveliness queries, the run descriptions and refusal counts): everyone in the
  stack.

What leaves a process (``egress``) is not restricted: the receiver decides. An identity without a
certificate from the stack's authority cannot connect at all.

**A boat and a shore** (``docs/deployment.md``) are two stacks of one authority, each with a Zenoh
router (identity :data:`RELAY`) that carries traffic over the link. Zenoh's access control sees only
the last hop, so whatever crosses the link arrives from the router. The rules of each side
(:func:`acl` with ``side``) give the router the rights of the *other side as a whole*:

* on the boat, the router may do what the shore may do there (:func:`_shore_rights`): read, ask the
  open requests and the actuating ones; never publish a key, serve a request or declare a token.
  The shore router checks the shore's own processes by name first (only its operators may actuate),
  so the chain is: shore operator -> shore router -> boat router -> boat service.
  Both routers are identity :data:`RELAY`, so the boat router's own rights (its health token, its
  refusal counts) and every other boat identity hold only over :data:`LOOPBACK`: over the link, a
  certificate of the authority is the shore's router or nothing (the shore could otherwise forge
  the boat router's health and refusals, or speak on the boat router as a boat service).
* on the shore, the router may publish and serve what the boat says; towards the router, the shore
  sends only what the boat accepts (the same :func:`_shore_rights`, as ``egress``), so nothing the
  boat would refuse crosses the link.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, Literal

from seaway.contract import keys

Side = Literal["local", "boat", "shore"]
SIDES: tuple[str, ...] = ("local", "boat", "shore")
"""``local``: one stack on one machine (no router); ``boat``/``shore``: the two halves of a deployment."""

OPERATORS: tuple[str, ...] = ("launcher", "operator", "groundstation")
"""Identities whose requests move the vessel or reset the stack: the launcher, the ``seaway``
operator commands and the ground station."""
TOOLS: tuple[str, ...] = ("operator", "replay")
"""Identities that are not services: the operator commands and ``seaway replay``."""
IDENTITIES: tuple[str, ...] = (*keys.SERVICES, *TOOLS)
"""Every identity a stack's authority issues a certificate to."""
RELAY = "router"
"""The identity of a side's Zenoh router (``seaway router``), the only process that crosses the link."""
SHORE_IDENTITIES: tuple[str, ...] = ("launcher", "recorder", RELAY, "operator", "groundstation")
"""The identities a shore computer runs (profile ``shore``, the operator commands, the ground station)."""
LOOPBACK = "lo"
"""The interface a boat's own processes link over (``boat-client.json5``): Linux's loopback."""
ROS2 = "ros2"
"""The ROS 2 face's identity (``seaway-ros2``, docs/ros2.md)."""
ROS2_REQUESTS: tuple[keys.KeySpec, ...] = (keys.MISSION_SET, keys.MISSION_COMMAND)
"""What the ROS 2 face may ask when the stack lets ROS 2 write (``acl(ros2_writes=True)``): a
mission and its pause/resume/abort, decided by the controller as an operator's are."""
ROS2_WRITES_POLICY = "ros2-writes"
"""The policy ``acl(ros2_writes=True)`` adds."""
HARNESS = "harness"
"""The test harness: may do everything. Issued only when asked for (tests, benchmarks); the
launcher never issues it."""

# Messages a reader needs: its subscriptions and liveliness interest must reach the producers.
_CACHE = "@adv"
"""zenoh-ext's chunk under a topic's key for its publisher's cache and liveliness token (a chunk
starting with @ is matched by no wildcard, so it is named)."""
_READ = ["declare_subscriber", "liveliness_query", "declare_liveliness_subscriber"]
_FROM_SHORE, _BOAT_VIA_ROUTER = "from-shore", "boat-via-router"
"""The policies only a boat's and only a shore's rules have (``side_of`` tells the side by them)."""
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


def _actuating() -> list[str]:
    return [_wild(s.suffix) for s in keys.REGISTRY if s.kind == "query"]


def _open_requests() -> list[str]:
    return [_wild(f"{keys.RUN}/*"), _wild(f"{keys.REFUSALS}/*")]


def _shore_rights(rid: str, flow: str) -> list[dict[str, Any]]:
    """What the shore may do on the boat: read, ask the open and the actuating requests."""
    return [_rule(f"{rid}-read", _READ, [f"{keys.ROOT}/**"], [flow]),
            _rule(f"{rid}-ask", ["query"], [*_open_requests(), *_actuating()], [flow])]


def side_identities(side: Side) -> tuple[str, ...]:
    """The identities a side's authority issues: every one on a boat or a single machine, the
    operator's few on a shore."""
    return SHORE_IDENTITIES if side == "shore" else IDENTITIES


def acl(overrides: Mapping[str, str] | None = None, *, harness: bool = False,
        side: Side = "local", ros2_writes: bool = False) -> dict[str, Any]:
    """The ``access_control`` section of every process's Zenoh config in one stack.

    ``overrides``: the profile's producers (:func:`producers`); ``harness``: admit the test
    harness identity with every right; ``side``: ``local`` for a stack alone on its machine, or the
    ``boat``/``shore`` half of a deployment, where the router (:data:`RELAY`) carries the other
    side (module docstring). ``ros2_writes``: the ROS 2 face may ask :data:`ROS2_REQUESTS`. The
    same document serves every process of a side, router included.
    """
    if side not in SIDES:
        raise AccessError(f"side {side!r} unknown; allowed: {', '.join(SIDES)}")
    who = producers(overrides)
    identities = [*side_identities(side), *([HARNESS] if harness else [])]
    senders = [i for i in identities if not (side == "shore" and i == RELAY)]
    rules = [
        _rule("read", _READ, [f"{keys.ROOT}/**"], ["ingress", "egress"]),
        # Open requests: the run descriptions and the refusal counts (read-only answers).
        _rule("ask-open", ["query"], _open_requests()),
        _rule("send", _EVERYTHING, ["**", f"**/{_CACHE}/**"], ["egress"]),
        # A late subscriber (a restarted recorder) finds the topics' caches and asks them.
        _rule("recall", ["query", *_READ], [f"{keys.ROOT}/**/{_CACHE}/**"], ["ingress", "egress"]),
        _rule("ask-actuate", ["query"], _actuating()),
    ]
    policies = [
        {"id": "stack", "rules": ["read", "ask-open", "recall"], "subjects": identities},
        {"id": "send", "rules": ["send"], "subjects": senders},
        {"id": "operators", "rules": ["ask-actuate"],
         "subjects": [i for i in (*OPERATORS, HARNESS) if i in identities]},
    ]
    if ros2_writes and ROS2 in identities:
        rules.append(_rule("ros2-ask", ["query"], [_wild(s.suffix) for s in ROS2_REQUESTS]))
        policies.append({"id": ROS2_WRITES_POLICY, "rules": ["ros2-ask"], "subjects": [ROS2]})
    if side == "boat":
        # What arrives from the router came from the shore: the shore's rights, nothing more.
        relay = _shore_rights(_FROM_SHORE, "ingress")
        rules += relay
        policies.append({"id": _FROM_SHORE, "rules": [r["id"] for r in relay], "subjects": [RELAY]})
    elif side == "shore":
        # What arrives from the router is the boat speaking; what goes to it, only what the boat
        # accepts from the shore (so nothing it would refuse crosses the link).
        relay = [_rule("from-boat", ["put", "delete", "reply", "declare_queryable", "liveliness_token"],
                       [f"{keys.ROOT}/**"]),
                 *_shore_rights("to-boat", "egress")]
        rules += relay
        policies.append({"id": _BOAT_VIA_ROUTER, "rules": [r["id"] for r in relay], "subjects": [RELAY]})
    for ident in identities:
        if ident == HARNESS:
            rules.append(_rule(f"all-{ident}", _EVERYTHING,
                               [f"{keys.ROOT}/**", f"{keys.ROOT}/**/{_CACHE}/**"]))
            policies.append({"id": ident, "rules": [f"all-{ident}"], "subjects": [ident]})
            continue
        mine_specs = [spec for spec in keys.REGISTRY if ident in who[spec.suffix]]
        topics = [_wild(spec.suffix) for spec in mine_specs if spec.kind == "topic"]
        topics.append(_wild(f"{keys.REFUSALS}/{ident}"))
        served = [_wild(spec.suffix) for spec in mine_specs if spec.kind == "query"]
        served += [_wild(f"{keys.RUN}/{ident}"), _wild(f"{keys.REFUSALS}/{ident}")]
        # A shore process's token is named as the shore's (keys.side_service), never the boat's.
        tokens = [_wild(f"{keys.HEALTH}/{keys.side_service(ident, side)}")] + [
            _wild(spec.suffix) for spec in mine_specs if spec.suffix.startswith("lockstep/")]
        caches = [f"{t}/{_CACHE}/**" for t in topics]
        mine = [f"pub-{ident}", f"serve-{ident}", f"alive-{ident}", f"cache-{ident}",
                f"recall-{ident}"]
        # Its topics' caches (zenoh-ext's advanced publisher): announced, and answered with the
        # samples kept, on the topic's own key.
        rules.append(_rule(mine[3], ["declare_queryable", "liveliness_token"], caches))
        rules.append(_rule(mine[4], ["reply"], [*caches, *topics]))
        rules.append(_rule(mine[1], ["declare_queryable", "reply"], served))
        rules.append(_rule(mine[2], ["liveliness_token"], tokens))
        rules.append(_rule(mine[0], ["put", "delete"], topics))
        policies.append({"id": ident, "rules": mine, "subjects": [ident]})
    subjects = [{"id": i, "cert_common_names": [i]} for i in identities]
    if side == "boat":
        # Zenoh matches a subject by certificate name AND interface: only the router arrives over
        # the link, and there it is the shore (its own rights are the onboard router's, on loopback).
        onboard = f"{RELAY}-onboard"
        subjects = [s if s["id"] == RELAY else {**s, "interfaces": [LOOPBACK]} for s in subjects]
        subjects.append({"id": onboard, "cert_common_names": [RELAY], "interfaces": [LOOPBACK]})
        for policy in policies:
            if policy["id"] == RELAY:
                policy["subjects"] = [onboard]
    # A policy names subjects by id: the stack-wide policies list every identity's subject.
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def side_of(rules: Mapping[str, Any]) -> Side:
    """The side whose rules ``rules`` (an ``acl`` document) are: what a process with them declares
    its health token as (``keys.side_service``)."""
    ids = {p.get("id") for p in rules.get("policies", []) if isinstance(p, Mapping)}
    if _BOAT_VIA_ROUTER in ids:
        return "shore"
    return "boat" if _FROM_SHORE in ids else "local"
