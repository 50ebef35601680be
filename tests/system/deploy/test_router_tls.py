"""``seaway router`` as real processes with a deployment's credentials: start, health, stop; the relay
chain between a boat and a shore; and what an intruder at the boat's link port gets (nothing).

The credentials are made by the real command (``seaway credentials create DIR --deployment``). The
routers run the shipped configs (deploy/zenoh/{boat,shore}-router.json5) with only their ports moved
(``--listen`` / ``--connect``, so parallel tests never collide) and ``$SEAWAY_CREDENTIALS`` naming
their side's folder. The test's own sessions load the shipped client configs as one identity of a
side (``seaway.runtime.zenoh_bus.load_zenoh_config``, what every service does), port moved the same
way. On one computer the shore router reaches the boat router over loopback; the last test reaches
it over a real interface too, as it does on the water.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh
from seaway.contract import access, keys
from seaway.contract.messages import Refusals
from seaway.runtime.credentials import Credentials
from seaway.runtime.zenoh_bus import ZenohBus

from tests.conftest import Procs, free_port, wait_for
from tests.system.deploy import deployment
from tests.system.deploy.deployment import bare_tls_client, link_address, session

pytestmark = pytest.mark.system
VESSEL = "vessel1"
THRUST = keys.THRUST.key(VESSEL)
MISSION_SET = keys.MISSION_SET.key(VESSEL)
HEALTH = keys.health_wildcard(VESSEL)
BOAT_SAYS = "accepted by the boat"


@pytest.fixture(scope="module")
def dep(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One deployment for the module; the boat router's certificate also names this computer's
    non-loopback address (if it has one), which the last test dials."""
    addr = link_address()
    return deployment.create(tmp_path_factory.mktemp("deployment") / "creds", (addr,) if addr else ())


def side_env(dep: Path | None, side: str = "boat") -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("SEAWAY_ROUTER_", "SEAWAY_ZENOH_", "SEAWAY_IDENTITY", "SEAWAY_CREDENTIALS"))}
    env["PYTHONUNBUFFERED"] = "1"
    if dep is not None:
        env["SEAWAY_CREDENTIALS"] = str(dep / side)
    return env


def router_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "seaway.tools.router", "--vessel", VESSEL, *args]


def start_routers(procs: Procs, dep: Path, boat_link: str, shore_connect: str,
                  boat_health: bool = True) -> tuple[subprocess.Popen, subprocess.Popen, int, int]:
    """Shore router first (it must retry until the boat is there), then the boat router; returns
    them and the loopback ports of the boat's and the shore's peers, once the two routers are linked."""
    boat_local, shore_local = free_port(), free_port()
    shore = procs.start(router_cmd("--role", "shore", "--listen", f"tls/127.0.0.1:{shore_local}",
                                   "--connect", shore_connect, "--health", "router"),
                        env=side_env(dep, "shore"), name="shore-router")
    wait_for(lambda: "up in" in Procs.log(shore), 20, what="the shore router up")
    boat = procs.start(router_cmd("--role", "boat", "--listen", f"tls/127.0.0.1:{boat_local}",
                                  "--listen", boat_link, *(["--health", "router"] if boat_health else [])),
                       env=side_env(dep, "boat"), name="boat-router")
    wait_for(lambda: re.search(r"router \w+ connected", Procs.log(shore)), 30,
             what="the shore router's TLS session with the boat router")
    return boat, shore, boat_local, shore_local


class Collector:
    def __init__(self, s: zenoh.Session, keyexpr: str = "seaway/**") -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[str, bytes]] = []
        self.sub = s.declare_subscriber(keyexpr, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes()))

    def payloads(self, key: str) -> list[bytes]:
        with self.lock:
            return [p for k, p in self.samples if k == key]


def replies(s: zenoh.Session, key: str, timeout_s: float = 3.0) -> list[str]:
    return [r.ok.payload.to_string() for r in s.get(key, timeout=timeout_s) if r.ok is not None]


def tokens(s: zenoh.Session) -> set[str]:
    return {str(r.ok.key_expr).rsplit("/", 1)[-1] for r in s.liveliness().get(HEALTH, timeout=2.0)
            if r.ok is not None}


def close(*sessions: zenoh.Session) -> None:
    for s in sessions:
        s.close()


def stop_routers(procs: Procs, *routers: subprocess.Popen) -> None:
    for p in routers:
        assert procs.stop(p, signal.SIGINT) < 2.0, f"{p.args} took too long to stop"
        assert p.returncode == 0, Procs.log(p)


# -- the router process ---------------------------------------------------------------------------


def test_router_starts_declares_health_and_stops_quickly(procs: Procs, dep: Path) -> None:
    port = free_port()
    for sig in (signal.SIGINT, signal.SIGTERM):
        p = procs.start(router_cmd("--role", "boat", "--listen", f"tls/127.0.0.1:{port}",
                                   "--health", "router"), env=side_env(dep), name=f"router-{sig.name}")
        wait_for(lambda p=p: "up in" in Procs.log(p) or p.poll() is not None, 20, what="the router up")
        s = session("boat", "launcher", dep, f"tls/127.0.0.1:{port}")
        try:
            wait_for(lambda s=s: "router" in tokens(s), 15, what="the router's health token")
            assert p.poll() is None
            took = procs.stop(p, sig, timeout_s=5)
        finally:
            s.close()
        assert p.returncode == 0, Procs.log(p)
        assert took < 2.0, f"router took {took:.2f} s to stop on {sig.name}"
        log = Procs.log(p)
        assert "access control on" in log and "router stopped" in log
        assert f"{dep / 'boat' / 'router.pem'}" in log, "the router runs with its side's certificate"
        assert re.search(r"link up: tls/127\.0\.0\.1:\d+ <-> .*authenticated as launcher", log), log
        assert "peer" in log and "connected" in log, "the router logs the sessions it serves"


def test_router_refuses_a_port_in_use_and_missing_credentials(procs: Procs, dep: Path,
                                                              tmp_path: Path) -> None:
    port = free_port()
    first = procs.start(router_cmd("--role", "boat", "--listen", f"tls/127.0.0.1:{port}"), env=side_env(dep),
                        name="first")
    wait_for(lambda: "up in" in Procs.log(first), 20, what="the first router")
    second = procs.start(router_cmd("--role", "boat", "--listen", f"tls/127.0.0.1:{port}"), env=side_env(dep),
                         name="second")
    assert second.wait(20) == 1
    assert "could not start the router" in Procs.log(second)
    procs.stop(first)
    nowhere = str(tmp_path / "nowhere")
    for name, env, says in [
        ("no-credentials", side_env(None), "seaway credentials create DIR --deployment"),
        ("opted-out", {**side_env(None), "SEAWAY_CREDENTIALS": "none"}, "links over TLS"),
        ("missing-folder", {**side_env(None), "SEAWAY_CREDENTIALS": nowhere}, "does not exist"),
    ]:
        p = procs.start(router_cmd("--role", "boat"), env=env, name=name)
        assert p.wait(20) == 2, Procs.log(p)
        assert says in Procs.log(p), Procs.log(p)


@pytest.mark.parametrize("profile", ["boat", "shore"])
def test_launching_a_side_without_its_credentials_says_how_to_make_them(
        profile: str, tmp_path: Path) -> None:
    env = {**side_env(None), "SEAWAY_STACKS_DIR": str(tmp_path / "stacks")}
    out = subprocess.run([sys.executable, "-m", "seaway.tools.cli", "launch", profile,
                          "--run-dir", str(tmp_path / "run")], env=env, capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "seaway credentials create DIR --deployment" in out.stderr
    assert f"SEAWAY_CREDENTIALS=DIR/{profile}" in out.stderr
    assert not (tmp_path / "run").exists(), "nothing started"


# -- the chain: shore operator -> shore router -> boat router -> boat service ----------------------


def test_the_relay_chain_carries_the_shores_rights_and_no_more(procs: Procs, dep: Path) -> None:
    link = free_port()
    boat_router, shore_router, boat_port, shore_port = start_routers(
        procs, dep, f"tls/127.0.0.1:{link}", f"tls/localhost:{link}")
    on_boat, ashore = f"tls/127.0.0.1:{boat_port}", f"tls/127.0.0.1:{shore_port}"
    controller = session("boat", "controller", dep, on_boat)
    estimator = session("boat", "estimator", dep, on_boat)
    launcher = session("boat", "launcher", dep, on_boat)
    operator = session("shore", "operator", dep, ashore)
    recorder = session("shore", "recorder", dep, ashore)
    try:
        boat_heard = Collector(estimator)
        controller_heard = Collector(controller)
        op_heard, rec_heard = Collector(operator), Collector(recorder)
        served = controller.declare_queryable(MISSION_SET, lambda q: q.reply(q.key_expr, BOAT_SAYS))
        alive = controller.liveliness().declare_token(keys.health_key(VESSEL, "controller"))
        # Shore processes must never answer the boat's requests nor look alive on the boat.
        impostor = operator.declare_queryable(MISSION_SET, lambda q: q.reply(q.key_expr, "impostor"))
        shore_alive = recorder.liveliness().declare_token(keys.health_key(VESSEL, "recorder"))

        # The boat's data reaches the shore once the declarations have crossed both routers.
        wait_for(lambda: (controller.put(THRUST, b"warmup"), bool(op_heard.payloads(THRUST)))[1], 20,
                 interval_s=0.2, what="boat data on the shore")
        for i in range(20):
            controller.put(THRUST, f"boat {i}".encode())
            operator.put(THRUST, f"shore operator {i}".encode())
            recorder.put(THRUST, f"shore recorder {i}".encode())
            time.sleep(0.02)
        # The shore operator's request is answered by the boat's queryable, over the same path the
        # forged puts took: by the time it is answered, they had their chance. Remote queryables
        # only, every one of them: the operator's own impostor answers its own session (harmless,
        # and under load the only one its session knew yet, before the boat's declaration crossed
        # both routers; the check that matters, the boat never hearing it, is the launcher's below).
        def boat_replies() -> list[str]:
            return [r.ok.payload.to_string() for r in operator.get(
                MISSION_SET, timeout=3.0, target=zenoh.QueryTarget.ALL,
                allowed_destination=zenoh.Locality.REMOTE) if r.ok is not None]
        assert wait_for(boat_replies, 20, interval_s=0.2, what="the boat's answer ashore") == [BOAT_SAYS]
        wait_for(lambda: len([p for p in op_heard.payloads(THRUST) if p.startswith(b"boat ")]) == 20
                 and len([p for p in rec_heard.payloads(THRUST) if p.startswith(b"boat ")]) == 20
                 and len([p for p in boat_heard.payloads(THRUST) if p.startswith(b"boat ")]) == 20,
                 10, what="every boat command on the boat and ashore")
        time.sleep(0.5)
        for heard in (boat_heard, controller_heard):
            assert not [p for p in heard.payloads(THRUST) if p.startswith(b"shore")], \
                "a shore ctrl/thrust reached the boat"
        # A shore process that is not an operator is refused by its own router.
        assert replies(recorder, MISSION_SET, 2.0) == []
        # The boat's own requests are answered by the boat only.
        assert replies(launcher, MISSION_SET) == [BOAT_SAYS]
        # Health: the shore sees the boat's; the boat never sees the shore's.
        wait_for(lambda: {"controller", "router"} <= tokens(operator), 10, what="boat health ashore")
        assert "recorder" not in tokens(launcher), "a shore health token reached the boat"
        for entity in (served, alive, impostor, shore_alive):
            entity.undeclare()
    finally:
        close(controller, estimator, launcher, operator, recorder)
    stop_routers(procs, shore_router, boat_router)
    assert re.search(r"link up: .*authenticated as router", Procs.log(boat_router)), \
        "the shore router came in as identity router"


def test_the_shore_tells_the_boats_recorder_from_its_own(procs: Procs, dep: Path, tmp_path: Path) -> None:
    """A recorder on each side, each a real bus with its side's credentials: the shore sees the
    boat's health/recorder and its own health/shore-recorder, and sees the boat's go while its own
    lives on. Before, both were health/recorder: the shore's token hid the boat's death (the page's
    NOT RECORDING waited for both)."""
    link = free_port()
    boat_router, shore_router, boat_port, shore_port = start_routers(
        procs, dep, f"tls/127.0.0.1:{link}", f"tls/localhost:{link}")
    boat_rec = ZenohBus.connect(VESSEL, deployment.client_file("boat", tmp_path, boat_port),
                                identity="recorder", credentials=Credentials(dep / "boat"))
    shore_rec = ZenohBus.connect(VESSEL, deployment.client_file("shore", tmp_path, shore_port),
                                 identity="recorder", credentials=Credentials(dep / "shore"))
    operator = session("shore", "operator", dep, f"tls/127.0.0.1:{shore_port}")
    try:
        assert (boat_rec.side, shore_rec.side) == ("boat", "shore")
        boat_rec.declare_alive("recorder")
        shore_rec.declare_alive("recorder")
        wait_for(lambda: {"recorder", "shore-recorder", "router", "shore-router"} <= tokens(operator),
                 20, what="both recorders' and both routers' tokens ashore")
        boat_rec.close()
        # One answer that holds both: a get cut short under load (its 2 s timeout) can miss either
        # token, and a lone "recorder gone" would then say nothing of the shore's.
        wait_for(lambda: (lambda t: "recorder" not in t and "shore-recorder" in t)(tokens(operator)),
                 10, what="the boat recorder's token gone, the shore recorder's still there")
        # Nor can a shore process pass for the boat's: its own rules refuse the boat's name.
        forged = shore_rec.session.liveliness().declare_token(keys.health_key(VESSEL, "recorder"))
        time.sleep(1.0)
        assert "recorder" not in tokens(operator)
        forged.undeclare()
    finally:
        shore_rec.close()
        boat_rec.close()
        close(operator)
    stop_routers(procs, shore_router, boat_router)


# -- intruders at the boat's link port ---------------------------------------------------------------


def health_json(dep: Path, boat_port: int, tmp_path: Path) -> dict:
    """``seaway health --json`` on the boat: the operator command, with the boat's credentials."""
    client = deployment.client_file("boat", tmp_path, boat_port)
    out = subprocess.run([sys.executable, "-m", "seaway.tools.cli", "health", "--json", "--wait", "1",
                          "--vessel", VESSEL, "--zenoh-config", str(client)],
                         env=side_env(dep), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_intruders_at_the_link_port_get_nothing_onto_the_boat(procs: Procs, dep: Path,
                                                              tmp_path: Path) -> None:
    link = free_port()
    boat_router, shore_router, boat_port, _ = start_routers(
        procs, dep, f"tls/127.0.0.1:{link}", f"tls/localhost:{link}")
    at_link = f"tls/localhost:{link}"
    other = deployment.other_authority(tmp_path / "other")
    # No certificate, a certificate of another authority (trusting ours, or its own): no link at all.
    for why, ca, cert in [("no client certificate", dep / "ca.pem", None),
                          ("a certificate of another authority", dep / "ca.pem", other.folder / "operator"),
                          ("trusting another authority", other.folder / "ca.pem", dep / "shore" / "router")]:
        shown = (Path(f"{cert}.pem"), Path(f"{cert}-key.pem")) if cert else ()
        t0 = time.monotonic()
        with pytest.raises(zenoh.ZError):
            bare_tls_client(at_link, ca, *shown).close()
            pytest.fail(f"a TLS session opened with {why}")
        assert time.monotonic() - t0 < 10, why

    controller = session("boat", "controller", dep, f"tls/127.0.0.1:{boat_port}")
    estimator = session("boat", "estimator", dep, f"tls/127.0.0.1:{boat_port}")
    # The shore's own certificates, without the shore's rules, straight to the link port: its router's
    # (a compromised shore) and its recorder's (an identity the boat also has).
    rogue_router = session("shore", "router", dep, at_link, rules=False, mode="client")
    rogue_recorder = session("shore", "recorder", dep, at_link, rules=False, mode="client")
    try:
        boat_heard = Collector(estimator)
        served = controller.declare_queryable(MISSION_SET, lambda q: q.reply(q.key_expr, BOAT_SAYS))
        forged: list = []
        for rogue in (rogue_router, rogue_recorder):
            forged += [rogue.liveliness().declare_token(keys.health_key(VESSEL, "controller")),
                       rogue.declare_queryable(keys.NAV_RESET.key(VESSEL),
                                               lambda q: q.reply(q.key_expr, "impostor"))]
        wait_for(lambda: replies(rogue_router, MISSION_SET, 1.0) == [BOAT_SAYS], 20,
                 what="the rogue shore router reaching the boat's controller")  # the shore's right
        for i in range(20):
            rogue_router.put(THRUST, f"rogue router {i}".encode())
            rogue_recorder.put(THRUST, f"rogue recorder {i}".encode())
            rogue_recorder.put(keys.LOCKSTEP_RECORDER.key(VESSEL), b"{}")
            controller.put(THRUST, f"boat {i}".encode())
            time.sleep(0.02)
        assert replies(rogue_router, MISSION_SET) == [BOAT_SAYS]
        wait_for(lambda: len(boat_heard.payloads(THRUST)) >= 20, 10, what="the boat's own commands")
        time.sleep(0.5)
        assert [p for p in boat_heard.payloads(THRUST) if not p.startswith(b"boat ")] == []
        assert boat_heard.payloads(keys.LOCKSTEP_RECORDER.key(VESSEL)) == []
        assert replies(estimator, keys.NAV_RESET.key(VESSEL), 2.0) == [], "an impostor served nav/reset"
        assert "controller" not in tokens(estimator), "a forged health token reached the boat"

        # The boat router refused them, and says so like every service: `seaway health` on the boat.
        def counted() -> dict[tuple[str, str, str], int]:
            report = health_json(dep, boat_port, tmp_path)
            return {(c["identity"], c["action"], c["key"]): c["count"]
                    for r in report["refusals"] if r["identity"] == access.RELAY for c in r["counts"]}

        counts = wait_for(lambda: (c := counted()).get(("router", "put", THRUST), 0) >= 20 and c, 20,
                          what="the boat router's refusal counts")
        assert counts.get(("recorder", "put", THRUST), 0) >= 20, counts
        assert counts.get(("unauthenticated", "connect", ""), 0) >= 2, counts
        for entity in (served, *forged):
            entity.undeclare()
    finally:
        close(controller, estimator, rogue_router, rogue_recorder)
    stop_routers(procs, shore_router, boat_router)


def test_over_a_real_interface_only_the_shore_router_gets_in(procs: Procs, dep: Path) -> None:
    """Dialled on a non-loopback address, as on the water: the shore router carries the shore's
    rights, and nothing else of the authority gets anything (on loopback, a dry run on one computer,
    the same certificates would count as boat processes at the boat router)."""
    addr = link_address()
    if addr is None:
        pytest.skip("this computer has no non-loopback address (tests/system/deploy/test_netns.py "
                    "shows the same across two network namespaces)")
    link = free_port()
    boat_router, shore_router, boat_port, shore_port = start_routers(
        procs, dep, f"tls/{addr}:{link}", f"tls/{addr}:{link}", boat_health=False)
    over_link = (rf"link up: tls/{re.escape(addr)}:{link} <-> .*interfaces (?!lo\b)\w+.*"
                 "authenticated as router")
    wait_for(lambda: re.search(over_link, Procs.log(boat_router)), 10,
             what="the boat router's log of the shore router's link on a real interface")
    at_link = f"tls/{addr}:{link}"
    controller = session("boat", "controller", dep, f"tls/127.0.0.1:{boat_port}")
    estimator = session("boat", "estimator", dep, f"tls/127.0.0.1:{boat_port}")
    operator = session("shore", "operator", dep, f"tls/127.0.0.1:{shore_port}")
    rogue_router = session("shore", "router", dep, at_link, rules=False, mode="client")
    direct_operator = session("shore", "operator", dep, at_link, mode="client")
    boat_cert_outside = session("boat", "controller", dep, at_link, rules=False, mode="client")
    try:
        boat_heard = Collector(estimator)
        direct_heard = Collector(direct_operator)
        served = controller.declare_queryable(MISSION_SET, lambda q: q.reply(q.key_expr, BOAT_SAYS))
        wait_for(lambda: replies(operator, MISSION_SET, 1.0) == [BOAT_SAYS], 20,
                 what="the shore operator's request answered over the link")
        # The boat router's own rights (its health, its refusal counts) are not the shore's.
        forged = [rogue_router.liveliness().declare_token(keys.health_key(VESSEL, access.RELAY)),
                  rogue_router.declare_queryable(keys.refusals_key(VESSEL, access.RELAY),
                                                 lambda q: q.reply(q.key_expr, b"forged"))]
        for i in range(20):
            rogue_router.put(keys.refusals_key(VESSEL, access.RELAY), b"forged")
            boat_cert_outside.put(THRUST, f"outside {i}".encode())
            controller.put(THRUST, f"boat {i}".encode())
            time.sleep(0.02)
        assert replies(rogue_router, MISSION_SET) == [BOAT_SAYS], "the shore's rights are still there"
        wait_for(lambda: len(boat_heard.payloads(THRUST)) >= 20, 10, what="the boat's own commands")
        time.sleep(0.5)
        assert [p for p in boat_heard.payloads(THRUST) if not p.startswith(b"boat ")] == []
        assert b"forged" not in boat_heard.payloads(keys.refusals_key(VESSEL, access.RELAY))
        assert "router" not in tokens(estimator), "the shore declared the boat router's health"
        boat_router_says = replies(estimator, keys.refusals_key(VESSEL, access.RELAY))
        assert boat_router_says and all(Refusals.decode(r.encode()).identity == access.RELAY
                                        for r in boat_router_says), boat_router_says
        # The shore's operator certificate straight to the link port is nobody on the boat.
        assert direct_heard.payloads(THRUST) == [], "a certificate other than the router's read boat data"
        assert replies(direct_operator, MISSION_SET, 2.0) == []
        for entity in (served, *forged):
            entity.undeclare()
    finally:
        close(controller, estimator, operator, rogue_router, direct_operator, boat_cert_outside)
    stop_routers(procs, shore_router, boat_router)
