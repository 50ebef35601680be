"""``seaway router`` config handling: which file, endpoint and TLS replacements, refusals in words."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from seaway.tools import router
from seaway.tools.router import RouterConfigError, build_config, resolve_config

REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"


def get(conf, key: str):
    return json.loads(conf.get_json(key))


@pytest.fixture(autouse=True)
def _no_router_env(monkeypatch: pytest.MonkeyPatch) -> None:
    for var in (router.ENV_ROUTER_CONFIG, router.ENV_ROUTER_CONNECT, router.ENV_ROUTER_LISTEN,
                router.ENV_TLS_DIR):
        monkeypatch.delenv(var, raising=False)


def test_resolve_by_name_and_by_path(tmp_path: Path) -> None:
    assert resolve_config("boat-router.json5") == ZENOH_DIR / "boat-router.json5"
    own = tmp_path / "mine.json5"
    own.write_text('{mode: "router"}')
    assert resolve_config(str(own)) == own
    with pytest.raises(RouterConfigError, match=r"available: .*boat-router\.json5"):
        resolve_config("nope.json5")
    with pytest.raises(RouterConfigError, match="does not exist"):
        resolve_config(str(tmp_path / "sub" / "nope.json5"))


def test_endpoints_are_replaced() -> None:
    conf, s = build_config(ZENOH_DIR / "shore-router.json5", connect=["tcp/10.0.0.2:7447"],
                           listen=["tcp/127.0.0.1:17000"])
    assert get(conf, "connect/endpoints") == ["tcp/10.0.0.2:7447"]
    assert get(conf, "listen/endpoints") == ["tcp/127.0.0.1:17000"]
    assert s.connect == ["tcp/10.0.0.2:7447"] and s.listen == ["tcp/127.0.0.1:17000"]
    # the rest of the file is kept
    assert get(conf, "connect/retry")["period_init_ms"] == 500
    assert get(conf, "mode") == "router"


def test_a_client_config_is_refused_as_a_router_config() -> None:
    with pytest.raises(RouterConfigError, match="mode 'peer'"):
        build_config(ZENOH_DIR / "boat-client.json5")


def test_a_config_without_mode_becomes_a_router(tmp_path: Path) -> None:
    p = tmp_path / "bare.json5"
    p.write_text('{listen: {endpoints: ["tcp/127.0.0.1:0"]}}')
    conf, _ = build_config(p)
    assert get(conf, "mode") == "router"


def test_invalid_file_is_refused_with_its_name(tmp_path: Path) -> None:
    p = tmp_path / "bad.json5"
    p.write_text('{mode: "router", no_such_key: 1}')
    with pytest.raises(RouterConfigError, match=r"bad.json5 is invalid.*no_such_key"):
        build_config(p)


def test_tls_files_must_exist_and_tls_dir_moves_them(tmp_path: Path) -> None:
    with pytest.raises(RouterConfigError, match=r"missing: root_ca_certificate /etc/seaway/tls/ca.pem"):
        build_config(ZENOH_DIR / "boat-router-tls.json5")
    with pytest.raises(RouterConfigError, match=str(tmp_path / "boat-key.pem")):
        build_config(ZENOH_DIR / "boat-router-tls.json5", tls_dir=tmp_path)
    for name in ("ca.pem", "boat.pem", "boat-key.pem"):
        (tmp_path / name).write_text("x")
    conf, s = build_config(ZENOH_DIR / "boat-router-tls.json5", tls_dir=tmp_path)
    assert get(conf, "transport/link/tls/root_ca_certificate") == str(tmp_path / "ca.pem")
    assert get(conf, "transport/link/tls/listen_private_key") == str(tmp_path / "boat-key.pem")
    assert s.mtls and s.access_control
    assert "mTLS" in s.summary() and "access control on" in s.summary()


def test_a_tls_endpoint_without_a_ca_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "tls.json5"
    p.write_text('{mode: "router", listen: {endpoints: ["tls/127.0.0.1:0"]}}')
    with pytest.raises(RouterConfigError, match="root_ca_certificate"):
        build_config(p)


def test_cfg_overrides(tmp_path: Path) -> None:
    conf, s = build_config(ZENOH_DIR / "boat-router.json5", overrides=["transport/link/tx/lease=2000"])
    assert get(conf, "transport/link/tx/lease") == 2000 and s.lease_ms == 2000
    (tmp_path / "other-ca.pem").write_text("x")
    conf, s = build_config(ZENOH_DIR / "shore-router-tls.json5", check_files=False,
                           overrides=[f"transport/link/tls/root_ca_certificate='{tmp_path}/other-ca.pem'"])
    assert s.tls_files["root_ca_certificate"] == f"{tmp_path}/other-ca.pem"
    with pytest.raises(RouterConfigError, match="KEY=JSON5_VALUE"):
        build_config(ZENOH_DIR / "boat-router.json5", overrides=["lease"])
    with pytest.raises(RouterConfigError, match="no/such/key"):
        build_config(ZENOH_DIR / "boat-router.json5", overrides=["no/such/key=1"])


def test_main_check_and_exit_codes(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture,
                                   tmp_path: Path) -> None:
    assert router.main(["--role", "boat", "--check"]) == 0
    assert "router config valid" in capsys.readouterr().out
    assert router.main(["--check"]) == 2
    assert "name a config" in capsys.readouterr().err
    assert router.main(["--config", "shore-client.json5", "--check"]) == 2
    # the environment picks the file and the endpoint; the command line wins over it
    monkeypatch.setenv(router.ENV_ROUTER_CONFIG, "shore-router.json5")
    monkeypatch.setenv(router.ENV_ROUTER_CONNECT, "tcp/10.1.1.1:7447, tcp/10.1.1.2:7447")
    assert router.main(["--role", "boat", "--check"]) == 0
    out = capsys.readouterr().out
    assert "shore-router.json5" in out and "connect tcp/10.1.1.1:7447, tcp/10.1.1.2:7447" in out
    assert router.main(["--config", "boat-router.json5", "--check"]) == 0
    assert "boat-router.json5" in capsys.readouterr().out
    # TLS files from the environment's folder
    monkeypatch.setenv(router.ENV_ROUTER_CONFIG, "shore-router-tls.json5")
    monkeypatch.setenv(router.ENV_TLS_DIR, str(tmp_path))
    assert router.main(["--check"]) == 2
    assert str(tmp_path / "shore-key.pem") in capsys.readouterr().err
