"""``seaway router`` config handling: which file, endpoint replacements, the side's credentials (its
certificate and rules) inserted, refusals in words."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from seaway.contract import access
from seaway.runtime import credentials
from seaway.tools import router
from seaway.tools.router import RouterConfigError, build_config, resolve_config

REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"


def get(conf, key: str):
    return json.loads(conf.get_json(key))


@pytest.fixture(autouse=True)
def _no_router_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for var in (router.ENV_ROUTER_CONFIG, router.ENV_ROUTER_CONNECT, router.ENV_ROUTER_LISTEN,
                credentials.ENV_CREDENTIALS):
        monkeypatch.delenv(var, raising=False)


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory) -> dict[str, credentials.Credentials]:
    return credentials.create_deployment(tmp_path_factory.mktemp("dep") / "creds")


def test_resolve_by_name_and_by_path(tmp_path: Path) -> None:
    assert resolve_config("boat-router.json5") == ZENOH_DIR / "boat-router.json5"
    own = tmp_path / "mine.json5"
    own.write_text('{mode: "router"}')
    assert resolve_config(str(own)) == own
    with pytest.raises(RouterConfigError, match=r"available: .*boat-router\.json5"):
        resolve_config("nope.json5")
    with pytest.raises(RouterConfigError, match="does not exist"):
        resolve_config(str(tmp_path / "sub" / "nope.json5"))


def test_endpoints_are_replaced(deployment: dict[str, credentials.Credentials]) -> None:
    conf, s = build_config(ZENOH_DIR / "shore-router.json5", connect=["tls/10.0.0.2:7449"],
                           listen=["tls/127.0.0.1:17000"], credentials=deployment["shore"])
    assert get(conf, "connect/endpoints") == ["tls/10.0.0.2:7449"]
    assert get(conf, "listen/endpoints") == ["tls/127.0.0.1:17000"]
    assert s.connect == ["tls/10.0.0.2:7449"] and s.listen == ["tls/127.0.0.1:17000"]
    # the rest of the file is kept
    assert get(conf, "connect/retry")["period_init_ms"] == 500
    assert get(conf, "mode") == "router"


def test_a_client_config_is_refused_as_a_router_config() -> None:
    with pytest.raises(RouterConfigError, match="mode 'peer'"):
        build_config(ZENOH_DIR / "boat-client.json5")


def test_a_config_without_mode_becomes_a_router(tmp_path: Path) -> None:
    p = tmp_path / "bare.json5"
    p.write_text('{listen: {endpoints: ["tcp/127.0.0.1:0"]}}')
    conf, s = build_config(p)
    assert get(conf, "mode") == "router"
    assert not s.access_control and "access control off" in s.summary()


def test_invalid_file_is_refused_with_its_name(tmp_path: Path) -> None:
    p = tmp_path / "bad.json5"
    p.write_text('{mode: "router", no_such_key: 1}')
    with pytest.raises(RouterConfigError, match=r"bad.json5 is invalid.*no_such_key"):
        build_config(p)


@pytest.mark.parametrize("side", ["boat", "shore"])
def test_a_tls_config_needs_the_sides_credentials_and_gets_the_routers(
        side: str, deployment: dict[str, credentials.Credentials]) -> None:
    with pytest.raises(RouterConfigError, match=r"links over TLS.*--credentials DIR.*"
                                                r"seaway credentials create DIR --deployment"):
        build_config(ZENOH_DIR / f"{side}-router.json5")
    made = deployment[side]
    conf, s = build_config(ZENOH_DIR / f"{side}-router.json5", credentials=made)
    assert s.tls_files == {"root_ca_certificate": str(made.folder / "ca.pem"),
                           "listen_certificate": str(made.folder / "router.pem"),
                           "listen_private_key": str(made.folder / "router-key.pem"),
                           "connect_certificate": str(made.folder / "router.pem"),
                           "connect_private_key": str(made.folder / "router-key.pem")}
    assert s.mtls and s.access_control
    assert "mTLS" in s.summary() and "access control on" in s.summary()
    rules = get(conf, "access_control")
    assert [p["id"] for p in rules["policies"]] == [p["id"] for p in access.acl(side=side)["policies"]]


def test_unusable_credentials_are_refused_in_words(tmp_path: Path) -> None:
    with pytest.raises(RouterConfigError, match=r"does not exist"):
        build_config(ZENOH_DIR / "boat-router.json5", credentials=credentials.Credentials(tmp_path / "no"))
    made = credentials.create_deployment(tmp_path / "dep")["boat"]
    os.chmod(made.folder, 0o755)
    with pytest.raises(RouterConfigError, match=r"open to other users.*chmod 700"):
        build_config(ZENOH_DIR / "boat-router.json5", credentials=made)
    os.chmod(made.folder, 0o700)
    (made.folder / "router-key.pem").unlink()
    with pytest.raises(RouterConfigError, match=r"no router-key\.pem for identity 'router'"):
        build_config(ZENOH_DIR / "boat-router.json5", credentials=made)


def test_a_named_tls_file_must_exist(tmp_path: Path) -> None:
    p = tmp_path / "own.json5"
    p.write_text('{mode: "router", listen: {endpoints: ["tls/127.0.0.1:0"]}, '
                 f'transport: {{link: {{tls: {{root_ca_certificate: "{tmp_path}/ca.pem"}}}}}}}}')
    with pytest.raises(RouterConfigError, match=rf"missing: root_ca_certificate {tmp_path}/ca\.pem"):
        build_config(p)
    (tmp_path / "ca.pem").write_text("x")
    _, s = build_config(p)  # a hand-made TLS config with its own files is the operator's business
    assert s.tls_files == {"root_ca_certificate": str(tmp_path / "ca.pem")}


def test_cfg_overrides(tmp_path: Path, deployment: dict[str, credentials.Credentials]) -> None:
    boat = ZENOH_DIR / "boat-router.json5"
    conf, s = build_config(boat, credentials=deployment["boat"], overrides=["transport/link/tx/lease=2000"])
    assert get(conf, "transport/link/tx/lease") == 2000 and s.lease_ms == 2000
    # --cfg comes last: it may even replace what the credentials put there
    conf, s = build_config(boat, credentials=deployment["boat"], check_files=False,
                           overrides=[f"transport/link/tls/root_ca_certificate='{tmp_path}/other-ca.pem'"])
    assert s.tls_files["root_ca_certificate"] == f"{tmp_path}/other-ca.pem"
    with pytest.raises(RouterConfigError, match="KEY=JSON5_VALUE"):
        build_config(boat, credentials=deployment["boat"], overrides=["lease"])
    with pytest.raises(RouterConfigError, match="no/such/key"):
        build_config(boat, credentials=deployment["boat"], overrides=["no/such/key=1"])


def test_main_check_and_exit_codes(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture,
                                   deployment: dict[str, credentials.Credentials]) -> None:
    boat, shore = (str(deployment[s].folder) for s in ("boat", "shore"))
    # no credentials: the shipped (TLS) configs are refused, naming how to make them
    assert router.main(["--role", "boat", "--check"]) == 2
    assert "seaway credentials create DIR --deployment" in capsys.readouterr().err
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, credentials.NONE)
    assert router.main(["--role", "boat", "--check"]) == 2
    assert "links over TLS" in capsys.readouterr().err
    assert router.main(["--role", "boat", "--credentials", boat, "--check"]) == 0
    out = capsys.readouterr().out
    assert "router config valid" in out and f"{boat}/router.pem" in out and "access control on" in out
    assert router.main(["--check"]) == 2
    assert "name a config" in capsys.readouterr().err
    assert router.main(["--config", "shore-client.json5", "--credentials", shore, "--check"]) == 2
    # the environment picks the file, the endpoints and the credentials; the command line wins
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, shore)
    monkeypatch.setenv(router.ENV_ROUTER_CONFIG, "shore-router.json5")
    monkeypatch.setenv(router.ENV_ROUTER_CONNECT, "tls/10.1.1.1:7449, tls/10.1.1.2:7449")
    assert router.main(["--role", "boat", "--check"]) == 0
    out = capsys.readouterr().out
    assert "shore-router.json5" in out and "connect tls/10.1.1.1:7449, tls/10.1.1.2:7449" in out
    assert f"{shore}/ca.pem" in out
    assert router.main(["--config", "boat-router.json5", "--credentials", boat, "--check"]) == 0
    out = capsys.readouterr().out
    assert "boat-router.json5" in out and f"{boat}/router.pem" in out
    # the deployment's root (the authority, not a side) is refused: it has no router certificate
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, str(Path(shore).parent))
    assert router.main(["--check"]) == 2
    assert "has no router.pem for identity 'router'" in capsys.readouterr().err
