"""The energy budget on the ground station (issue #17 item 5): ``mission/energy`` in the API's vessel
view, in the live stream's frames and in a recording's replay frames, with budgets constructed here
on the in-memory bus and with the recorder's own writer."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import EnergyBudget, MissionStatus, NavOrigin, StateEstimate
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.settings import Settings
from seaway_recorder.core import RecordingWriter

TOKEN = "test-token-0123456789abcdef"
T0 = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000


def budget(k: int, mission_id: str = "box", **fields: Any) -> EnergyBudget:
    """The budget at period k: 10 J used per period, a point of no return 30 m north."""
    base = dict(stamp_ns=T0 + k * PERIOD_NS, mission_id=mission_id, active_leg=1,
                energy_used_j=10.0 * k, energy_to_go_j=900.0 - 10.0 * k, energy_to_go_low_j=850.0 - 10.0 * k,
                energy_to_go_high_j=950.0 - 10.0 * k, energy_to_home_j=120.0, home_x_m=0.0,
                home_y_m=0.0, battery_remaining_j=5000.0 - 10.0 * k, reserve_j=1000.0,
                margin_j=3880.0 - 10.0 * k, no_return_x_m=30.0, no_return_y_m=4.0,
                no_return_along_m=25.0, policy="return", decision="none")
    return EnergyBudget.make(**(base | fields))


@pytest.fixture
def hub() -> MemoryHub:
    return MemoryHub()


@pytest.fixture
def vessel(hub: MemoryHub) -> Iterator[MemoryBus]:
    bus = hub.bus("v1")
    bus.declare_alive("controller")
    yield bus
    bus.close()


@pytest.fixture
def client(hub: MemoryHub, vessel: MemoryBus) -> Iterator[TestClient]:
    with TestClient(create_app(hub.bus("gs"), Settings(token=TOKEN))) as c:
        yield c


def test_the_vessel_view_carries_the_budgets_figures(client: TestClient, vessel: MemoryBus) -> None:
    assert client.get("/api/vessels/v1").json()["energy"] is None
    pub = vessel.publisher(keys.MISSION_ENERGY)
    pub.put(budget(1))
    pub.put(budget(2, decision="return", decided_ns=T0 + 2 * PERIOD_NS, reason="to home reached"))
    e = client.get("/api/vessels/v1").json()["energy"]
    assert e["age_s"] >= 0 and not e["stale"]
    m = e["message"]
    assert (m["energy_used_j"], m["energy_to_go_j"], m["energy_to_home_j"]) == (20.0, 880.0, 120.0)
    assert (m["battery_remaining_j"], m["reserve_j"], m["margin_j"]) == (4980.0, 1000.0, 3860.0)
    assert (m["no_return_x_m"], m["no_return_y_m"], m["no_return_along_m"]) == (30.0, 4.0, 25.0)
    assert m["decision"] == "return" and m["reason"] == "to home reached"
    # The schema documents it.
    view = client.get("/openapi.json").json()["components"]["schemas"]["VesselView"]
    assert "point of no return" in view["properties"]["energy"]["description"]


def test_the_stream_sends_the_latest_budget(client: TestClient, vessel: MemoryBus) -> None:
    pub = vessel.publisher(keys.MISSION_ENERGY)
    pub.put(budget(1))
    with client.websocket_connect("/api/stream?vessel=v1") as ws:
        first = ws.receive_json()
        assert first["updates"]["energy"]["message"]["energy_to_go_j"] == 890.0
        pub.put(budget(7, decision="warn", decided_ns=T0))
        while True:
            frame = ws.receive_json()
            got = frame["updates"].get("energy", {}).get("message")
            if got is not None:
                break
        assert got["energy_to_go_j"] == 830.0 and got["decision"] == "warn"


def test_a_recordings_budgets_replay_as_live_frames(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    run = runs / "energy-run"
    run.mkdir(parents=True)
    w = RecordingWriter(run / "recording.mcap", foxglove=False)
    w.open(T0)

    def put(spec: keys.KeySpec, msg: Any, at_ns: int) -> None:
        assert w.write(spec.key("boat7"), msg.encode(), f"application/json;{msg.SCHEMA}", at_ns)

    put(keys.NAV_ORIGIN, NavOrigin(stamp_ns=T0, lat_rad=math.radians(47.0), lon_rad=math.radians(8.0),
                                   alt_m=0.0), T0)
    for k in range(20):
        t = T0 + k * PERIOD_NS
        put(keys.NAV_STATE, StateEstimate(stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * k,
                                          y_m=0.0, psi_rad=0.0), t + 1_000_000)
        put(keys.MISSION_STATUS, MissionStatus(stamp_ns=t, state="active", mission_id="box",
                                               active_leg=1, waypoint_count=2), t + 2_000_000)
        put(keys.MISSION_ENERGY, budget(k), t + 3_000_000)
    w.close(T0 + 20 * PERIOD_NS)
    with TestClient(create_app(MemoryHub().bus("gs"), Settings(token=TOKEN, runs_dir=runs))) as c:
        r = c.get("/api/recording/frames", params={"id": "energy-run", "start_s": 0, "end_s": 100})
        assert r.status_code == 200, r.text
        frames = [f["frame"] for f in r.json()["frames"]]
    energies = [f["updates"]["energy"]["message"] for f in frames if "energy" in f["updates"]]
    assert energies and energies[-1]["energy_used_j"] == 190.0
    assert energies[-1]["no_return_along_m"] == 25.0
    # Exactly what a live client would have had: the same message, as the fleet keeps it.
    live = Fleet(2.0)
    live.on_message("boat7", "energy", budget(19), 0.0)
    (frame,) = live.changes({}, None, 0.0)
    assert json.loads(frame)["updates"]["energy"]["message"] == energies[-1]
