"""The access rules generated from the key registry, and the credentials folder's safety checks.

The rules are evaluated here the way Zenoh evaluates them (allow-rules of the policies whose
subjects match, default deny), on the generated document itself, so a change of the generator that
would let a non-producer publish or a non-operator actuate fails here; the system tests
(tests/system/launch/test_authority.py) show Zenoh enforcing the same document.
"""

from __future__ import annotations

import fnmatch
import os
import stat

import pytest
import zenoh
from seaway.contract import access, keys
from seaway.runtime import credentials


def allowed(rules: dict, identity: str, message: str, key: str, flow: str = "ingress") -> bool:
    by_id = {r["id"]: r for r in rules["rules"]}
    for policy in rules["policies"]:
        if identity not in policy["subjects"]:
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
