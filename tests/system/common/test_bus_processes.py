"""Bus: separate processes exchange typed messages and requests over Zenoh on loopback.

The behaviour both bus transports share is in tests/contract/test_bus_contract.py; here it is
checked across real processes (the raw calls send what a typed publisher would refuse).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, ScenarioRequest, ThrustCommand
from seaway.runtime.bus import Bus

from tests.conftest import wait_for

pytestmark = pytest.mark.system
PEER = str(Path(__file__).with_name("bus_peer.py"))


def lines(procs, p) -> list[dict]:
    out = []
    for line in procs.log(p).splitlines():
        if line.startswith("{"):
            out.append(json.loads(line))
    return out


def test_two_processes_exchange_messages_and_requests(procs, zenoh_env) -> None:
    resp = procs.start([sys.executable, PEER, "responder"], zenoh_env, "responder")
    wait_for(lambda: "READY" in procs.log(resp), 10, what="responder ready")
    talk = procs.start([sys.executable, PEER, "talker"], zenoh_env, "talker")

    # Typed messages flow in order from one process to the other.
    got = wait_for(lambda: [d for d in lines(procs, resp) if "seq" in d] if
                   len([d for d in lines(procs, resp) if "seq" in d]) >= 20 else None, 15,
                   what="20 thrust messages at the responder")
    seqs = [d["seq"] for d in got]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    assert all(d["port"] == float(d["seq"]) for d in got)

    # The request from the talker is answered by the responder's queryable.
    reply = wait_for(lambda: [d for d in lines(procs, talk) if "reply" in d], 10, what="a reply")[0]
    assert reply == {"reply": True, "reason": "armed"}

    # This test process is a third peer: a refusal comes back with its reason, and a malformed
    # payload on the responder's key is dropped while the responder keeps receiving.
    with Bus.open("vessel1") as bus:
        r = bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=False), timeout_s=3)
        assert (r.accepted, r.reason) == (False, "disarm refused by test responder")
        bad = bus.query_raw(keys.VEHICLE_ARM.key("vessel1"), b"{not json", timeout_s=3)
        refused = [x for x in bad if x.error is None]
        assert refused and b"malformed request" in refused[0].payload
        raw = bus.raw_publisher(keys.THRUST.key("vessel1"))
        raw.put(b'{"stamp_ns": 1, "thrust_port_n": NaN}')
        raw.put(b"\x00\x01garbage")
        n_before = len(lines(procs, resp))
        wait_for(lambda: any(d.get("malformed", 0) >= 2 for d in lines(procs, resp)[n_before:]), 10,
                 what="responder to count 2 malformed and keep receiving")
        assert "dropped malformed payload on seaway/vessel1/ctrl/thrust" in procs.log(resp)
        assert resp.poll() is None

        # Health tokens: the responder declared one; it disappears when the process stops.
        wait_for(lambda: "launcher" in bus.alive_services(), 5, what="responder's health token")

        # SIGTERM ends both promptly.
        for p in (talk, resp):
            assert procs.stop(p, signal.SIGTERM, timeout_s=2.0) < 2.0
            assert p.returncode == 0, procs.log(p)
        wait_for(lambda: "launcher" not in bus.alive_services(timeout_s=0.5), 5,
                 what="health token gone after exit")


def test_wrong_type_refused_before_the_wire(zenoh_env) -> None:
    with Bus.open("vessel1") as bus:
        pub = bus.publisher(keys.NAV_STATE)
        with pytest.raises(TypeError, match="carries StateEstimate, not ThrustCommand"):
            pub.put(ThrustCommand.make(stamp_ns=1, thrust_port_n=0.0, thrust_starboard_n=0.0))
        r = bus.request(keys.SIM_SCENARIO, ScenarioRequest.make(
            stamp_ns=1, action="restart"), timeout_s=0.3)
        assert not r.accepted and "no reply" in r.reason
    time.sleep(0)


LEAVES_OPEN = """
import sys
from seaway.contract import keys
from seaway.runtime.bus import Bus
bus = Bus.open("vessel1")
bus.subscribe(keys.SIM_CLOCK, callback=lambda key, msg: None)
bus.subscribe(keys.MISSION_STATUS, mode="latest")
print("OPEN", flush=True)
if sys.argv[1] == "raise":
    raise RuntimeError("a service bug")
"""


@pytest.mark.parametrize("how", ["return", "raise"])
def test_a_process_that_leaves_its_bus_open_still_exits(zenoh_env, how) -> None:
    """zenoh-python serves callbacks on non-daemon threads that end only with their session: an
    open bus once kept a crashed service (so the launcher never restarted it) and a failed test's
    pytest (so CI ran out of time) alive for ever."""
    out = subprocess.run([sys.executable, "-c", LEAVES_OPEN, how], env=zenoh_env,
                         capture_output=True, text=True, timeout=60, check=False)
    assert "OPEN" in out.stdout, out.stderr
    assert out.returncode == (0 if how == "return" else 1), out.stderr
    if how == "raise":
        assert "RuntimeError: a service bug" in out.stderr
