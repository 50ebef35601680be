"""The access rules generated from the key registry (a stack alone, a boat and its shore), and the
credentials folders (one stack's, a deployment's) with their safety checks.

The rules are evaluated here the way Zenoh evaluates them (allow-rules of the policies whose
subjects match by certificate name and interface, default deny), on the generated document itself,
so a change of the generator that would let a non-producer publish, a non-operator actuate or the
shore speak for the boat fails here; the system tests (tests/system/launch/test_authority.py,
tests/system/deploy/test_router_tls.py) show Zenoh enforcing the same documents.
"""

from __future__ import annotations

import datetime
import fnmatch
import json
import os
import stat

import pytest
import zenoh
from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.x509.oid import NameOID
from seaway.contract import access, keys
from seaway.runtime import credentials


def allowed(rules: dict, identity: str, message: str, key: str, flow: str = "ingress",
            interface: str = access.LOOPBACK) -> bool:
    """Zenoh's verdict for a remote whose certificate names ``identity``, linked over ``interface``:
    a subject matches when every property it lists does (name and interface)."""
    by_id = {r["id"]: r for r in rules["rules"]}
    subjects = {s["id"] for s in rules["subjects"]
                if identity in s["cert_common_names"] and interface in s.get("interfaces", [interface])}
    for policy in rules["policies"]:
        if not subjects & set(policy["subjects"]):
            continue
        for rid in policy["rules"]:
            r = by_id[rid]
            if flow in r["flows"] and message in r["messages"] and any(
                    fnmatch.fnmatchcase(key, e.replace("**", "\0").replace("*", "[!/]*").replace("\0", "*"))
                    for e in r["key_exprs"]):
                return True
    return False


RULES = access.acl()


@pytest.mark.parametrize("spec", [s for s in keys.REGISTRY if s.kind == "topic"], ids=lambda s: s.suffix)
def test_only_a_keys_producers_may_publish_it(spec):
    key = spec.key("vessel1")
    for ident in access.IDENTITIES:
        assert allowed(RULES, ident, "put", key) == (ident in spec.producers), (ident, key)


@pytest.mark.parametrize("spec", [s for s in keys.REGISTRY if s.kind == "query"], ids=lambda s: s.suffix)
def test_only_operators_actuate_and_only_the_owner_serves(spec):
    key = spec.key("vessel1")
    for ident in access.IDENTITIES:
        assert allowed(RULES, ident, "query", key) == (ident in access.OPERATORS), (ident, key)
        assert allowed(RULES, ident, "declare_queryable", key) == (ident == spec.producer)
        assert allowed(RULES, ident, "reply", key) == (ident == spec.producer)


def test_health_tokens_only_from_the_service_they_name_and_reading_is_open():
    for service in keys.SERVICES:
        key = keys.health_key("vessel1", service)
        for ident in access.IDENTITIES:
            assert allowed(RULES, ident, "liveliness_token", key) == (ident == service)
            assert allowed(RULES, ident, "declare_subscriber", key)
    assert allowed(RULES, "replay", "query", keys.run_description_key("vessel1", "controller"))
    assert not allowed(RULES, "harness", "put", keys.THRUST.key("vessel1"))  # not issued here
    assert allowed(access.acl(harness=True), "harness", "put", keys.THRUST.key("vessel1"))
    # Unknown identities (no certificate of this authority) get nothing, not even reading.
    assert not allowed(RULES, "mallory", "declare_subscriber", keys.NAV_STATE.key("vessel1"))


def test_a_profile_narrows_a_key_to_one_producer_and_only_to_a_registered_one():
    narrowed = access.acl({"sensors/gnss": "sim"})
    key = keys.GNSS.key("vessel1")
    assert allowed(narrowed, "sim", "put", key)
    assert not allowed(narrowed, "vehicle_io", "put", key)
    assert not allowed(narrowed, "replay", "put", key)
    with pytest.raises(access.AccessError, match=r"'estimator' may not produce 'ctrl/thrust'.*controller"):
        access.producers({"ctrl/thrust": "estimator"})
    with pytest.raises(access.AccessError, match=r"not a registered key"):
        access.producers({"ctrl/nonsense": "controller"})


def test_zenoh_accepts_the_generated_rules_and_tls_settings(tmp_path):
    made = credentials.create(tmp_path / "c", producers={"sensors/gnss": "sim"}, harness=True)
    conf = zenoh.Config()
    for key, value in made.zenoh_settings("controller").items():
        import json

        conf.insert_json5(key, json.dumps(value))  # raises on a field Zenoh does not know


def test_a_credentials_folder_open_to_others_or_missing_an_identity_is_refused(tmp_path):
    made = credentials.create(tmp_path / "c")
    made.check("controller")
    assert stat.S_IMODE((made.folder / "controller-key.pem").stat().st_mode) == 0o600
    with pytest.raises(credentials.CredentialsError, match=r"identities there: .*controller"):
        made.check("harness")  # not issued without harness=True
    os.chmod(made.folder, 0o755)
    with pytest.raises(credentials.CredentialsError, match=r"open to other users.*chmod 700"):
        made.check("controller")
    os.chmod(made.folder, 0o700)
    os.chmod(made.folder / "sim-key.pem", 0o644)
    with pytest.raises(credentials.CredentialsError, match=r"readable by other users.*0600"):
        made.check("sim")
    with pytest.raises(credentials.CredentialsError, match=r"does not exist.*seaway credentials create"):
        credentials.Credentials(tmp_path / "nowhere").check("sim")


# -- a boat and its shore (access.acl(side=...)) -------------------------------------------------------

BOAT = access.acl(side="boat")
SHORE = access.acl(side="shore")
LINK = "wlan0"  # any interface but loopback: how the shore router reaches the boat router
READS = ("declare_subscriber", "liveliness_query", "declare_liveliness_subscriber")
SENDS = ("put", "delete", "reply", "declare_queryable", "liveliness_token")
MESSAGES = (*READS, *SENDS, "query")
V = "vessel1"


def every_key() -> list[str]:
    """Every concrete key a stack uses: the registry's, and each identity's health, run and refusals."""
    out = [spec.key(V) for spec in keys.REGISTRY]
    out += [keys.health_key(V, s) for s in keys.SERVICES]
    out += [keys.run_description_key(V, s) for s in keys.SERVICES]
    out += [keys.refusals_key(V, i) for i in (*access.IDENTITIES, access.HARNESS)]
    return out


def asks() -> list[str]:
    """The requests the shore may ask: the open ones and every actuating one."""
    return [spec.key(V) for spec in keys.REGISTRY if spec.kind == "query"] + [
        keys.run_description_key(V, "controller"), keys.refusals_key(V, "vehicle_io")]


def test_a_certificate_past_its_end_is_refused_before_any_link_is_tried(tmp_path):
    """TLS would refuse every link of an expired certificate, and the process would wait for a
    stack it never joins with nothing in its log to say why: the check names the file, its end and
    the clock, and what to do."""
    ended = credentials.create(tmp_path / "ended", days=-1)
    with pytest.raises(credentials.CredentialsError) as err:
        ended.check("controller")
    end = _cert(ended.folder / "ca.pem").not_valid_after_utc
    assert "ca.pem" in str(err.value) and f"{end:%Y-%m-%d}" in str(err.value)
    assert "credentials create" in str(err.value)
    from seaway.tools import credentials_cli

    assert credentials_cli.main(["show", str(ended.folder)]) == 1  # NOT USABLE
    current = credentials.create(tmp_path / "current", days=1)
    current.check("controller")  # a day left: usable
    assert current.ends("controller") == min(_cert(current.folder / n).not_valid_after_utc
                                             for n in ("ca.pem", "controller.pem"))


def test_a_side_must_be_known():
    with pytest.raises(access.AccessError, match=r"side 'ship' unknown; allowed: local, boat, shore"):
        access.acl(side="ship")  # type: ignore[arg-type]


@pytest.mark.parametrize("interface", [LINK, access.LOOPBACK])
def test_on_the_boat_the_router_reads_and_asks_but_never_speaks_for_the_boat(interface):
    """What crosses the link arrives from the boat router: it carries the shore's rights and no more
    (over loopback, also the onboard router's own health token and refusal counts)."""
    router = access.RELAY
    onboard = interface == access.LOOPBACK
    own = {keys.health_key(V, router), keys.refusals_key(V, router)} if onboard else set()
    for key in every_key():
        for message in READS:
            assert allowed(BOAT, router, message, key, interface=interface), (message, key)
        for message in ("put", "delete"):
            assert allowed(BOAT, router, message, key, interface=interface) == (
                key == keys.refusals_key(V, router) and key in own), (message, key)
        assert allowed(BOAT, router, "liveliness_token", key, interface=interface) == (
            key == keys.health_key(V, router) and key in own), key
    served = {keys.run_description_key(V, router), keys.refusals_key(V, router)}
    for key in every_key():
        for message in ("declare_queryable", "reply"):
            assert allowed(BOAT, router, message, key, interface=interface) == (
                interface == access.LOOPBACK and key in served), (message, key)
    for key in asks():
        assert allowed(BOAT, router, "query", key, interface=interface), key
    # the boat sends the shore everything it says
    for key in every_key():
        for message in (*SENDS, *READS, "query"):
            assert allowed(BOAT, router, message, key, flow="egress", interface=interface)


def test_on_the_boat_every_other_identity_exists_on_loopback_only():
    """Over the link a certificate of the authority is the shore's router or nothing: a shore
    computer's operator or recorder certificate (the same names as the boat's) gets nothing there."""
    for ident in (*access.IDENTITIES, access.HARNESS):
        if ident == access.RELAY:
            continue
        for key in every_key():
            for message in MESSAGES:
                for flow in ("ingress", "egress"):
                    assert not allowed(BOAT, ident, message, key, flow, interface=LINK), (ident, message, key)
    # ...while on loopback the boat's processes have exactly the rules of a stack alone.
    for ident in access.IDENTITIES:
        if ident == access.RELAY:
            continue
        for key in every_key():
            for message in MESSAGES:
                assert allowed(BOAT, ident, message, key) == allowed(RULES, ident, message, key), \
                    (ident, message, key)


def test_on_the_shore_the_router_is_the_boat_speaking():
    router = access.RELAY
    for key in every_key():
        for message in (*SENDS, *READS):
            assert allowed(SHORE, router, message, key, interface=LINK), (message, key)
    # it may ask the open requests; nothing on the shore serves an actuating one, nor may ask it
    for key in asks():
        actuating = keys.spec_for_suffix(key.split("/", 2)[2]) is not None
        assert allowed(SHORE, router, "query", key, interface=LINK) == (not actuating), key


def test_the_shore_sends_the_boat_exactly_what_the_boat_accepts_from_it():
    """Egress towards the router on the shore = ingress from the router over the link on the boat,
    message by message and key by key: nothing the boat would refuse leaves the shore."""
    router = access.RELAY
    for key in every_key():
        for message in MESSAGES:
            to_boat = allowed(SHORE, router, message, key, flow="egress", interface=access.LOOPBACK)
            assert to_boat == allowed(BOAT, router, message, key, interface=LINK), (message, key)
            if message in ("put", "delete", "reply", "declare_queryable", "liveliness_token"):
                assert not to_boat, (message, key)


def test_the_shore_has_only_its_own_identities_and_only_its_operators_actuate():
    names = {n for s in SHORE["subjects"] for n in s["cert_common_names"]}
    assert names == set(access.SHORE_IDENTITIES)
    assert not [s for s in SHORE["subjects"] if "interfaces" in s]
    arm = keys.VEHICLE_ARM.key(V)
    for ident in access.IDENTITIES:
        if ident not in access.SHORE_IDENTITIES:
            assert not any(allowed(SHORE, ident, m, k) for m in MESSAGES for k in every_key()), ident
    for ident in access.SHORE_IDENTITIES:
        assert allowed(SHORE, ident, "declare_subscriber", keys.THRUST.key(V)), ident
        if ident != access.RELAY:  # the router asks for the boat's side (checked above)
            assert allowed(SHORE, ident, "query", arm) == (ident in access.OPERATORS), ident
        # no shore process publishes a boat key on the shore either
        assert not allowed(SHORE, ident, "put", keys.THRUST.key(V)) or ident == access.RELAY, ident


def test_a_shore_process_declares_its_health_as_the_shores_never_as_the_boats():
    """On the shore, the boat's health/recorder arrives through the router; the shore's recorder
    may declare only health/shore-recorder, so neither stands for the other."""
    for ident in (i for i in access.SHORE_IDENTITIES if i != access.RELAY and i in keys.SERVICES):
        own = keys.health_key(V, ident, "shore")
        assert own.endswith(f"/health/shore-{ident}")
        assert allowed(SHORE, ident, "liveliness_token", own), ident
        boats = keys.health_key(V, ident)
        assert not allowed(SHORE, ident, "liveliness_token", boats), ident
        assert allowed(BOAT, ident, "liveliness_token", boats), ident  # the boat's own, on the boat
        assert not allowed(BOAT, ident, "liveliness_token", own), ident
        assert keys.own_service(own.rsplit("/", 1)[1], "shore") == ident
        assert keys.own_service(boats.rsplit("/", 1)[1], "shore") is None
        assert keys.own_service(boats.rsplit("/", 1)[1], "boat") == ident


@pytest.mark.parametrize("side", access.SIDES)
def test_the_rules_say_their_side(side, tmp_path):
    assert access.side_of(access.acl(side=side)) == side
    if side != "local":
        credentials.create_deployment(tmp_path / "dep")
        assert credentials.Credentials(tmp_path / "dep" / side).side == side
    else:
        assert credentials.create(tmp_path / "one").side == "local"


def test_a_stack_alone_is_unchanged_by_the_sides():
    assert access.acl() == access.acl(side="local")
    assert not [s for s in RULES["subjects"] if "interfaces" in s]
    assert not [p for p in RULES["policies"] if p["id"] in ("from-shore", "boat-via-router")]
    # The router there is one more identity of the stack: its own health and refusal counts only.
    router = access.RELAY
    for key in every_key():
        assert allowed(RULES, router, "put", key) == (key == keys.refusals_key(V, router)), key
        assert allowed(RULES, router, "liveliness_token", key) == (key == keys.health_key(V, router)), key
    actuating = [s.key(V) for s in keys.REGISTRY if s.kind == "query"]
    assert not [k for k in actuating if allowed(RULES, router, "query", k)]


@pytest.mark.parametrize("side", access.SIDES)
def test_zenoh_accepts_each_sides_rules(side):
    conf = zenoh.Config()
    conf.insert_json5("access_control", json.dumps(access.acl(side=side)))  # raises on an unknown field
    assert json.loads(conf.get_json("access_control/enabled")) is True


# -- a deployment's credentials (credentials.create_deployment, `seaway credentials create --deployment`) --


def _cert(path):
    return x509.load_pem_x509_certificate(path.read_bytes())


def _san(path) -> tuple[set[str], set[str]]:
    """A certificate's subject alternative names: (DNS names, IP addresses)."""
    san = _cert(path).extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    ips = {str(a) for a in san.get_values_for_type(x509.IPAddress)}
    return set(san.get_values_for_type(x509.DNSName)), ips


def _mode(path):
    return stat.S_IMODE(path.stat().st_mode)


def test_a_deployment_is_two_private_folders_of_one_authority_whose_key_stays_at_the_root(tmp_path):
    root = tmp_path / "dep"
    made = credentials.create_deployment(root, boat_hosts=("boat.lan", "192.168.8.2"))
    assert set(made) == {"boat", "shore"}
    assert _mode(root) == 0o700 and (root / "ca-key.pem").is_file() and _mode(root / "ca-key.pem") == 0o600
    ca = _cert(root / "ca.pem")
    for side, idents in (("boat", access.IDENTITIES), ("shore", access.SHORE_IDENTITIES)):
        folder = root / side
        assert made[side].folder == folder and _mode(folder) == 0o700
        assert not (folder / "ca-key.pem").exists(), f"the authority's key is in {side}/"
        assert (folder / "ca.pem").read_bytes() == (root / "ca.pem").read_bytes()
        certs = sorted(p.name for p in folder.glob("*.pem") if not p.name.endswith("-key.pem"))
        assert certs == sorted(["ca.pem", *(f"{i}.pem" for i in idents)])
        for ident in idents:
            cert = _cert(folder / f"{ident}.pem")
            assert cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == ident
            cert.verify_directly_issued_by(ca)  # raises if another authority signed it
            assert _mode(folder / f"{ident}-key.pem") == 0o600, (side, ident)
            made[side].check(ident)
        assert made[side].access_rules() == access.acl(side=side)
    # The routers' certificates name the boat's hosts (the shore router dials one of them); only them.
    for side in ("boat", "shore"):
        assert _san(root / side / "router.pem") == ({"localhost", "boat.lan"}, {"127.0.0.1", "192.168.8.2"})
    assert _san(root / "boat" / "controller.pem") == ({"localhost"}, {"127.0.0.1"})


def test_a_deployment_narrows_the_boats_producers_and_creating_again_rotates(tmp_path):
    root = tmp_path / "dep"
    credentials.create_deployment(root, producers={"sensors/gnss": "vehicle_io"})
    gnss = keys.GNSS.key(V)
    boat = credentials.Credentials(root / "boat").access_rules()
    assert allowed(boat, "vehicle_io", "put", gnss) and not allowed(boat, "sim", "put", gnss)
    old_ca = _cert(root / "ca.pem")
    (root / "shore" / "stale.pem").write_text("left over from an earlier layout")
    credentials.create_deployment(root)
    assert not (root / "shore" / "stale.pem").exists()
    with pytest.raises(InvalidSignature):
        _cert(root / "boat" / "controller.pem").verify_directly_issued_by(old_ca)
    assert _cert(root / "shore" / "ca.pem") == _cert(root / "ca.pem") != old_ca


def test_the_cli_makes_a_deployment_and_refuses_a_boat_host_without_one(tmp_path, capsys):
    from seaway.tools import credentials_cli

    assert credentials_cli.main(["create", str(tmp_path / "plain"), "--boat-host", "10.0.0.2"]) == 2
    assert "--boat-host goes with --deployment" in capsys.readouterr().err
    assert not (tmp_path / "plain").exists()
    dep = tmp_path / "dep"
    assert credentials_cli.main(["create", str(dep), "--deployment", "--boat-host", "10.0.0.2",
                                 "--days", "7"]) == 0
    out = capsys.readouterr().out
    assert f"SEAWAY_CREDENTIALS={dep / 'boat'}" in out and f"SEAWAY_CREDENTIALS={dep / 'shore'}" in out
    assert "10.0.0.2" in _san(dep / "boat" / "router.pem")[1]
    router = _cert(dep / "boat" / "router.pem")
    # Valid for --days from now, and from the epoch: a boat whose clock runs behind (no real-time
    # clock, no network) still takes certificates made on the shore (credentials.VALID_FROM).
    now = datetime.datetime.now(datetime.UTC)
    assert 6 <= (router.not_valid_after_utc - now).days <= 7
    assert router.not_valid_before_utc.year == 1970
    assert _cert(dep / "boat" / "ca.pem").not_valid_before_utc.year == 1970
    assert credentials_cli.main(["show", str(dep)]) == 0
    shown = capsys.readouterr().out
    assert f"{dep / 'boat'}:" in shown and f"{dep / 'shore'}:" in shown and "NOT USABLE" not in shown


def test_a_topics_cache_is_its_producers_and_any_stack_process_may_ask_it():
    # zenoh-ext's advanced publisher (a real-time topic's cache for a restarted recorder): its
    # liveliness token and queryable under <key>/@adv/..., its replies on the key itself.
    key = keys.THRUST.key("vessel1")
    cache = f"{key}/@adv/pub/0123abcd/7/uhlc/_"
    for message in ("declare_queryable", "liveliness_token", "reply"):
        assert allowed(RULES, "controller", message, cache), message
        assert not allowed(RULES, "estimator", message, cache), message
    assert allowed(RULES, "controller", "reply", key)
    assert not allowed(RULES, "estimator", "reply", key)
    for message in ("query", "declare_liveliness_subscriber", "liveliness_query"):
        assert allowed(RULES, "recorder", message, cache), message
        assert allowed(RULES, "recorder", message, "seaway/**/@adv/**"), message


# -- the ROS 2 face's writes (acl(ros2_writes=True)) ---------------------------------------------------


@pytest.mark.parametrize("side", ["local", "boat"])
def test_ros2_may_ask_the_missions_requests_only_when_writes_are_on(side):
    on = access.acl(side=side, ros2_writes=True)
    off = access.acl(side=side)
    asked = {s.suffix for s in access.ROS2_REQUESTS}
    assert asked == {keys.MISSION_SET.suffix, keys.MISSION_COMMAND.suffix}
    for spec in (s for s in keys.REGISTRY if s.kind == "query"):
        key = spec.key("vessel1")
        assert allowed(on, access.ROS2, "query", key) == (spec.suffix in asked), spec.suffix
        assert not allowed(off, access.ROS2, "query", key), spec.suffix
        assert not allowed(on, access.ROS2, "reply", key)  # it asks; the controller answers
    # Nothing else changes: no other identity gains a right, ros2 publishes nothing new.
    for ident in access.IDENTITIES:
        if ident != access.ROS2:
            for spec in keys.REGISTRY:
                for message in ("put", "query"):
                    key = spec.key("vessel1")
                    assert allowed(on, ident, message, key) == allowed(off, ident, message, key)
    for spec in keys.REGISTRY:
        assert allowed(on, access.ROS2, "put", spec.key("vessel1")) == allowed(
            off, access.ROS2, "put", spec.key("vessel1"))


def test_ros2_writes_go_into_the_credentials_rules(tmp_path):
    made = credentials.create(tmp_path / "c", ros2_writes=True)
    assert made.access_rules() == access.acl(ros2_writes=True)
    conf = zenoh.Config()
    conf.insert_json5("access_control", json.dumps(made.access_rules()))  # Zenoh accepts it
