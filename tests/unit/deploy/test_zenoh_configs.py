"""The boat/shore Zenoh configs (deploy/zenoh/) and profiles: they parse, they fit together, every
link is mutual TLS, and what each process actually runs is that file plus its side's certificate and
the side's access rules generated from the key registry (``seaway.contract.access``; what those
rules allow is checked key by key in tests/unit/common/test_access.py, and against real routers in
tests/system/deploy/).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zenoh
from seaway.contract import access
from seaway.runtime import credentials
from seaway.runtime.zenoh_bus import load_zenoh_config
from seaway.tools.launch.profile import load_profile
from seaway.tools.router import build_config

REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"
ROUTERS = ["boat-router.json5", "shore-router.json5"]
CLIENTS = ["boat-client.json5", "shore-client.json5"]
SIDES = ["boat", "shore"]


def conf(name: str) -> zenoh.Config:
    return zenoh.Config.from_file(str(ZENOH_DIR / name))


def get(name_or_conf: str | zenoh.Config, key: str):
    c = conf(name_or_conf) if isinstance(name_or_conf, str) else name_or_conf
    return json.loads(c.get_json(key))


def compact(doc):
    """A config section as written: Zenoh fills every property left out with null."""
    if isinstance(doc, dict):
        return {k: compact(v) for k, v in doc.items() if v is not None}
    if isinstance(doc, list):
        return [compact(v) for v in doc]
    return doc


def port_of(endpoint: str) -> tuple[str, int]:
    proto, _, rest = endpoint.partition("/")
    return proto, int(rest.rsplit(":", 1)[1].split("#")[0])


def host_of(endpoint: str) -> str:
    return endpoint.partition("/")[2].rsplit(":", 1)[0]


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory) -> dict[str, credentials.Credentials]:
    return credentials.create_deployment(tmp_path_factory.mktemp("dep") / "seaway-credentials")


# -- every file ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROUTERS + CLIENTS)
def test_config_parses_with_zenoh(name: str) -> None:
    c = conf(name)
    assert json.loads(c.get_json("mode")) == ("router" if "router" in name else "peer")
    assert json.loads(c.get_json("scouting/multicast/enabled")) is False, "multicast must stay off"


def test_every_zenoh_file_is_known_here() -> None:
    assert sorted(p.name for p in ZENOH_DIR.glob("*.json5")) == sorted(ROUTERS + CLIENTS)


@pytest.mark.parametrize("name", ROUTERS + CLIENTS)
def test_every_link_is_tls_and_the_files_name_no_certificate_and_no_rules(name: str) -> None:
    """Plain TCP is gone; the certificate files and the access rules come from the side's
    credentials folder (never written in a shipped file, where they would go stale)."""
    endpoints = [*get(name, "listen/endpoints"), *get(name, "connect/endpoints")]
    assert endpoints and all(e.startswith("tls/") for e in endpoints), endpoints
    tls = get(name, "transport/link/tls")
    assert not [k for k, v in tls.items() if k.endswith(("certificate", "private_key")) and v], tls
    assert get(name, "access_control/enabled") is False, "the rules are generated, not shipped"


@pytest.mark.parametrize("name", CLIENTS)
def test_services_are_loopback_peers_that_retry_their_router(name: str) -> None:
    assert all(e.startswith("tls/127.0.0.1:") for e in get(name, "listen/endpoints"))
    connect = get(name, "connect/endpoints")
    assert len(connect) == 1 and connect[0].startswith("tls/127.0.0.1:")
    assert get(name, "connect/timeout_ms") == -1 and get(name, "connect/exit_on_failure") is False
    # peers find each other through the router but never connect to a router they hear of
    assert get(name, "scouting/gossip/autoconnect") == ["peer"]


@pytest.mark.parametrize("name", ROUTERS)
def test_routers_gossip_only_to_their_own_peers(name: str) -> None:
    assert get(name, "scouting/gossip/target") == ["peer"]
    assert get(name, "transport/link/tx/lease") <= 5000, "a dead link must be noticed within seconds"
    assert get(name, "transport/unicast/open_timeout") <= 5000, "an attempt on a dead link must end"


def test_boat_services_reach_the_boat_router_on_loopback_and_only_the_link_port_is_open() -> None:
    _, client_port = port_of(get("boat-client.json5", "connect/endpoints")[0])
    listen = get("boat-router.json5", "listen/endpoints")
    local = [e for e in listen if host_of(e) == "127.0.0.1"]
    assert [port_of(e)[1] for e in local] == [client_port]
    link = [e for e in listen if e not in local]
    assert len(link) == 1 and port_of(link[0])[1] != client_port, "one port for the shore, not the peers'"
    assert get("boat-router.json5", "connect/endpoints") == [], "the boat connects to nobody"


def test_shore_services_reach_the_shore_router_and_it_reaches_the_boat_link_port() -> None:
    _, client_port = port_of(get("shore-client.json5", "connect/endpoints")[0])
    listen = get("shore-router.json5", "listen/endpoints")
    assert [port_of(e) for e in listen] == [("tls", client_port)]
    assert host_of(listen[0]) == "127.0.0.1", "the shore router is local"
    (target,) = get("shore-router.json5", "connect/endpoints")
    (link,) = [e for e in get("boat-router.json5", "listen/endpoints") if host_of(e) != "127.0.0.1"]
    assert port_of(target) == port_of(link)
    assert host_of(target) in credentials.DEFAULT_BOAT_HOSTS, "the name the boat router's certificate has"
    assert get("shore-router.json5", "connect/timeout_ms") == -1
    assert get("shore-router.json5", "connect/exit_on_failure") is False
    assert get("shore-router.json5", "connect/retry")["period_max_ms"] <= 2000


def test_boat_and_shore_can_share_one_computer_for_a_dry_run() -> None:
    boat = {port_of(e)[1] for e in get("boat-router.json5", "listen/endpoints")}
    shore = {port_of(e)[1] for e in get("shore-router.json5", "listen/endpoints")}
    assert not boat & shore


# -- what each process runs: the file, its certificate, its side's rules --------------------------------


@pytest.mark.parametrize("side", SIDES)
def test_a_router_runs_as_identity_router_with_its_sides_rules(
        side: str, deployment: dict[str, credentials.Credentials]) -> None:
    made = deployment[side]
    c, settings = build_config(ZENOH_DIR / f"{side}-router.json5", credentials=made)
    assert get(c, "transport/link/tls/root_ca_certificate") == str(made.folder / "ca.pem")
    for role in ("listen", "connect"):
        assert get(c, f"transport/link/tls/{role}_certificate") == str(made.folder / "router.pem")
        assert get(c, f"transport/link/tls/{role}_private_key") == str(made.folder / "router-key.pem")
    # a connecting router shows its certificate only with mTLS on its own side too
    assert get(c, "transport/link/tls/enable_mtls") is True
    assert compact(get(c, "access_control")) == access.acl(side=side)
    assert settings.mtls and settings.access_control
    assert get(c, "transport/link/tx/lease") == get(f"{side}-router.json5", "transport/link/tx/lease")


@pytest.mark.parametrize("side", SIDES)
def test_a_sides_processes_run_as_themselves_with_the_same_rules(
        side: str, deployment: dict[str, credentials.Credentials]) -> None:
    made = deployment[side]
    for ident in access.side_identities(side):
        c = load_zenoh_config(ZENOH_DIR / f"{side}-client.json5", ident, made)
        assert get(c, "transport/link/tls/connect_certificate") == str(made.folder / f"{ident}.pem")
        assert compact(get(c, "access_control")) == access.acl(side=side)
        assert get(c, "connect/endpoints") == get(f"{side}-client.json5", "connect/endpoints")


def test_a_tls_client_config_refuses_to_run_without_credentials(
        deployment: dict[str, credentials.Credentials]) -> None:
    with pytest.raises(credentials.CredentialsError, match=r"links over TLS.*--deployment"):
        load_zenoh_config(ZENOH_DIR / "boat-client.json5", "controller", credentials.NONE)
    # the shore folder has no boat service in it
    with pytest.raises(credentials.CredentialsError, match=r"no controller\.pem.*there: .*operator"):
        load_zenoh_config(ZENOH_DIR / "shore-client.json5", "controller", deployment["shore"])


# -- profiles -------------------------------------------------------------------------------------


@pytest.mark.parametrize("role", SIDES)
def test_profile_is_one_side_and_starts_its_router_first(role: str) -> None:
    profile = load_profile(role)
    assert profile.side == role, "a deployment profile needs that side's credentials"
    assert profile.zenoh_config == f"{role}-client.json5"
    assert (ZENOH_DIR / profile.zenoh_config).is_file()
    router, *others = profile.processes
    assert router.command[:4] == ["seaway", "router", "--role", role]
    assert "--credentials" not in router.command, "the router takes the launcher's $SEAWAY_CREDENTIALS"
    assert router.service == "router"
    assert router.command[router.command.index("--health") + 1] == router.service
    assert router.restart == "on-failure" and router.required
    by_name = {p.name: p for p in profile.processes}

    def depends_on_router(name: str) -> bool:
        return any(a == "router" or depends_on_router(a) for a in by_name[name].after)

    assert others and all(depends_on_router(p.name) for p in others)
    # every process the profile runs has a certificate on its side
    assert {p.service for p in profile.processes} <= set(access.side_identities(role))


def test_the_other_profiles_are_a_stack_alone() -> None:
    for name in ("sim", "sim-batch", "replay"):
        assert load_profile(name).side == "local", name


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
