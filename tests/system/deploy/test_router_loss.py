"""The boat's control loop does not depend on the boat router: the peers mesh directly, so killing
the router (SIGKILL) loses nothing between them, and a restarted router is rejoined by itself.

Runs the shipped boat-client.json5 with only its router port moved (a copy in tmp), on loopback,
every process an identity of the boat's credentials (``seaway credentials create --deployment``):
mutual TLS between the peers and the boat's access rules, as on the water.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import Procs, free_port, wait_for
from tests.system.deploy import deployment
from tests.system.deploy.standin import FORBIDDEN_SEQ0

pytestmark = pytest.mark.system
STANDIN = str(Path(__file__).with_name("standin.py"))
THRUST = "seaway/vessel1/ctrl/thrust"


def records(p) -> list[dict]:
    out = []
    for line in Path(p.log_path).read_text(errors="replace").splitlines():
        if line.startswith("{"):
            out.append(json.loads(line))
    return out


def test_boat_loop_survives_its_router(procs: Procs, tmp_path: Path) -> None:
    port = free_port()
    dep = deployment.create(tmp_path / "creds")
    client = deployment.client_file("boat", tmp_path, port)
    env = {k: v for k, v in os.environ.items()
           if k not in ("SEAWAY_ZENOH_RENDEZVOUS", "SEAWAY_ZENOH_CONFIG", "SEAWAY_IDENTITY")}
    env |= {"SEAWAY_CREDENTIALS": str(dep / "boat"), "PYTHONUNBUFFERED": "1"}
    router_env = dict(env)
    env["SEAWAY_ZENOH_CONFIG"] = str(client)
    router = [sys.executable, "-m", "seaway.tools.router", "--role", "boat",
              "--listen", f"tls/127.0.0.1:{port}"]
    r1 = procs.start(router, env=router_env, name="router1")
    rec = procs.start([sys.executable, STANDIN, "boat-recorder"], env=env, name="recorder")
    wait_for(lambda: '"ready"' in Procs.log(rec), 20, what="recorder stand-in")
    ctl = procs.start([sys.executable, STANDIN, "boat-control", "--rate-hz", "50"], env=env, name="control")
    wait_for(lambda: len([r for r in records(rec) if r.get("key") == THRUST]) > 50, 20,
             what="commands recorded")
    r1.send_signal(signal.SIGKILL)
    r1.wait(5)
    t_kill = time.monotonic()
    time.sleep(3.0)
    r2 = procs.start(router, env=router_env, name="router2")
    wait_for(lambda: Procs.log(r2).count("peer ") >= 2 and "connected" in Procs.log(r2), 15,
             what="the peers back on the restarted router")
    time.sleep(1.0)
    assert procs.stop(ctl, signal.SIGINT) < 5
    time.sleep(0.5)
    assert procs.stop(rec, signal.SIGINT) < 5
    procs.stop(r2, signal.SIGINT)

    published = next(r["published"] for r in records(ctl) if r.get("event") == "stopped")
    got = [r for r in records(rec) if r.get("key") == THRUST]
    seqs = [r["seq"] for r in got]
    assert seqs == list(range(1, published + 1)), \
        f"lost {sorted(set(range(1, published + 1)) - set(seqs))[:20]} of {published}"
    assert not [s for s in seqs if s >= FORBIDDEN_SEQ0]
    without_router = [r for r in got if t_kill < r["t"] < t_kill + 3.0]
    assert len(without_router) >= 0.9 * 50 * 3.0, f"{len(without_router)} commands while the router was dead"
