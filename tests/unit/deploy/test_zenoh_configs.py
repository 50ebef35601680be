"""The boat/shore Zenoh configs (deploy/zenoh/) and profiles: they parse, they fit together, and the
boat router's access control says what docs/deployment.md says, key by registered key.

The access-control checks evaluate the config's rules the way Zenoh documents them (explicit deny >
explicit allow > default; a rule's key expression must include the message's key). The system tests
(tests/system/deploy/) check the same policy against real routers.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import zenoh
from seaway.contract import keys
from seaway.tools.launch.profile import load_profile

REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"
ROUTERS = ["boat-router.json5", "boat-router-tls.json5", "shore-router.json5", "shore-router-tls.json5"]
CLIENTS = ["boat-client.json5", "shore-client.json5"]
BOAT_ROUTERS = ["boat-router.json5", "boat-router-tls.json5"]
SHORE_REQUESTS = {"mission/set", "mission/command", "vehicle/arm", "vehicle/mode"}


def conf(name: str) -> zenoh.Config:
    return zenoh.Config.from_file(str(ZENOH_DIR / name))


def get(name: str, key: str):
    return json.loads(conf(name).get_json(key))


def port_of(endpoint: str) -> tuple[str, int]:
    proto, _, rest = endpoint.partition("/")
    return proto, int(rest.rsplit(":", 1)[1].split("#")[0])


# -- a small evaluator of Zenoh access control, for concrete keys ------------------------------------


def ke_includes(pattern: str, key: str) -> bool:
    """Does key expression ``pattern`` (with * and **) include the concrete ``key``?"""
    rx = "/".join("(?:[^/]+)" if c == "*" else "(?:.*)" if c == "**" else re.escape(c)
                  for c in pattern.split("/"))
    rx = rx.replace("/(?:.*)", "(?:/.*)?").replace("(?:.*)/", "(?:.*/)?")
    return re.fullmatch(rx, key) is not None


class Acl:
    def __init__(self, name: str) -> None:
        self.doc = get(name, "access_control")
        self.rules = {r["id"]: r for r in self.doc["rules"]}

    def decide(self, subject: str, flow: str, message: str, key: str) -> bool:
        decisions = set()
        for policy in self.doc["policies"]:
            if subject not in policy["subjects"]:
                continue
            for rid in policy["rules"]:
                r = self.rules[rid]
                if (flow in r.get("flows", ["ingress", "egress"]) and message in r["messages"]
                        and any(ke_includes(p, key) for p in r["key_exprs"])):
                    decisions.add(r["permission"])
        if "deny" in decisions:
            return False
        if "allow" in decisions:
            return True
        return self.doc["default_permission"] == "allow"


def test_key_expression_inclusion_helper() -> None:
    assert ke_includes("**", "seaway/v/ctrl/thrust")
    assert ke_includes("seaway/**", "seaway/v/ctrl/thrust")
    assert ke_includes("seaway/*/ctrl/thrust", "seaway/v/ctrl/thrust")
    assert ke_includes("seaway/*/shore/**", "seaway/v/shore/heartbeat")
    assert not ke_includes("seaway/*/shore/**", "seaway/v/ctrl/thrust")
    assert not ke_includes("seaway/*/mission/set", "seaway/v/mission/status")
    assert not ke_includes("seaway/*/ctrl/thrust", "seaway/a/b/ctrl/thrust")


# -- every file ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROUTERS + CLIENTS)
def test_config_parses_with_zenoh(name: str) -> None:
    c = conf(name)
    assert json.loads(c.get_json("mode")) == ("router" if "router" in name else "peer")
    assert json.loads(c.get_json("scouting/multicast/enabled")) is False, "multicast must stay off"


def test_every_zenoh_file_is_known_here() -> None:
    assert sorted(p.name for p in ZENOH_DIR.glob("*.json5")) == sorted(ROUTERS + CLIENTS)


@pytest.mark.parametrize("name", CLIENTS)
def test_services_are_loopback_peers_that_retry_their_router(name: str) -> None:
    assert all(e.startswith("tcp/127.0.0.1:") for e in get(name, "listen/endpoints"))
    connect = get(name, "connect/endpoints")
    assert len(connect) == 1 and connect[0].startswith("tcp/127.0.0.1:")
    assert get(name, "connect/timeout_ms") == -1 and get(name, "connect/exit_on_failure") is False
    # peers find each other through the router but never connect to a router they hear of
    assert get(name, "scouting/gossip/autoconnect") == ["peer"]


@pytest.mark.parametrize("name", ROUTERS)
def test_routers_gossip_only_to_their_own_peers(name: str) -> None:
    assert get(name, "scouting/gossip/target") == ["peer"]
    assert get(name, "transport/link/tx/lease") <= 5000, "a dead link must be noticed within seconds"


@pytest.mark.parametrize("router", BOAT_ROUTERS)
def test_boat_services_reach_the_boat_router(router: str) -> None:
    _, client_port = port_of(get("boat-client.json5", "connect/endpoints")[0])
    local = [e for e in get(router, "listen/endpoints") if e.startswith("tcp/")]
    assert any(port_of(e)[1] == client_port for e in local), (router, local)


@pytest.mark.parametrize("router", ["shore-router.json5", "shore-router-tls.json5"])
def test_shore_services_reach_the_shore_router_and_it_reaches_the_boat(router: str) -> None:
    _, client_port = port_of(get("shore-client.json5", "connect/endpoints")[0])
    assert [port_of(e) for e in get(router, "listen/endpoints")] == [("tcp", client_port)]
    assert get(router, "listen/endpoints")[0].startswith("tcp/127.0.0.1:"), "the shore router is local"
    boat = router.replace("shore", "boat")
    (target,) = get(router, "connect/endpoints")
    assert port_of(target) in [port_of(e) for e in get(boat, "listen/endpoints")]
    assert get(router, "connect/timeout_ms") == -1 and get(router, "connect/exit_on_failure") is False
    assert get(router, "connect/retry")["period_max_ms"] <= 2000


def test_boat_and_shore_can_share_one_computer_for_a_dry_run() -> None:
    boat = {port_of(e)[1] for r in BOAT_ROUTERS for e in get(r, "listen/endpoints")}
    shore = {port_of(e)[1] for r in ["shore-router.json5", "shore-router-tls.json5"]
             for e in get(r, "listen/endpoints")}
    assert not boat & shore


def test_tls_configs_use_mutual_tls_and_only_tls_on_the_link() -> None:
    boat, shore = "boat-router-tls.json5", "shore-router-tls.json5"
    assert get(boat, "transport/link/tls/enable_mtls") is True
    assert get(shore, "transport/link/tls/enable_mtls") is True
    assert get(shore, "transport/link/tls/verify_name_on_connect") is True
    link = [e for e in get(boat, "listen/endpoints") if not e.startswith("tcp/127.0.0.1:")]
    assert link and all(e.startswith("tls/") for e in link)
    assert all(e.startswith("tls/") for e in get(shore, "connect/endpoints"))
    for name, files in [(boat, ("root_ca_certificate", "listen_certificate", "listen_private_key")),
                        (shore, ("root_ca_certificate", "connect_certificate", "connect_private_key"))]:
        for key in files:
            assert get(name, f"transport/link/tls/{key}").startswith("/etc/seaway/tls/"), (name, key)


# -- access control -------------------------------------------------------------------------------


def shore_subject(router: str) -> str:
    return "anyone" if router == "boat-router.json5" else "shore"


def test_acl_subjects() -> None:
    def subjects(name: str) -> dict[str, dict]:  # zenoh fills absent properties with null
        return {s["id"]: {k: v for k, v in s.items() if v is not None}
                for s in get(name, "access_control/subjects")}

    plain = subjects("boat-router.json5")
    assert plain["boat"] == {"id": "boat", "interfaces": ["lo"]}
    assert plain["anyone"] == {"id": "anyone"}, "plain TCP: everyone off loopback is the shore"
    tls = subjects("boat-router-tls.json5")
    assert tls["shore"]["cert_common_names"] == ["seaway-shore"]
    assert tls["shore"]["link_protocols"] == ["tls"]
    assert tls["boat"]["link_protocols"] == ["tcp"] and tls["boat"]["interfaces"] == ["lo"]


@pytest.mark.parametrize("router", BOAT_ROUTERS)
def test_acl_default_deny_and_the_boat_may_do_everything(router: str) -> None:
    acl = Acl(router)
    assert acl.doc["enabled"] is True and acl.doc["default_permission"] == "deny"
    for spec in keys.REGISTRY:
        for msg in ("put", "declare_subscriber", "query", "reply", "declare_queryable"):
            for flow in ("ingress", "egress"):
                assert acl.decide("boat", flow, msg, spec.key("vessel1")), (spec.suffix, msg, flow)
    assert acl.decide("boat", "ingress", "liveliness_token", keys.health_key("vessel1", "controller"))


@pytest.mark.parametrize("router", BOAT_ROUTERS)
def test_acl_the_shore_may_not_publish_any_boat_key(router: str) -> None:
    acl, who = Acl(router), shore_subject(router)
    for spec in keys.REGISTRY:
        key = spec.key("vessel1")
        if spec.kind == "topic":
            assert not acl.decide(who, "ingress", "put", key), f"shore may publish {spec.suffix}"
            assert not acl.decide(who, "ingress", "delete", key)
            assert acl.decide(who, "ingress", "declare_subscriber", key), f"shore cannot see {spec.suffix}"
            assert acl.decide(who, "egress", "put", key), f"the boat cannot send {spec.suffix} ashore"
        else:
            assert not acl.decide(who, "ingress", "declare_queryable", key), \
                f"shore could answer the boat's {spec.suffix} requests"
    assert not acl.decide(who, "ingress", "put", "seaway/vessel1/ctrl/thrust")


@pytest.mark.parametrize("router", BOAT_ROUTERS)
def test_acl_the_shore_may_send_the_operator_requests_only(router: str) -> None:
    acl, who = Acl(router), shore_subject(router)
    queries = {s.suffix for s in keys.REGISTRY if s.kind == "query"}
    assert queries >= SHORE_REQUESTS
    for suffix in queries:
        allowed = acl.decide(who, "ingress", "query", f"seaway/vessel1/{suffix}")
        assert allowed == (suffix in SHORE_REQUESTS), suffix
        if allowed:
            assert acl.decide(who, "egress", "reply", f"seaway/vessel1/{suffix}")


@pytest.mark.parametrize("router", BOAT_ROUTERS)
def test_acl_shore_namespace_health_and_liveliness(router: str) -> None:
    acl, who = Acl(router), shore_subject(router)
    assert acl.decide(who, "ingress", "put", "seaway/vessel1/shore/heartbeat")
    assert not any(s.suffix.startswith("shore/") for s in keys.REGISTRY), \
        "seaway/<vessel>/shore/** is the shore's; no boat key may live there"
    health = keys.health_key("vessel1", "recorder")
    assert not acl.decide(who, "ingress", "liveliness_token", health), "shore health on the boat"
    assert acl.decide(who, "egress", "liveliness_token", health), "the shore must see the boat's health"
    assert acl.decide(who, "ingress", "declare_liveliness_subscriber", keys.health_key("vessel1", "sim"))
    assert acl.decide(who, "ingress", "liveliness_query", health)


# -- profiles -------------------------------------------------------------------------------------


@pytest.mark.parametrize("role", ["boat", "shore"])
def test_profile_starts_its_router_first(role: str) -> None:
    profile = load_profile(role)
    assert profile.zenoh_config == f"{role}-client.json5"
    assert (ZENOH_DIR / profile.zenoh_config).is_file()
    router, *others = profile.processes
    assert router.command[:4] == ["seaway", "router", "--role", role]
    assert router.service == "router"
    assert router.command[router.command.index("--health") + 1] == router.service
    assert router.restart == "on-failure" and router.required
    by_name = {p.name: p for p in profile.processes}

    def depends_on_router(name: str) -> bool:
        return any(a == "router" or depends_on_router(a) for a in by_name[name].after)

    assert others and all(depends_on_router(p.name) for p in others)


def test_shore_profile_sends_nothing_and_produces_no_boat_key() -> None:
    profile = load_profile("shore")
    assert not profile.mission_on_start
    assert not getattr(profile, "arm_on_start", False)
    assert not getattr(profile, "mode_on_start", None)
    assert all(p.produced_keys() == [] for p in profile.processes)


def test_boat_profile_runs_the_onboard_loop_and_waits_for_a_mission() -> None:
    profile = load_profile("boat")
    services = {p.service for p in profile.processes}
    assert {"recorder", "vehicle_io", "estimator", "controller"} <= services
    assert not profile.mission_on_start and not profile.stop_when_complete
