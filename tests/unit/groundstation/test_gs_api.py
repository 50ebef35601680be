"""The ground station's API with FastAPI's test client over the in-memory bus: a responder plays the
vessel's services (vehicle_io, controller, sim), answering the requests the API turns into."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import pytest
from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import (
    MissionStatus,
    NavOrigin,
    Reply,
    SolveRecord,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.settings import Settings

DATA = Path(__file__).parent / "data"
TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
SQUARE_M = [{"x_m": 0, "y_m": 0}, {"x_m": 20, "y_m": 0}, {"x_m": 20, "y_m": 20}]


@dataclass
class Vessel:
    """The vessel's side: services alive on ``v1`` that answer and remember each request."""

    bus: MemoryBus
    requests: dict[str, list[Any]] = field(default_factory=dict)

    def serve(self, spec: keys.KeySpec, refuse: str | None = None) -> None:
        def handle(req: Any) -> Reply:
            self.requests.setdefault(spec.suffix, []).append(req)
            if refuse:
                return Reply.refuse(1, refuse)
            return Reply.accept(1, f"{spec.suffix} done")

        self.bus.queryable(spec, handle)

    def publish(self, spec: keys.KeySpec, msg: Any) -> None:
        self.bus.publisher(spec).put(msg)


@pytest.fixture
def hub() -> MemoryHub:
    return MemoryHub()


@pytest.fixture
def vessel(hub: MemoryHub) -> Iterator[Vessel]:
    bus = hub.bus("v1")
    for service in ("vehicle_io", "controller", "estimator"):
        bus.declare_alive(service)
    v = Vessel(bus)
    for spec in (keys.VEHICLE_ARM, keys.MISSION_SET, keys.MISSION_COMMAND):
        v.serve(spec)
    yield v
    bus.close()


def client_for(hub: MemoryHub, **overrides: Any) -> TestClient:
    settings = Settings(token=TOKEN, request_timeout_s=2.0, **overrides)
    return TestClient(create_app(hub.bus("gs"), settings))


@pytest.fixture
def client(hub: MemoryHub, vessel: Vessel) -> Iterator[TestClient]:
    with client_for(hub) as c:
        yield c


def state(x_m: float) -> StateEstimate:
    return StateEstimate(stamp_ns=5, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=2.0, psi_rad=0.1)


def mission(**extra: Any) -> dict[str, Any]:
    return {"waypoints": SQUARE_M, "coa_radius_m": 2.0, "task_power_w": 10.0, **extra}


# -- reading --------------------------------------------------------------------------------------


def test_fleet_shows_vessels_from_health_with_their_latest_messages(client: TestClient,
                                                                     vessel: Vessel) -> None:
    vessel.publish(keys.NAV_STATE, state(1.0))
    vessel.publish(keys.NAV_STATE, state(4.0))
    vessel.publish(keys.VEHICLE_STATUS, VehicleStatus(stamp_ns=5, autopilot="px4", link_ok=True,
                                                      armed=False, mode="MANUAL"))
    vessel.publish(keys.MISSION_STATUS, MissionStatus(stamp_ns=5, state="idle"))
    vessel.publish(keys.SOLVE, SolveRecord(stamp_ns=5, controller="cc-empc", status="ok", success=True,
                                           iterations=3, solve_time_s=1e-4,
                                           predicted_x_m=[0.0, 1.0], predicted_y_m=[0.0, 0.5]))
    r = client.get("/api/vessels")
    assert r.status_code == 200
    (v1,) = r.json()["vessels"]
    assert v1["vessel"] == "v1" and v1["services"] == ["controller", "estimator", "vehicle_io"]
    assert v1["state"]["message"]["x_m"] == 4.0 and v1["state"]["age_s"] >= 0
    assert v1["vehicle"]["message"]["mode"] == "MANUAL" and v1["mission"]["message"]["state"] == "idle"
    assert v1["solve"]["message"]["predicted_y_m"] == [0.0, 0.5]
    assert not v1["simulated"] and v1["origin"] is None
    one = client.get("/api/vessels/v1")
    assert one.status_code == 200 and one.json()["state"]["message"]["x_m"] == 4.0


def test_unknown_vessel_is_404_naming_those_seen(client: TestClient) -> None:
    r = client.get("/api/vessels/ghost")
    assert r.status_code == 404 and "ghost" in r.json()["detail"] and "v1" in r.json()["detail"]
    r = client.post("/api/vessels/ghost/arm", headers=AUTH)
    assert r.status_code == 404
    assert client.get("/api/vessels/bad%20name").status_code == 422


# -- authority and bounds -------------------------------------------------------------------------


def test_commands_need_the_operator_token(client: TestClient, vessel: Vessel) -> None:
    r = client.post("/api/vessels/v1/arm")
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert "Authorization: Bearer" in r.json()["detail"]
    r = client.post("/api/vessels/v1/arm", headers={"Authorization": "Bearer not-the-token"})
    assert r.status_code == 403 and r.json()["detail"] == "wrong operator token"
    r = client.post("/api/vessels/v1/arm", headers={"Authorization": f"Basic {TOKEN}"})
    assert r.status_code == 401
    assert "vehicle/arm" not in vessel.requests  # nothing reached the vessel


def test_oversize_bodies_are_413_declared_or_chunked(hub: MemoryHub, vessel: Vessel) -> None:
    with client_for(hub, max_body_bytes=1000) as c:
        big = json.dumps(mission(mission_id="x" * 10), indent=1) + " " * 2000
        json_auth = {**AUTH, "content-type": "application/json"}
        r = c.post("/api/vessels/v1/mission", content=big, headers=json_auth)
        assert r.status_code == 413 and "1000 bytes" in r.json()["detail"]

        def chunks() -> Iterator[bytes]:
            for _ in range(20):
                yield b" " * 100

        r = c.post("/api/vessels/v1/mission", content=chunks(), headers=json_auth)
        assert r.status_code == 413
        assert c.post("/api/vessels/v1/mission", json=mission(), headers=AUTH).status_code == 200
    assert len(vessel.requests["mission/set"]) == 1


def test_command_rate_limit_is_429_with_retry_after(hub: MemoryHub, vessel: Vessel) -> None:
    # About one request a week once the burst is spent: the third at once is refused.
    with client_for(hub, rate_limit_per_s=1e-6, rate_limit_burst=2) as c:
        assert [c.post("/api/vessels/v1/arm", headers=AUTH).status_code for _ in range(2)] == [200, 200]
        r = c.post("/api/vessels/v1/arm", headers=AUTH)
        assert r.status_code == 429 and int(r.headers["retry-after"]) >= 1
        assert c.get("/api/vessels").status_code == 200  # reading is not limited
    assert len(vessel.requests["vehicle/arm"]) == 2


# -- vehicle and mission commands -----------------------------------------------------------------


def test_arm_disarm_and_mode_become_their_bus_requests(client: TestClient, vessel: Vessel) -> None:
    r = client.post("/api/vessels/v1/arm", headers=AUTH)
    assert r.status_code == 200
    assert r.json() == {"vessel": "v1", "request": "vehicle/arm", "outcome": "accepted", "accepted": True,
                        "reason": "vehicle/arm done", "detail": {}}
    assert client.post("/api/vessels/v1/disarm", json={"force": True}, headers=AUTH).status_code == 200
    arm, disarm = vessel.requests["vehicle/arm"]
    assert (arm.arm, arm.force, disarm.arm, disarm.force) == (True, False, False, True)
    # nobody serves vehicle/mode here: no reply is a 504 that says so
    r = client.post("/api/vessels/v1/mode", json={"mode": "HOLD"}, headers=AUTH)
    assert r.status_code == 504 and r.json()["outcome"] == "no_reply" and "no reply" in r.json()["reason"]
    assert client.post("/api/vessels/v1/mode", json={"mode": "a b"}, headers=AUTH).status_code == 422


def test_refusal_is_409_with_the_reason(hub: MemoryHub) -> None:
    bus = hub.bus("v2")
    bus.declare_alive("controller")
    Vessel(bus).serve(keys.MISSION_SET, refuse="waypoint 2 at (9000.0, 0.0) m is outside the operating area")
    with client_for(hub) as c:
        r = c.post("/api/vessels/v2/mission", json=mission(), headers=AUTH)
    assert r.status_code == 409
    body = r.json()
    assert body["outcome"] == "refused" and not body["accepted"] and "operating area" in body["reason"]
    assert body["mission"]["coa_radius_m"] == 2.0


def test_mission_send_start_pause_resume_abort(client: TestClient, vessel: Vessel) -> None:
    assert client.post("/api/vessels/v1/mission/start", headers=AUTH).status_code == 404  # none sent yet
    r = client.post("/api/vessels/v1/mission", headers=AUTH,
                    json=mission(controller="nmpc", predict_disturbance=True, mission_id="box"))
    assert r.status_code == 200 and r.json()["mission"]["controller"] == "nmpc"
    sent = vessel.requests["mission/set"][0]
    assert [(w.x_m, w.y_m) for w in sent.waypoints] == [(0, 0), (20, 0), (20, 20)]
    assert sent.predict_disturbance and sent.task_power_w == 10.0
    for cmd in ("pause", "resume", "abort"):
        r = client.post(f"/api/vessels/v1/mission/{cmd}", headers=AUTH)
        assert r.status_code == 200 and r.json()["request"] == "mission/command"
    assert [c.command for c in vessel.requests["mission/command"]] == ["pause", "resume", "abort"]
    r = client.post("/api/vessels/v1/mission/start", headers=AUTH)
    assert r.status_code == 200 and len(vessel.requests["mission/set"]) == 2
    assert client.get("/api/vessels/v1").json()["last_mission"]["mission_id"] == "box"


@pytest.mark.parametrize("body, field_name", [
    ({"waypoints": SQUARE_M[:1], "coa_radius_m": 2, "task_power_w": 0.49}, "waypoints"),
    ({"waypoints": [{"x_m": 0, "y_m": 0, "lat_deg": 1, "lon_deg": 2}, {"x_m": 1, "y_m": 1}],
      "coa_radius_m": 2, "task_power_w": 0.49}, "waypoints"),
    ({"waypoints": [{"x_m": 0}, {"x_m": 1, "y_m": 1}], "coa_radius_m": 2, "task_power_w": 0.49}, "waypoints"),
    (mission(coa_radius_m=0), "coa_radius_m"),
    (mission(task_power_w=-1), "task_power_w"),
    (mission(controller="PID!"), "controller"),
    (mission(colour="red"), "colour"),
])
def test_bad_missions_are_422_naming_the_field(client: TestClient, vessel: Vessel, body: dict,
                                               field_name: str) -> None:
    r = client.post("/api/vessels/v1/mission", json=body, headers=AUTH)
    assert r.status_code == 422
    assert any(field_name in [str(p) for p in e["loc"]] for e in r.json()["detail"]), r.json()
    assert "mission/set" not in vessel.requests


# -- import and export ------------------------------------------------------------------------------


def test_import_real_plan_upload_refused_then_skipped(client: TestClient, vessel: Vessel) -> None:
    data = (DATA / "simple_square.plan").read_bytes()
    files = {"file": ("simple_square.plan", data, "application/octet-stream")}
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH, files=files,
                    data={"coa_radius_m": "3", "task_power_w": "10"})
    assert r.status_code == 422 and "items[0] (doJumpId 1): command 22 (NAV_TAKEOFF)" in r.json()["detail"]
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH, files=files,
                    data={"coa_radius_m": "3", "task_power_w": "10", "skip_unsupported": "true",
                          "controller": "eo-empc"})
    assert r.status_code == 200, r.text
    assert len(r.json()["skipped"]) == 1
    sent = vessel.requests["mission/set"][0]
    assert (sent.waypoints[0].lat_deg, sent.waypoints[0].lon_deg) == (47.398742, 8.546594)
    assert (sent.coa_radius_m, sent.controller, len(sent.waypoints)) == (3.0, "eo-empc", 4)


def test_an_imported_plans_own_area_is_said_not_to_be_sent(client: TestClient, vessel: Vessel) -> None:
    """The mission goes, the file's geoFence does not: the reply lists it with what was left out,
    so nobody takes the file's fence for the one the vessel keeps to."""
    from seaway_groundstation.routes.missions import AREA_NOT_SENT

    from tests.unit.groundstation.test_gs_plans import QGC_FENCE, QGC_RALLY

    plain = json.loads((DATA / "simple_square.plan").read_text())
    fenced = {**plain, "geoFence": QGC_FENCE, "rallyPoints": QGC_RALLY}
    body = {"coa_radius_m": 3.0, "task_power_w": 10.0, "skip_unsupported": True}
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH, json={"document": fenced, **body})
    assert r.status_code == 200, r.text
    assert AREA_NOT_SENT in r.json()["skipped"] and len(r.json()["skipped"]) == 2  # takeoff too
    assert len(vessel.requests["mission/set"]) == 1
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH, json={"document": plain, **body})
    assert r.status_code == 200 and AREA_NOT_SENT not in r.json()["skipped"]
    # Reading it for the page's editor says so too (the page shows what a mission leaves out).
    r = client.post("/api/missions/parse", json={"document": fenced, "skip_unsupported": True})
    assert r.status_code == 200 and r.json()["area"] and AREA_NOT_SENT in r.json()["skipped"]


def test_import_geojson_as_json_body_and_refusals(client: TestClient, vessel: Vessel) -> None:
    doc = json.loads((DATA / "rfc7946-example.geojson").read_text())
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                    json={"document": doc, "coa_radius_m": 2.0, "task_power_w": 0.49,
                          "skip_unsupported": True})
    assert r.status_code == 200 and r.json()["mission"]["waypoints"][0] == {
        "x_m": None, "y_m": None, "lat_deg": 0.0, "lon_deg": 102.0}
    # not a mission file, missing parameters, unknown parameters, not JSON, wrong content type
    bad = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                      json={"document": {"type": "Point", "coordinates": [1, 2]}, "coa_radius_m": 1,
                            "task_power_w": 0.49})
    assert bad.status_code == 422 and "\"Point\" is not supported" in bad.json()["detail"]
    no_radius = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                            json={"document": doc, "task_power_w": 0.49, "skip_unsupported": True})
    assert no_radius.status_code == 422 and "coa_radius_m is required" in no_radius.json()["detail"]
    extra = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                        files={"file": ("a.geojson", b"{}")}, data={"colour": "red"})
    assert extra.status_code == 422 and extra.json()["detail"][0]["loc"] == ["colour"]
    garbage = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                          files={"file": ("a.plan", b"not json")}, data={"coa_radius_m": "1"})
    assert garbage.status_code == 422 and "uploaded a.plan: not JSON" in garbage.json()["detail"]
    text = client.post("/api/vessels/v1/mission/import", headers={**AUTH, "content-type": "text/plain"},
                       content=b"hello")
    assert text.status_code == 415
    assert len(vessel.requests["mission/set"]) == 1


def test_parse_reads_a_file_without_sending(client: TestClient, vessel: Vessel) -> None:
    doc = json.loads((DATA / "PX4SITL-ArduRover.plan").read_text())
    r = client.post("/api/missions/parse", json={"document": doc, "skip_unsupported": True})
    assert r.status_code == 200 and r.json()["source"] == "plan" and len(r.json()["waypoints"]) == 5
    assert client.post("/api/missions/parse", json={"document": doc}).status_code == 422
    assert "mission/set" not in vessel.requests


def test_parse_returns_the_plans_operating_area(client: TestClient) -> None:
    doc = json.loads((DATA / "PX4SITL-ArduRover.plan").read_text())
    assert client.post("/api/missions/parse", json={"document": doc, "skip_unsupported": True}
                       ).json()["area"] is None  # its geoFence and rallyPoints are empty
    lat, lon = doc["mission"]["plannedHomePosition"][:2]
    d = 0.01
    ring = [[lat - d, lon - d], [lat - d, lon + d], [lat + d, lon + d], [lat + d, lon - d]]
    doc["geoFence"]["polygons"] = [{"inclusion": True, "version": 1, "polygon": ring}]
    doc["rallyPoints"]["points"] = [[lat, lon, 5.0]]
    area = client.post("/api/missions/parse", json={"document": doc, "skip_unsupported": True}).json()["area"]
    assert area["keep_in"]["vertices_deg"][0] == [lat - d, lon - d]
    assert area["rally"] == [{"name": "", "position_deg": [lat, lon]}]


def test_export_last_mission_as_plan_and_geojson(client: TestClient, vessel: Vessel) -> None:
    assert client.get("/api/vessels/v1/mission/export").status_code == 404  # nothing sent yet
    sent = client.post("/api/vessels/v1/mission", json=mission(mission_id="box"), headers=AUTH)
    assert sent.status_code == 200
    r = client.get("/api/vessels/v1/mission/export?format=geojson")
    assert r.status_code == 409 and "no NED origin" in r.json()["detail"]
    vessel.publish(keys.NAV_ORIGIN, NavOrigin(stamp_ns=1, lat_rad=math.radians(47.0),
                                              lon_rad=math.radians(8.0), alt_m=0.0))
    geo = client.get("/api/vessels/v1/mission/export?format=geojson")
    assert geo.status_code == 200 and geo.headers["content-type"].startswith("application/geo+json")
    assert 'filename="v1-box.geojson"' in geo.headers["content-disposition"]
    coords = geo.json()["geometry"]["coordinates"]
    assert coords[0] == pytest.approx([8.0, 47.0]) and coords[1][1] > 47.0
    assert geo.json()["properties"]["coa_radius_m"] == 2.0
    plan = client.get("/api/vessels/v1/mission/export")
    assert plan.status_code == 200 and plan.json()["fileType"] == "Plan"
    assert plan.json()["mission"]["items"][1]["params"][4] == pytest.approx(coords[1][1])
    # the exported file imports back to the same path
    r = client.post("/api/vessels/v1/mission/import", headers=AUTH,
                    files={"file": ("v1-box.plan", plan.content)}, data={"task_power_w": "10"})
    assert r.status_code == 200 and r.json()["mission"]["coa_radius_m"] == 2.0
    assert client.get("/api/vessels/v1/mission/export?format=kml").status_code == 422


@pytest.mark.parametrize("mission_id", ["\u2713 survey", "Nord \u2013 S\u00fcd", "a\r\nX-Injected: 1",
                                        '"quoted"; x=1', "box"])
def test_export_names_its_file_safely_whatever_the_mission_id(client: TestClient, vessel: Vessel,
                                                              mission_id: str) -> None:
    """The mission_id went into Content-Disposition as it was: a character outside latin-1 made
    the header unencodable (a 500) and a CR/LF made uvicorn drop the connection. Now filename= is
    ASCII-safe and filename*= (RFC 5987) carries the real name."""
    body = mission(mission_id=mission_id, waypoints=[{"lat_deg": 28.18, "lon_deg": 112.94},
                                                     {"lat_deg": 28.181, "lon_deg": 112.94}])
    draft = client.post("/api/missions/export", json=body)
    assert client.post("/api/vessels/v1/mission", json=body, headers=AUTH).status_code == 200
    sent = client.get("/api/vessels/v1/mission/export?format=geojson")
    for r, stem, ext in ((draft, "mission", "plan"), (sent, "v1", "geojson")):
        assert r.status_code == 200, r.text
        header = r.headers["content-disposition"]
        assert header.isascii() and "\r" not in header and "\n" not in header, header
        ascii_name = re.search(r'filename="([^"]*)"', header)
        assert ascii_name and re.fullmatch(r"[A-Za-z0-9_.-]+", ascii_name.group(1)), header
        assert ascii_name.group(1).startswith(stem + "-") and ascii_name.group(1).endswith("." + ext)
        real = re.search(r"filename\*=UTF-8''(\S+)", header)
        assert real and unquote(real.group(1)) == f"{stem}-{mission_id}.{ext}", header


def test_export_refuses_metres_no_vessel_reaches(client: TestClient, vessel: Vessel) -> None:
    """x_m = 1e9 m (25 times round the Earth) became an ordinary latitude and longitude in the
    exported file, with a 200. Metres beyond the area's bound (MAX_RANGE_M on each axis) are now a
    422 naming the waypoint, in every body that takes them."""
    from seaway.area.model import MAX_RANGE_M

    vessel.publish(keys.NAV_ORIGIN, NavOrigin(stamp_ns=1, lat_rad=math.radians(47.0),
                                              lon_rad=math.radians(8.0), alt_m=0.0))
    for far in ({"x_m": 1e9, "y_m": 0.0}, {"x_m": 0.0, "y_m": -3e7}, {"x_m": 1e308, "y_m": 0.0}):
        body = mission(waypoints=[{"x_m": 0.0, "y_m": 0.0}, far])
        for path in ("/api/missions/export?vessel=v1", "/api/missions/check?vessel=v1",
                     "/api/vessels/v1/mission"):
            r = client.post(path, json=body, headers=AUTH)
            assert r.status_code == 422, (path, far, r.text)
            assert any(e["loc"][:3] == ["body", "waypoints", 1] for e in r.json()["detail"]), r.text
        r = client.post("/api/vessels/v1/home", json={"home": far}, headers=AUTH)
        assert r.status_code == 422 and "home" in r.text
    assert "mission/set" not in vessel.requests
    edge = mission(waypoints=[{"x_m": 0.0, "y_m": 0.0}, {"x_m": MAX_RANGE_M, "y_m": -MAX_RANGE_M}])
    assert client.post("/api/missions/export?vessel=v1", json=edge).status_code == 200


def test_a_mission_known_otherwise_with_metres_too_far_does_not_export() -> None:
    """The last mission sent or the launcher's is exported too: its metres are checked there."""
    from seaway.contract.messages import Waypoint
    from seaway.vessel.frames import GeoOrigin
    from seaway_groundstation import bodies

    origin = GeoOrigin.from_degrees(47.0, 8.0, 0.0)
    near, far = Waypoint(x_m=10.0, y_m=0.0), Waypoint(x_m=0.0, y_m=1e9)
    assert len(bodies.mission_points_deg([near, near], origin)) == 2
    with pytest.raises(bodies.RangeError, match="waypoint 1: y_m"):
        bodies.mission_points_deg([near, far], origin)


def test_max_waypoints_bounds_missions_sent_checked_and_exported(hub: MemoryHub, vessel: Vessel) -> None:
    """The setting bounded imported files only: a body took up to mission_files.MAX_WAYPOINTS
    whatever it was set to. Now send, check and export refuse more, naming the bound."""
    wps = [{"x_m": float(i), "y_m": float(i % 2) * 5} for i in range(11)]
    with client_for(hub, max_waypoints=10) as c:
        vessel.publish(keys.NAV_ORIGIN, NavOrigin(stamp_ns=1, lat_rad=0.8, lon_rad=0.14, alt_m=0.0))
        for path in ("/api/vessels/v1/mission", "/api/missions/check", "/api/missions/export?vessel=v1"):
            r = c.post(path, json=mission(waypoints=wps), headers=AUTH)
            assert r.status_code == 422, (path, r.text)
            assert "10" in r.json()["detail"] and "max_waypoints" in r.json()["detail"], r.text
            assert c.post(path, json=mission(waypoints=wps[:10]), headers=AUTH).status_code == 200, path
    assert [len(m.waypoints) for m in vessel.requests["mission/set"]] == [10]


# -- simulation -------------------------------------------------------------------------------------


def test_scenario_only_for_simulated_vessels(client: TestClient, hub: MemoryHub, vessel: Vessel) -> None:
    r = client.post("/api/vessels/v1/scenario", json={"restart": True}, headers=AUTH)
    assert r.status_code == 409 and "not simulated" in r.json()["reason"]
    vessel.bus.declare_alive("sim")
    vessel.serve(keys.SIM_SCENARIO)
    assert client.get("/api/vessels/v1").json()["simulated"]
    assert client.post("/api/vessels/v1/scenario", json={"name": "lake"}, headers=AUTH).status_code == 200
    assert client.post("/api/vessels/v1/scenario", json={"restart": True}, headers=AUTH).status_code == 200
    loaded, restarted = vessel.requests["sim/scenario"]
    assert loaded.scenario["name"] == "lake" and restarted.scenario is None
    assert client.post("/api/vessels/v1/scenario", json={"name": "no-such"}, headers=AUTH).status_code == 404
    assert client.post("/api/vessels/v1/scenario", json={"name": "../etc"}, headers=AUTH).status_code == 422
    assert client.post("/api/vessels/v1/scenario", json={}, headers=AUTH).status_code == 422


# -- the stream and the schema -----------------------------------------------------------------------


def test_stream_sends_the_latest_and_never_a_backlog(client: TestClient, vessel: Vessel) -> None:
    vessel.publish(keys.NAV_STATE, state(0.0))
    with client.websocket_connect("/api/stream?vessel=v1") as ws:
        first = ws.receive_json()
        assert first["vessel"] == "v1" and first["updates"]["state"]["message"]["x_m"] == 0.0
        n = 200
        for k in range(1, n + 1):  # far faster than 20 Hz: the client gets the latest, not 200
            vessel.publish(keys.NAV_STATE, state(float(k)))
        frames = 0
        while True:
            frame = ws.receive_json()
            frames += 1
            if frame["updates"].get("state", {}).get("message", {}).get("x_m") == float(n):
                break
        assert frames < n


def test_stream_refuses_a_bad_vessel_name_saying_why(client: TestClient) -> None:
    """Closed before the handshake, the client got a bare HTTP 403 (as if it lacked authority);
    now it is accepted, then closed with 1008 and the reason."""
    from starlette.websockets import WebSocketDisconnect

    with client.websocket_connect("/api/stream?vessel=a/b") as ws, \
            pytest.raises(WebSocketDisconnect) as closed:
        ws.receive_json()
    assert closed.value.code == 1008 and "a/b" in closed.value.reason
    with client.websocket_connect("/api/stream?vessel=" + "\u00e9" * 100) as ws, \
            pytest.raises(WebSocketDisconnect) as closed:
        ws.receive_json()
    assert closed.value.code == 1008 and len(closed.value.reason.encode()) <= 123


def test_a_stream_client_past_the_bound_is_told_to_come_back_later(hub: MemoryHub,
                                                                  vessel: Vessel) -> None:
    from starlette.websockets import WebSocketDisconnect

    vessel.publish(keys.NAV_STATE, state(0.0))
    with client_for(hub, max_stream_clients=1) as c, c.websocket_connect("/api/stream") as first:
        assert first.receive_json()["vessel"] == "v1"
        with c.websocket_connect("/api/stream") as second, \
                pytest.raises(WebSocketDisconnect) as closed:
            second.receive_json()
        assert closed.value.code == 1013 and "too many stream clients" in closed.value.reason


def test_openapi_documents_every_endpoint_with_tags_and_refusals(client: TestClient) -> None:
    schema = client.get("/openapi.json").json()
    assert {t["name"] for t in schema["tags"]} == {"fleet", "mission", "vehicle", "sim", "replay", "page"}
    commands = [(p, op) for p, ops in schema["paths"].items() for m, op in ops.items()
                if m == "post" and p.startswith("/api/vessels/")]
    assert len(commands) == 11
    for path, op in commands:
        assert op["tags"] and op["summary"], path
        assert {"401", "403", "404", "409", "429", "504"} <= set(op["responses"]), path
        assert op.get("security"), path
    imp = schema["paths"]["/api/vessels/{vessel}/mission/import"]["post"]["requestBody"]["content"]
    assert {"multipart/form-data", "application/json"} <= set(imp)
    assert "VesselView" in schema["components"]["schemas"]


def test_a_state_stamped_far_ahead_of_the_wall_clock_is_dropped_not_shown(client: TestClient,
                                                                          vessel: Vessel) -> None:
    """Valid but absurd: an insider's state stamped 10^9 s ahead posed as the newest for good (shown
    fresh, 10^6 m/s) and stretched the mission's metrics to its stamp (10^10 grid samples: all the
    machine's memory). It is dropped, counted and logged; the vessel's real states go on."""
    import time

    vessel.publish(keys.NAV_STATE, state(1.0))
    absurd = StateEstimate(stamp_ns=time.time_ns() + 10**18, u_mps=1e6, v_mps=0.0, r_radps=0.0,
                           x_m=1e12, y_m=2.0, psi_rad=0.1)
    vessel.publish(keys.NAV_STATE, absurd)
    (v1,) = client.get("/api/vessels").json()["vessels"]
    assert v1["state"]["message"]["x_m"] == 1.0
    vessel.publish(keys.NAV_STATE, state(3.0))  # the next real one is taken
    (v1,) = client.get("/api/vessels").json()["vessels"]
    assert v1["state"]["message"]["x_m"] == 3.0
    gate = client.app.state.groundstation.link.stamps  # type: ignore[attr-defined]
    assert gate.dropped == {(keys.NAV_STATE.key("v1"), "ahead"): 1}


@pytest.mark.parametrize(("path", "body"), [
    ("/api/vessels/v1/mode", "NaN"),
    ("/api/vessels/v1/mode", '{"mode": NaN}'),
    ("/api/vessels/v1/arm", '{"arm": true, "force": Infinity}'),
    ("/api/vessels/v1/mission", '{"waypoints": [{"x_m": NaN, "y_m": 0}, {"x_m": 1e400, "y_m": 0}], '
                                '"coa_radius_m": 2.0}'),
    ("/api/vessels/v1/mission", '{"waypoints": [{"x_m": 0, "y_m": 0}, {"x_m": 20, "y_m": 0}], '
                                '"coa_radius_m": -Infinity}'),
])
def test_nan_infinity_and_overflowing_numbers_in_a_body_are_a_422_naming_the_field(
        client: TestClient, vessel: Vessel, path: str, body: str) -> None:
    """Python's JSON reads NaN, Infinity and 1e400 as floats; the default 422 echoed them and could
    not encode its own answer: a bare 500 and a traceback. Now a 422 naming each field."""
    r = client.post(path, content=body, headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert detail and all(e["loc"] and e["msg"] for e in detail), detail
    assert any(str(e.get("input")) in ("nan", "inf", "-inf") for e in detail), detail
    assert vessel.requests.get(keys.VEHICLE_ARM.suffix) is None  # nothing reached the vessel


@pytest.mark.parametrize("content_type", ["application/octet-stream", "text/plain", None,
                                          "application/json"])
def test_a_binary_body_is_a_422_saying_what_to_send(client: TestClient, vessel: Vessel,
                                                    content_type: str | None) -> None:
    """Bytes that are not UTF-8: FastAPI's 422 echoed them and could not encode its own answer (a
    500 and a traceback), or, sent as JSON, a bare 400. Now a 422 on the body, echoing no bytes."""
    binary = bytes(range(256)) * 4
    headers = {**AUTH, **({"Content-Type": content_type} if content_type else {})}
    for path in ("/api/vessels/v1/mode", "/api/vessels/v1/mission", "/api/vessels/v1/arm"):
        r = client.post(path, content=binary, headers=headers)
        assert r.status_code == 422, (path, r.status_code, r.text)
        (error,) = r.json()["detail"]
        assert error["loc"] == ["body"] and error["type"] in ("body_not_json", "body_not_utf8")
        assert str(len(binary)) in error["msg"] and "UTF-8" in error["msg"]
        assert len(r.content) < 1024
    assert not vessel.requests.get(keys.VEHICLE_ARM.suffix)  # nothing reached the vessel


@pytest.mark.parametrize(("path", "body"), [
    ("/api/vessels/v1/mode", {"mode": "x" * 65536}),
    ("/api/vessels/v1/mission", {"waypoints": [{"x_m": 1.0}] * 3000, "coa_radius_m": 2.0,
                                 "task_power_w": 10.0}),
    ("/api/vessels/v1/mission", {"waypoints": [{"x_m": "far"} for _ in range(2000)],
                                 "coa_radius_m": 2.0, "task_power_w": 10.0, "note": "y" * 60000}),
])
def test_a_large_invalid_body_is_not_echoed_back(client: TestClient, vessel: Vessel, path: str,
                                                  body: dict[str, Any]) -> None:
    """A 64 KiB body's 422 gave the whole input back: now each field's input is cut to a short
    prefix and the errors listed are bounded."""
    raw = json.dumps(body)
    assert len(raw) > 30_000
    r = client.post(path, content=raw, headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422, r.text[:200]
    detail = r.json()["detail"]
    assert detail and all(e["loc"] and e["msg"] for e in detail)
    assert len(r.content) < 8 * 1024, len(r.content)
    assert all(len(json.dumps(e.get("input"))) < 100 for e in detail), detail
    assert "mission/set" not in vessel.requests


@pytest.mark.parametrize(("document", "field"), [
    ('{"name": "x", "vessel": {"mass_kg": NaN}}', "scenario.vessel.mass_kg"),
    ('{"current": {"speed_mps": [0.1, Infinity]}}', "scenario.current.speed_mps[1]"),
    ('{"mission": {"coa_radius_m": -1e400}}', "scenario.mission.coa_radius_m"),
])
def test_nan_or_infinity_inside_a_scenario_document_is_a_422_naming_the_field(
        client: TestClient, vessel: Vessel, document: str, field: str) -> None:
    """A scenario document is free-form: the body's finite-number rule did not reach inside it and
    the message refused it while being made (a 500). Now a 422 naming the field's path."""
    vessel.bus.declare_alive("sim")
    vessel.serve(keys.SIM_SCENARIO)
    r = client.post("/api/vessels/v1/scenario", content='{"scenario": ' + document + "}",
                    headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    (error,) = r.json()["detail"]
    assert error["loc"] == ["body", "scenario"] and field in error["msg"]
    assert keys.SIM_SCENARIO.suffix not in vessel.requests
    ok = client.post("/api/vessels/v1/scenario", json={"scenario": {"name": "x"}}, headers=AUTH)
    assert ok.status_code == 200  # the ground station goes on


@pytest.mark.parametrize("depth", [80, 300, 700])
def test_a_scenario_document_nested_too_deep_is_a_422_naming_the_limit(
        client: TestClient, vessel: Vessel, depth: int) -> None:
    """300 deep: the bus message could not be encoded (a 500); 700 deep: the finite-number check
    recursed past Python's limit (a 500). Now a 422 naming where and the limit."""
    from seaway_groundstation.bodies import MAX_DOCUMENT_DEPTH

    vessel.bus.declare_alive("sim")
    vessel.serve(keys.SIM_SCENARIO)
    body = '{"scenario": {"a": ' + "[" * depth + "]" * depth + "}}"
    r = client.post("/api/vessels/v1/scenario", content=body,
                    headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422, r.text[:300]
    (error,) = r.json()["detail"]
    assert error["loc"] == ["body", "scenario"] and str(MAX_DOCUMENT_DEPTH) in error["msg"]
    assert "scenario.a" in error["msg"] and len(r.content) < 4096
    assert keys.SIM_SCENARIO.suffix not in vessel.requests
    nested = '{"scenario": {"a": ' + "[" * 20 + "1" + "]" * 20 + "}}"  # deep, but a document's depth
    ok = client.post("/api/vessels/v1/scenario", content=nested,
                     headers={**AUTH, "Content-Type": "application/json"})
    assert ok.status_code == 200, ok.text


def test_a_mission_document_nested_too_deep_is_a_422(client: TestClient) -> None:
    doc = '{"document": {"type": "LineString", "coordinates": ' + "[" * 300 + "]" * 300 + "}}"
    r = client.post("/api/missions/parse", content=doc, headers={"Content-Type": "application/json"})
    assert r.status_code == 422 and "document.coordinates" in r.text, r.text[:300]


def test_the_document_checks_walk_without_recursion() -> None:
    """Deeper than Python's recursion limit and with integers beyond a float's range: measured
    and checked, not a RecursionError or an OverflowError."""
    from seaway_groundstation.bodies import non_finite_fields, too_deep

    doc: Any = [10**400, math.inf]
    for _ in range(5000):
        doc = [doc]
    assert too_deep({"a": doc}, "d") is not None
    assert too_deep({"a": [[1]], "b": {"c": 10**400}}, "d") is None
    assert non_finite_fields({"a": doc}, "d") == ["d.a" + "[0]" * 5000 + "[1] (inf)"]
    assert non_finite_fields({"a": [10**400, 1.5], "b": {"c": math.nan}}, "d") == ["d.b.c (nan)"]


def test_a_request_the_bus_cannot_encode_is_a_422_not_a_500(client: TestClient, vessel: Vessel,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Past the body's checks (here: the depth check lifted), a request whose encoding fails
    (PydanticSerializationError) was a 500 and a traceback; now a 422 saying it cannot be sent,
    and nothing reaches the vessel."""
    from seaway_groundstation import bodies

    monkeypatch.setattr(bodies, "too_deep", lambda *_a, **_k: None)
    vessel.bus.declare_alive("sim")
    vessel.serve(keys.SIM_SCENARIO)
    body = '{"scenario": {"a": ' + "[" * 300 + "]" * 300 + "}}"
    r = client.post("/api/vessels/v1/scenario", content=body,
                    headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422, r.text[:300]
    assert "sim/scenario" in r.json()["detail"] and "encode" in r.json()["detail"]
    assert keys.SIM_SCENARIO.suffix not in vessel.requests


def test_requests_without_the_token_do_not_use_up_the_operators_rate(hub: MemoryHub,
                                                                      vessel: Vessel) -> None:
    """One bucket per client address, counted before the token check: 5 of 10 operator commands
    were 429 after 10 requests without the token. Now those have their own bucket (401/403, then
    429), and the operator's commands all pass."""
    with client_for(hub, rate_limit_per_s=1e-6, rate_limit_burst=5) as c:  # no refill here
        anonymous = [c.post("/api/vessels/v1/arm").status_code for _ in range(6)]
        guessing = [c.post("/api/vessels/v1/arm", headers={"Authorization": "Bearer guess-0123456789"})
                    .status_code for _ in range(4)]
        assert anonymous == [401] * 5 + [429]  # their own bucket: limited too
        assert guessing == [429] * 4  # a wrong token is the same address without the token
        assert [c.post("/api/vessels/v1/arm", headers=AUTH).status_code for _ in range(5)] == [200] * 5
        r = c.post("/api/vessels/v1/arm", headers=AUTH)  # the operator's own bucket is bounded too
        assert r.status_code == 429 and "operator" in r.json()["detail"]
        assert c.post("/api/vessels/v1/arm").status_code == 429
    assert len(vessel.requests["vehicle/arm"]) == 5


def test_every_stream_client_hears_each_command_relayed_with_its_sender(client: TestClient,
                                                                       vessel: Vessel) -> None:
    vessel.publish(keys.NAV_STATE, state(0.0))
    with client.websocket_connect("/api/stream?vessel=v1") as ws:
        assert "command" not in ws.receive_json()["updates"]
        r = client.post("/api/vessels/v1/mission/pause", headers={**AUTH, "X-Seaway-Client": "tab-1"})
        assert r.status_code == 200
        while "command" not in (frame := ws.receive_json())["updates"]:
            pass
        note = frame["updates"]["command"]["message"]
        assert (note["request"], note["what"], note["outcome"], note["client"]) == (
            "mission/command", "pause", "accepted", "tab-1")
        # Refused requests are news too; a client without the header is "".
        r = client.post("/api/vessels/v1/arm", json={"force": True}, headers=AUTH)
        while (frame := ws.receive_json())["updates"].get("command", {}).get("message", {}).get(
                "request") != "vehicle/arm":
            pass
        assert frame["updates"]["command"]["message"]["what"] == "arm (forced)"
        assert frame["updates"]["command"]["message"]["client"] == ""


def test_a_bad_client_header_is_refused_naming_it(client: TestClient, vessel: Vessel) -> None:
    r = client.post("/api/vessels/v1/mission/pause", headers={**AUTH, "X-Seaway-Client": "a b/c"})
    assert r.status_code == 422 and "X-Seaway-Client" in r.json()["detail"], r.text
    assert "mission/command" not in vessel.requests


def test_set_home_here_or_at_a_point_becomes_the_bus_request(client: TestClient,
                                                              vessel: Vessel) -> None:
    vessel.serve(keys.MISSION_HOME)
    assert client.post("/api/vessels/v1/home", json={"home": "here"}, headers=AUTH).status_code == 200
    r = client.post("/api/vessels/v1/home", json={"home": {"lat_deg": 28.18, "lon_deg": 112.94}},
                    headers=AUTH)
    assert r.status_code == 200 and r.json()["request"] == "mission/home", r.text
    here, point = vessel.requests["mission/home"]
    assert here.home == "here" and (point.home.lat_deg, point.home.lon_deg) == (28.18, 112.94)
    # Refused at the edge, naming the field: no position, half a pair, a word, NaN text.
    for bad in ({"home": {}}, {"home": {"x_m": 1.0}}, {"home": "there"}, {}):
        r = client.post("/api/vessels/v1/home", json=bad, headers=AUTH)
        assert r.status_code == 422 and "home" in r.text, (bad, r.text)
    r = client.post("/api/vessels/v1/home", content=b'{"home": {"x_m": NaN, "y_m": 0}}',
                    headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 422
    assert len(vessel.requests["mission/home"]) == 2
