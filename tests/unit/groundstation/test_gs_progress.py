"""The page's live figures that the ground station computes: the paper's metrics of the current
mission from the states and thrusts it hears (worked out by hand here), the mission flown drawn in
metres (sent from here, or the launcher's mission.json), the NED frame's scale, and the address
file the launcher can read the page's address and token from."""

from __future__ import annotations

import json
import math
import stat
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import (
    MissionRequest,
    MissionStatus,
    NavOrigin,
    Reply,
    StateEstimate,
    ThrustCommand,
    Waypoint,
)
from seaway.runtime.memory_bus import MemoryHub
from seaway.vessel.frames import GeoOrigin
from seaway_groundstation import geo
from seaway_groundstation.app import create_app
from seaway_groundstation.progress import MissionTrack
from seaway_groundstation.service import write_address
from seaway_groundstation.settings import Settings

TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
T0 = 1_000_000_000_000
DT_NS = 100_000_000
ALPHA = 0.5
WPS = [(0.0, 0.0), (10.0, 0.0)]  # north 10 m, r_COA 1 m


def s(i: int, y: float = 0.5) -> StateEstimate:
    """The vessel 0.5 m east of the line, at 1 m/s north, one sample per 0.1 s."""
    return StateEstimate(stamp_ns=T0 + i * DT_NS, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * i, y_m=y,
                         psi_rad=0.0)


def status(i: int, state: str = "active", mission_id: str = "m1") -> MissionStatus:
    return MissionStatus(stamp_ns=T0 + i * DT_NS, state=state, mission_id=mission_id, waypoint_count=2)


def thrust(i: int, t_n: float = 4.0) -> ThrustCommand:
    return ThrustCommand(stamp_ns=T0 + i * DT_NS, thrust_port_n=t_n, thrust_starboard_n=t_n)


def fly(track: MissionTrack, n: int = 101) -> None:
    track.on_state(s(0))  # before the status that says the mission started: seeds the track
    track.on_status(status(0))
    for i in range(n):
        if i:
            track.on_state(s(i))
        track.on_thrust(thrust(i))
        track.on_status(status(i))


def test_metrics_of_a_straight_run_worked_out_by_hand() -> None:
    track = MissionTrack()
    fly(track)
    m = track.metrics(WPS, coa_radius_m=1.0, task_power_w=2.0, alpha_w_per_n2=ALPHA)
    assert m is not None and m.mission_id == "m1"
    # The circle of P1 (1 m) is entered when sqrt((10 - x)^2 + 0.5^2) <= 1: x >= 9.134, sample 92.
    assert m.completed and m.travel_time_s == pytest.approx(9.2)
    # Every sample is 0.5 m off the line; those inside P0's circle (x <= 0.866, samples 0-8) do not
    # count, nor the end instant: samples 9..91.
    assert m.avg_cross_track_m == pytest.approx(0.5) and m.cross_track_samples == 83
    # alpha (T1^2 + T2^2) + T^w = 0.5 * 32 + 2 = 18 W over 9.2 s.
    assert m.energy_j == pytest.approx(18.0 * 9.2)
    no_alpha = track.metrics(WPS, 1.0, 2.0, alpha_w_per_n2=None)
    assert no_alpha is not None and no_alpha.energy_j is None
    assert no_alpha.avg_cross_track_m == pytest.approx(0.5)


def test_a_new_mission_or_a_restart_starts_a_new_track_and_samples_stop_at_completion() -> None:
    track = MissionTrack()
    fly(track, n=20)
    track.on_status(status(20, "complete"))
    track.on_state(s(21))
    assert len(track.states) == 20  # nothing kept once complete
    track.on_status(status(30, "active"))  # the same mission started again
    assert track.start_ns == T0 + 30 * DT_NS and track.states == []
    track.on_status(status(31, "active", mission_id="m2"))
    assert track.mission_id == "m2" and track.start_ns == T0 + 31 * DT_NS
    track.on_state(s(5))  # from before the start (another episode): out of order, not kept after one
    track.on_state(s(40))
    track.on_state(s(39))
    assert [x.stamp_ns for x in track.states] == [T0 + 5 * DT_NS, T0 + 40 * DT_NS]


def test_frame_scale_matches_the_origins_own_conversion() -> None:
    origin = GeoOrigin.from_degrees(28.18, 112.94, 30.0)
    view = geo.frame_view(origin)
    assert view is not None
    lat, lon, _ = origin.to_geodetic(120.0, -80.0, 0.0)
    # The page's linear conversion, 144 m from the origin, against the exact one: within 1 cm.
    north = (math.degrees(lat) - view.lat0_deg) * view.north_m_per_deg
    east = (math.degrees(lon) - view.lon0_deg) * view.east_m_per_deg
    assert north == pytest.approx(120.0, abs=0.01) and east == pytest.approx(-80.0, abs=0.01)
    req = MissionRequest(stamp_ns=1, coa_radius_m=1, task_power_w=1,
                         waypoints=[Waypoint(x_m=1.0, y_m=2.0), Waypoint(lat_deg=math.degrees(lat),
                                                                         lon_deg=math.degrees(lon))])
    plan = geo.mission_plan(req, origin, "test")
    assert plan.waypoints_m[0] == (1.0, 2.0)
    assert plan.waypoints_m[1] == pytest.approx((120.0, -80.0), abs=1e-6)
    with pytest.raises(geo.NoOriginError):
        geo.mission_plan(req, None, "test")


def test_the_view_draws_the_mission_flown_and_the_metrics_come_from_what_was_heard(tmp_path: Path) -> None:
    hub = MemoryHub()
    vessel = hub.bus("v1")
    vessel.declare_alive("controller")
    vessel.queryable(keys.MISSION_SET, lambda req: Reply.accept(1, "mission started"))
    settings = Settings(token=TOKEN, run_dir=tmp_path, alpha_w_per_n2=ALPHA)
    with TestClient(create_app(hub.bus("gs"), settings)) as c:
        body = {"mission_id": "m1", "coa_radius_m": 1.0, "task_power_w": 2.0,
                "waypoints": [{"x_m": 0, "y_m": 0}, {"x_m": 10, "y_m": 0}]}
        assert c.post("/api/vessels/v1/mission", json=body, headers=AUTH).status_code == 200
        assert c.get("/api/vessels/v1/metrics").json() is None  # no status names it yet
        pub = {spec: vessel.publisher(spec) for spec in (keys.NAV_STATE, keys.THRUST, keys.MISSION_STATUS)}
        pub[keys.MISSION_STATUS].put(status(0))
        for i in range(101):
            pub[keys.NAV_STATE].put(s(i))
            pub[keys.THRUST].put(thrust(i))
            pub[keys.MISSION_STATUS].put(status(i))
        view = c.get("/api/vessels/v1").json()
        assert view["active_mission"]["waypoints_m"] == [[0.0, 0.0], [10.0, 0.0]]
        assert view["active_mission"]["source"] == "groundstation"
        assert view["thrust"]["message"]["thrust_port_n"] == 4.0
        m = c.get("/api/vessels/v1/metrics").json()
        assert m["completed"] and m["avg_cross_track_m"] == pytest.approx(0.5)
        assert m["energy_j"] == pytest.approx(18.0 * 9.2)
        # The request went into the run folder's journal, with the mission as sent.
        (line,) = (tmp_path / "groundstation" / "requests.jsonl").read_text().splitlines()
        entry = json.loads(line)
        assert entry["request"] == "mission/set" and entry["outcome"] == "accepted"
        assert entry["message"]["mission_id"] == "m1"

        # The launcher's mission (mission.json in the run folder) is drawn once a status names it.
        launcher = MissionRequest(stamp_ns=1, mission_id="lake", coa_radius_m=2.0, task_power_w=250.0,
                                  waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=22, y_m=0)])
        (tmp_path / "mission.json").write_text(launcher.model_dump_json())
        pub[keys.MISSION_STATUS].put(status(200, mission_id="lake"))
        view = c.get("/api/vessels/v1").json()
        assert view["active_mission"]["mission_id"] == "lake"
        assert view["active_mission"]["source"] == "launcher"
        pub[keys.MISSION_STATUS].put(status(201, mission_id="unknown"))
        assert c.get("/api/vessels/v1").json()["active_mission"] is None


def test_the_view_has_the_frame_scale_once_an_origin_is_heard() -> None:
    hub = MemoryHub()
    vessel = hub.bus("v1")
    vessel.declare_alive("estimator")
    with TestClient(create_app(hub.bus("gs"), Settings(token=TOKEN))) as c:
        assert c.get("/api/vessels/v1").json()["geo"] is None
        vessel.publisher(keys.NAV_ORIGIN).put(NavOrigin(stamp_ns=1, lat_rad=math.radians(45.0),
                                                        lon_rad=0.0, alt_m=0.0))
        g = c.get("/api/vessels/v1").json()["geo"]
        assert g["lat0_deg"] == pytest.approx(45.0)
        assert 111_000 < g["north_m_per_deg"] < 111_300 and 78_700 < g["east_m_per_deg"] < 78_900


def test_the_address_file_is_readable_by_its_owner_only(tmp_path: Path) -> None:
    old = tmp_path / "groundstation" / "address.json"
    old.parent.mkdir()
    old.write_text("{}")
    old.chmod(0o644)  # a file left with wider bits is narrowed, not trusted
    path = write_address(tmp_path, "http://127.0.0.1:8321/", "secret-token-0123456789")
    assert path == old and stat.S_IMODE(path.stat().st_mode) == 0o600
    doc = json.loads(path.read_text())
    assert doc["page"] == "http://127.0.0.1:8321/#token=secret-token-0123456789"
    assert doc["url"] == "http://127.0.0.1:8321/" and doc["token"] == "secret-token-0123456789"


def test_a_track_keeps_only_what_the_metrics_read_of_each_sample() -> None:
    """Reproduced: each state was kept whole, its 81-number covariance too (the estimator sends
    one at 20 Hz): 4.2 kB a sample, 1.5 GB per vessel at the track's bound of samples."""
    import tracemalloc

    from seaway.contract.messages import MissionStatus as Status

    track = MissionTrack()
    track.on_status(Status(stamp_ns=T0, state="active", mission_id="m"))
    n = 2000
    wire = [StateEstimate(stamp_ns=T0 + k, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=float(k), y_m=0.0,
                          psi_rad=0.0, covariance=[0.1 * k] * 81).encode() for k in range(n)]
    tracemalloc.start()
    try:
        for payload in wire:  # decoded as the bus does; only what the track keeps stays
            track.on_state(StateEstimate.decode(payload))
        kept_b, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(track.states) == n
    assert kept_b / n < 400  # bytes a sample (a whole message: ~4200)
    assert [p.x_m for p in track.states[:3]] == [0.0, 1.0, 2.0]
