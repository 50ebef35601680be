"""``seaway router`` as a real process on loopback: start, health, stop; TLS with client certificates;
the boat router's access control against a shore router that holds the right certificate.

The routers run the shipped configs (deploy/zenoh/*-router*.json5) with only their ports moved
(``--listen`` / ``--connect``, so parallel tests never collide) and their TLS files in a tmp folder
(``--tls-dir``). The test's own sessions load the shipped client configs with the port moved the
same way.
"""

from __future__ import annotations

import json
import re
import signal
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh

from tests.conftest import Procs, free_port, wait_for
from tests.system.deploy.certs import have_openssl, make_deployment_certs

pytestmark = pytest.mark.system
REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"
VESSEL = "vessel1"


def router_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "seaway.tools.router", *args]


def peer(client_config: str, port: int) -> zenoh.Session:
    """A session with a shipped client config, connected to the router on ``port``."""
    conf = zenoh.Config.from_file(str(ZENOH_DIR / client_config))
    conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    return zenoh.open(conf)


class Collector:
    def __init__(self, session: zenoh.Session, keyexpr: str) -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[str, bytes]] = []
        self.sub = session.declare_subscriber(keyexpr, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes()))

    def payloads(self, key: str) -> list[bytes]:
        with self.lock:
            return [p for k, p in self.samples if k == key]


def replies(session: zenoh.Session, key: str, timeout_s: float = 2.0) -> list[str]:
    return [r.ok.payload.to_string() for r in session.get(key, timeout=timeout_s) if r.ok is not None]


def sees_router(session: zenoh.Session) -> bool:
    return bool(session.info.routers_zid())


# -- the router process ---------------------------------------------------------------------------


def test_router_starts_declares_health_and_stops_quickly(procs: Procs, tmp_path: Path) -> None:
    port = free_port()
    for sig in (signal.SIGINT, signal.SIGTERM):
        p = procs.start(router_cmd("--role", "boat", "--listen", f"tcp/127.0.0.1:{port}",
                                   "--health", "router", "--vessel", VESSEL),
                        env=None, name=f"router-{sig.name}")
        s = peer("boat-client.json5", port)
        try:
            health = f"seaway/{VESSEL}/health/router"
            wait_for(lambda s=s, health=health: any(r.ok is not None
                                                    for r in s.liveliness().get(health, timeout=0.5)),
                     15, what="the router's health token")
            assert p.poll() is None
            took = procs.stop(p, sig, timeout_s=5)
        finally:
            s.close()
        assert p.returncode == 0, Procs.log(p)
        assert took < 2.0, f"router took {took:.2f} s to stop on {sig.name}"
        log = Procs.log(p)
        assert "access control on" in log and "router stopped" in log
        assert "peer" in log and "connected" in log, "the router logs the sessions it serves"


def test_router_refuses_a_port_in_use_and_a_missing_certificate(procs: Procs, tmp_path: Path) -> None:
    port = free_port()
    first = procs.start(router_cmd("--role", "boat", "--listen", f"tcp/127.0.0.1:{port}"), env=None,
                        name="first")
    wait_for(lambda: "up in" in Procs.log(first), 15, what="the first router")
    second = procs.start(router_cmd("--role", "boat", "--listen", f"tcp/127.0.0.1:{port}"), env=None,
                         name="second")
    assert second.wait(15) == 1
    assert "could not start the router" in Procs.log(second)
    procs.stop(first)
    tls = procs.start(router_cmd("--config", "boat-router-tls.json5", "--tls-dir", str(tmp_path)),
                      env=None, name="tls")
    assert tls.wait(15) == 2
    assert f"missing: root_ca_certificate {tmp_path / 'ca.pem'}" in Procs.log(tls)


# -- TLS and access control -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not have_openssl():
        pytest.skip("the openssl command is not installed (needed to make throwaway certificates)")
    return make_deployment_certs(tmp_path_factory.mktemp("tls"))


def tls_client(port: int, certs: Path, cert: str | None, ca: str = "ca") -> zenoh.Session:
    """A client session straight to the boat router's TLS listener; raises if refused (2 s)."""
    tls = {"root_ca_certificate": str(certs / f"{ca}.pem")}
    if cert is not None:
        tls |= {"connect_certificate": str(certs / f"{cert}.pem"),
                "connect_private_key": str(certs / f"{cert}-key.pem"), "enable_mtls": True}
    conf = zenoh.Config.from_json5(json.dumps({
        "mode": "client",
        "connect": {"endpoints": [f"tls/localhost:{port}"], "timeout_ms": 2000},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {"link": {"tls": tls}},
    }))
    return zenoh.open(conf)


def test_tls_link_certificates_and_access_control(procs: Procs, certs: Path) -> None:
    boat_local, boat_tls, shore_local = free_port(), free_port(), free_port()
    # The shore router starts first: it must keep retrying until the boat is there.
    shore_router = procs.start(router_cmd(
        "--config", "shore-router-tls.json5", "--tls-dir", str(certs),
        "--listen", f"tcp/127.0.0.1:{shore_local}", "--connect", f"tls/localhost:{boat_tls}"),
        env=None, name="shore-router")
    time.sleep(1.0)
    boat_router = procs.start(router_cmd(
        "--config", "boat-router-tls.json5", "--tls-dir", str(certs),
        "--listen", f"tcp/127.0.0.1:{boat_local}", "--listen", f"tls/127.0.0.1:{boat_tls}"),
        env=None, name="boat-router")
    boat = peer("boat-client.json5", boat_local)
    shore = peer("shore-client.json5", shore_local)
    try:
        wait_for(lambda: re.search(r"router \w+ connected", Procs.log(shore_router)), 20,
                 what="the shore router's TLS session with the boat")
        wait_for(lambda: sees_router(boat) and sees_router(shore), 10, what="peers on their routers")
        wait_for(lambda: re.search(r"link up: tls/127\.0\.0\.1:\d+ <-> ", Procs.log(boat_router)), 5,
                 what="the boat router's log of the TLS link")

        thrust = f"seaway/{VESSEL}/ctrl/thrust"
        heartbeat = f"seaway/{VESSEL}/shore/heartbeat"
        on_boat = Collector(boat, "seaway/**")
        on_shore = Collector(shore, "seaway/**")
        boat.declare_queryable(f"seaway/{VESSEL}/vehicle/arm", lambda q: q.reply(q.key_expr, "armed"))
        boat.declare_queryable(f"seaway/{VESSEL}/sim/scenario", lambda q: q.reply(q.key_expr, "set"))
        # A shore queryable must never answer the boat's own requests.
        shore.declare_queryable(f"seaway/{VESSEL}/mission/set", lambda q: q.reply(q.key_expr, "impostor"))

        # Wait until the boat's data flows ashore (declarations have crossed both routers).
        def boat_reaches_shore() -> bool:
            boat.put(thrust, b"warmup")
            return bool(on_shore.payloads(thrust))

        wait_for(boat_reaches_shore, 10, interval_s=0.2, what="boat data on the shore")
        for i in range(20):
            boat.put(thrust, f"boat {i}".encode())
            shore.put(thrust, f"shore {i}".encode())
            shore.put(heartbeat, f"hb {i}".encode())
            time.sleep(0.02)
        wait_for(lambda: len([p for p in on_shore.payloads(thrust) if p.startswith(b"boat")]) >= 20
                 and len(on_boat.payloads(heartbeat)) >= 20, 5, what="data both ways")
        time.sleep(0.5)
        boat_thrust = on_boat.payloads(thrust)
        assert not [p for p in boat_thrust if p.startswith(b"shore")], "shore ctrl/thrust reached the boat"
        assert len([p for p in on_shore.payloads(thrust) if p.startswith(b"boat ")]) == 20
        assert len(on_boat.payloads(heartbeat)) == 20, "the shore's heartbeat did not reach the boat"
        assert replies(shore, f"seaway/{VESSEL}/vehicle/arm") == ["armed"]
        assert replies(shore, f"seaway/{VESSEL}/sim/scenario") == [], "shore may not set the scenario"
        assert replies(boat, f"seaway/{VESSEL}/mission/set") == [], "a shore queryable answered the boat"

        # Straight to the TLS listener: the right certificate gets in and sees the boat's data...
        good = tls_client(boat_tls, certs, "shore")
        try:
            seen = Collector(good, "seaway/**")
            wait_for(lambda: (boat.put(thrust, b"to good"), bool(seen.payloads(thrust)))[1], 5,
                     interval_s=0.2, what="data for the certified shore client")
        finally:
            good.close()
        # ...a certificate from our CA with another name gets in but is given nothing...
        intruder = tls_client(boat_tls, certs, "intruder")
        try:
            seen = Collector(intruder, "seaway/**")
            for _ in range(10):
                boat.put(thrust, b"to intruder")
                intruder.put(thrust, b"intruder")
                time.sleep(0.05)
            time.sleep(0.5)
            assert seen.payloads(thrust) == [b"intruder"] * 10, "another certificate name saw boat data"
            assert b"intruder" not in on_boat.payloads(thrust)
            assert replies(intruder, f"seaway/{VESSEL}/vehicle/arm", 1.0) == []
        finally:
            intruder.close()
        # ...and no certificate, a certificate from another CA, or trusting another CA: refused.
        for cert, ca, why in [(None, "ca", "no client certificate"),
                              ("rogue", "ca", "client certificate from another CA"),
                              ("shore", "rogue-ca", "the boat's certificate is not from the CA we trust")]:
            t0 = time.monotonic()
            with pytest.raises(zenoh.ZError):
                tls_client(boat_tls, certs, cert, ca).close()
                pytest.fail(f"TLS session opened with {why}")
            assert time.monotonic() - t0 < 10
    finally:
        boat.close()
        shore.close()
    for p in (shore_router, boat_router):
        assert procs.stop(p, signal.SIGINT) < 2.0
        assert p.returncode == 0, Procs.log(p)
