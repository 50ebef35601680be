"""The real ``seaway-groundstation`` process on a real Zenoh session with the stack's credentials:
it prints its address and token, lists the vessel this test declares health for, refuses a command
without the token, and carries a command with the token to the test's queryable and back."""

from __future__ import annotations

import json
import re
import signal
from typing import Any

import pytest
from seaway.contract import keys
from seaway.contract.messages import Reply, StateEstimate
from seaway.runtime.bus import Bus
from websockets.sync.client import connect

from tests.conftest import BIN, wait_for
from tests.system.groundstation.helpers import http

pytestmark = pytest.mark.system
VESSEL = "gs-test-boat"




def test_groundstation_process_serves_the_fleet_and_guards_commands(procs, zenoh_env) -> None:
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--request-timeout-s", "5"],
                     zenoh_env, "groundstation")
    line = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/) token (\S+)",
                                      procs.log(gs)), 30, what="the ground station's address line")
    base, token = line.group(1), line.group(2)
    with Bus.open(VESSEL) as bus:  # the test plays the vessel's vehicle_io
        arms: list[bool] = []

        def on_arm(req: Any) -> Reply:
            arms.append(req.arm)
            return Reply.accept(1, "armed by the test")

        bus.queryable(keys.VEHICLE_ARM, on_arm)
        bus.declare_alive("vehicle_io")

        def seen() -> list[dict]:
            status, body = http("GET", base + "api/vessels")
            assert status == 200
            return [v for v in body["vessels"] if v["vessel"] == VESSEL]

        (vessel,) = wait_for(seen, 20, what=f"{VESSEL} in /api/vessels")
        assert vessel["services"] == ["vehicle_io"]
        status, body = http("POST", base + f"api/vessels/{VESSEL}/arm")
        assert status == 401 and "Bearer" in body["detail"]
        status, _ = http("POST", base + f"api/vessels/{VESSEL}/arm", token="wrong-token")
        assert status == 403
        assert arms == []
        status, body = http("POST", base + f"api/vessels/{VESSEL}/arm", token=token)
        assert status == 200, body
        assert body["accepted"] and body["reason"] == "armed by the test" and arms == [True]
        # the live stream over a real WebSocket: the state the test publishes comes back
        ws_url = base.replace("http://", "ws://") + f"api/stream?vessel={VESSEL}"
        with connect(ws_url, open_timeout=10) as ws:
            assert json.loads(ws.recv(timeout=10))["vessel"] == VESSEL
            pub = bus.publisher(keys.NAV_STATE)

            def state_back() -> bool:
                pub.put(StateEstimate(stamp_ns=1, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=12.5,
                                      y_m=-3.0, psi_rad=0.2))
                frame = json.loads(ws.recv(timeout=2))
                return frame["updates"].get("state", {}).get("message", {}).get("x_m") == 12.5

            wait_for(state_back, 20, what="the published state on the stream")
    status, _ = http("GET", base + "api/vessels/nobody-here")
    assert status == 404
    procs.stop(gs, signal.SIGTERM, timeout_s=10)
    assert gs.returncode == 0, procs.log(gs)
