"""Vessel names from the bus are bounded: a publisher making up names cannot grow the ground
station without end, push out a vessel that is alive, or get a name the API cannot address shown.

Reproduced before the bound: 20 000 made-up names took 150 MB, a 7 MB first frame (0.9 s on the
event loop) to every stream client and 1.1 s per ``GET /api/vessels``, all without limit."""

from __future__ import annotations

from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import StateEstimate, message_encoding
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.settings import Settings
from seaway_groundstation.stream import StreamClient

TOKEN = "bound-token-0123456789abcdef"


def state(x_m: float) -> StateEstimate:
    return StateEstimate(stamp_ns=5, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=0.0, psi_rad=0.0)


def test_a_flood_of_made_up_vessel_names_is_refused_counted_and_the_real_vessel_stays() -> None:
    hub = MemoryHub()
    real = hub.bus("v1")
    real.declare_alive("controller")
    real.publisher(keys.NAV_STATE).put(state(1.0))
    liar = hub.bus("liar")
    with TestClient(create_app(hub.bus("gs"), Settings(token=TOKEN, max_vessels=8))) as client:
        for i in range(500):
            liar.publisher(keys.NAV_STATE, vessel=f"ghost{i}").put(state(1e7))
        real.publisher(keys.NAV_STATE).put(state(2.0))
        fleet = client.get("/api/vessels").json()
        names = [v["vessel"] for v in fleet["vessels"]]
        assert len(names) <= 8 and "v1" in names
        assert fleet["max_vessels"] == 8 and fleet["vessels_refused"] >= 500 - 8
        v1 = client.get("/api/vessels/v1").json()
        assert v1["state"]["message"]["x_m"] == 2.0  # the real vessel is still heard
        with client.websocket_connect("/api/stream") as ws:  # the first frame: the kept ones only
            frames = [ws.receive_json() for _ in range(len(names))]
        assert sorted(f["vessel"] for f in frames) == sorted(names)


def test_a_key_whose_vessel_name_is_not_valid_is_dropped_and_counted() -> None:
    hub = MemoryHub()
    liar = hub.bus("liar")
    with TestClient(create_app(hub.bus("gs"), Settings(token=TOKEN))) as client:
        # 65 characters: over the name's 64 (the typed publisher refuses it; the wire does not).
        liar.raw_publisher(f"{keys.ROOT}/{'x' * 65}/{keys.NAV_STATE.suffix}",
                           message_encoding(StateEstimate)).put(state(1.0).encode())
        fleet = client.get("/api/vessels").json()
        assert fleet["vessels"] == [] and fleet["vessels_refused"] == 1


def test_a_silent_vessel_without_services_makes_room_a_live_one_never_does() -> None:
    fleet = Fleet(max_vessels=2, forget_after_s=60.0)
    fleet.on_health("alive", "controller", True, 0.0)
    assert fleet.on_message("ghost", "state", state(1.0), 0.0)
    client = StreamClient(None)
    client.take(fleet, 0.0, 0.05, 0.0)
    assert {k[0] for k in client.seen} == {"alive", "ghost"}
    assert not fleet.on_message("new", "state", state(1.0), 30.0)  # the ghost spoke 30 s ago
    assert fleet.refused == 1 and fleet.vessels() == ["alive", "ghost"]
    assert fleet.on_message("new", "state", state(1.0), 61.0)  # now it may be forgotten
    assert fleet.vessels() == ["alive", "new"] and fleet.forgotten == 1
    # "alive" has been silent as long, but its controller's health token is there: kept.
    assert not fleet.on_message("newer", "state", state(1.0), 200.0) or fleet.knows("alive")
    assert fleet.knows("alive")
    client.take(fleet, 200.0, 0.05, 200.0)  # the client forgets the forgotten vessel's keys
    assert "ghost" not in {k[0] for k in client.seen} | {k[0] for k in client.budget}
