"""The Foxglove derivation (pure: decoded bus messages in, foxglove-sdk messages out), read back with
Google's protobuf library against the schemas foxglove-sdk ships."""

from __future__ import annotations

import json
import math

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, NavOrigin, SolveRecord, StateEstimate, Waypoint
from seaway.vessel.frames import GeoOrigin
from seaway_recorder.derive import FoxgloveDeriver, channel_spec, log_message

from tests.unit.recorder.foxglove_check import SDK_SCHEMAS, decode_strict, t_ns

V = "v1"
ORIGIN = GeoOrigin.from_degrees(47.0, 8.0, 400.0)
EPOCH_NS = 1_780_000_000_000_000_000


def decode(d):
    spec = channel_spec(d)
    assert spec.schema_data == bytes(SDK_SCHEMAS[spec.schema_name].data)
    assert (spec.schema_encoding, spec.message_encoding) == ("protobuf", "protobuf")
    return spec.schema_name, decode_strict(spec.schema_name, spec.schema_data, d.payload())


def state(stamp_ns: int, x: float, y: float, psi: float, cov: list[float] | None = None) -> StateEstimate:
    return StateEstimate.make(stamp_ns=stamp_ns, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x, y_m=y,
                              psi_rad=psi, covariance=cov)


def rotate(q, v):
    """Rotate v by the unit quaternion q = (x, y, z, w) (written out, not taken from the code)."""
    x, y, z, w = q
    vx, vy, vz = v
    # v' = v + 2 w (q x v) + 2 q x (q x v)
    cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    ccx, ccy, ccz = y * cz - z * cy, z * cx - x * cz, x * cy - y * cx
    return (vx + 2 * w * cx + 2 * ccx, vy + 2 * w * cy + 2 * ccy, vz + 2 * w * cz + 2 * ccz)


def test_nav_state_gives_position_with_its_covariance_frames_and_hull() -> None:
    d = FoxgloveDeriver(ORIGIN, timestamp_ns=lambda s: EPOCH_NS + s)
    cov = [0.0] * 81
    cov[3 * 9 + 3], cov[4 * 9 + 4], cov[3 * 9 + 4], cov[4 * 9 + 3] = 4.0, 9.0, 1.5, 1.5  # x N, y E
    out = {x.topic: decode(x) for x in d.feed(keys.NAV_STATE.key(V), state(2_500_000_000, 3.0, 4.0,
                                                                            math.pi / 2, cov))}
    assert set(out) == {f"foxglove/{V}/nav-state", f"foxglove/{V}/tf/ned", f"foxglove/{V}/tf/body",
                        f"foxglove/{V}/scene/vessel"}
    name, fix = out[f"foxglove/{V}/nav-state"]
    assert name == "foxglove.LocationFix"
    lat, lon, _ = ORIGIN.to_geodetic(3.0, 4.0, 0.0)
    assert (fix.latitude, fix.longitude) == pytest.approx((math.degrees(lat), math.degrees(lon)))
    # East-north-up, row-major: var(E) = var(y) = 9, var(N) = var(x) = 4, cov(E, N) = 1.5.
    assert list(fix.position_covariance) == [9.0, 1.5, 0.0, 1.5, 4.0, 0.0, 0.0, 0.0, 0.0]
    assert fix.position_covariance_type == 3  # KNOWN
    assert t_ns(fix.timestamp) == EPOCH_NS + 2_500_000_000
    assert fix.heading == pytest.approx(math.pi / 2)

    # map (east-north-up) -> <v>/ned: NED's north is the map's +y, east +x, down -z.
    _, static = out[f"foxglove/{V}/tf/ned"]
    assert (static.parent_frame_id, static.child_frame_id) == ("map", f"{V}/ned")
    q = (static.rotation.x, static.rotation.y, static.rotation.z, static.rotation.w)
    for ned, enu in (((1, 0, 0), (0, 1, 0)), ((0, 1, 0), (1, 0, 0)), ((0, 0, 1), (0, 0, -1))):
        assert rotate(q, ned) == pytest.approx(enu, abs=1e-12)
    # <v>/ned -> <v>/body: at (3, 4), heading east: the body's forward axis points east.
    _, body = out[f"foxglove/{V}/tf/body"]
    assert (body.parent_frame_id, body.child_frame_id) == (f"{V}/ned", f"{V}/body")
    assert (body.translation.x, body.translation.y, body.translation.z) == (3.0, 4.0, 0.0)
    qb = (body.rotation.x, body.rotation.y, body.rotation.z, body.rotation.w)
    assert rotate(qb, (1, 0, 0)) == pytest.approx((0, 1, 0), abs=1e-12)
    _, hull = out[f"foxglove/{V}/scene/vessel"]
    (entity,) = hull.entities
    assert entity.frame_id == f"{V}/body" and entity.frame_locked and len(entity.cubes) == 1

    # Later states: the position and the moving frame only (the static frame and hull once).
    later = {x.topic for x in d.feed(keys.NAV_STATE.key(V), state(2_600_000_000, 3.1, 4.0, 0.0))}
    assert later == {f"foxglove/{V}/nav-state", f"foxglove/{V}/tf/body"}
    # No covariance: LocationFix says UNKNOWN, not a made-up zero.
    _, fix2 = decode(next(x for x in d.feed(keys.NAV_STATE.key(V), state(2_700_000_000, 3.2, 4.0, 0.0))
                          if x.topic.endswith("nav-state")))
    assert fix2.position_covariance_type == 0


def test_positions_need_an_origin_the_bus_origin_wins() -> None:
    d = FoxgloveDeriver(None)
    assert not [x for x in d.feed(keys.NAV_STATE.key(V), state(1, 1.0, 0.0, 0.0))
                if x.topic.endswith("nav-state")]
    d.feed(keys.NAV_ORIGIN.key(V), NavOrigin.make(stamp_ns=1, lat_rad=ORIGIN.lat_rad,
                                                  lon_rad=ORIGIN.lon_rad, alt_m=0.0))
    (fix,) = [decode(x)[1] for x in d.feed(keys.NAV_STATE.key(V), state(2, 1.0, 0.0, 0.0))
              if x.topic.endswith("nav-state")]
    lat, _, _ = ORIGIN.to_geodetic(1.0, 0.0, 0.0)
    assert fix.latitude == pytest.approx(math.degrees(lat))


def accepted(accepted_ns: int, stamp_ns: int, pts: list[tuple[float, float]], r: float = 2.0):
    return MissionAccepted.make(stamp_ns=stamp_ns, accepted_ns=accepted_ns, mission_id="m1",
                                waypoints=[Waypoint(x_m=x, y_m=y) for x, y in pts], coa_radius_m=r,
                                task_power_w=1.0, controller="cc-empc", predict_disturbance=False)


def test_accepted_mission_gives_geojson_and_a_scene_once_per_acceptance() -> None:
    d = FoxgloveDeriver(ORIGIN)
    pts = [(0.0, 0.0), (20.0, 0.0), (20.0, 10.0)]
    out = {x.topic: decode(x) for x in d.feed(keys.MISSION_ACCEPTED.key(V), accepted(5, 5, pts))}
    assert set(out) == {f"foxglove/{V}/mission", f"foxglove/{V}/scene/mission"}
    name, gj = out[f"foxglove/{V}/mission"]
    assert name == "foxglove.GeoJSON"
    doc = json.loads(gj.geojson)
    path, *circles = doc["features"]
    assert path["geometry"]["type"] == "LineString"
    for (lon, lat), (x, y) in zip(path["geometry"]["coordinates"], pts, strict=True):
        n, e, _ = ORIGIN.to_ned(math.radians(lat), math.radians(lon), ORIGIN.alt_m)
        assert (n, e) == pytest.approx((x, y), abs=1e-6)
    assert len(circles) == len(pts)
    for c, (x, y) in zip(circles, pts, strict=True):
        ring = c["geometry"]["coordinates"][0]
        assert ring[0] == ring[-1]  # a closed GeoJSON ring
        for lon, lat in ring:
            n, e, _ = ORIGIN.to_ned(math.radians(lat), math.radians(lon), ORIGIN.alt_m)
            assert math.hypot(n - x, e - y) == pytest.approx(2.0, abs=1e-6)
    _, scene = out[f"foxglove/{V}/scene/mission"]
    (entity,) = scene.entities
    assert entity.frame_id == f"{V}/ned"
    strip, *loops = entity.lines
    assert [(p.x, p.y) for p in strip.points] == pts
    assert len(loops) == len(pts)
    # The controller republishes it once a second: drawn once; a new acceptance is drawn again.
    assert d.feed(keys.MISSION_ACCEPTED.key(V), accepted(5, 1_000_000_005, pts)) == []
    assert len(d.feed(keys.MISSION_ACCEPTED.key(V), accepted(9, 9, pts[:2]))) == 2


def test_mission_before_any_origin_is_drawn_when_the_origin_comes() -> None:
    d = FoxgloveDeriver(None)
    assert d.feed(keys.MISSION_ACCEPTED.key(V), accepted(5, 5, [(0.0, 0.0), (9.0, 0.0)])) == []
    out = d.feed(keys.NAV_ORIGIN.key(V), NavOrigin.make(stamp_ns=6, lat_rad=ORIGIN.lat_rad,
                                                        lon_rad=ORIGIN.lon_rad, alt_m=0.0))
    assert {x.topic for x in out} == {f"foxglove/{V}/mission", f"foxglove/{V}/scene/mission"}


def solve(stamp_ns: int, xs: list[float], ys: list[float]) -> SolveRecord:
    return SolveRecord.make(stamp_ns=stamp_ns, controller="cc-empc", status="ok", success=True,
                            iterations=3, solve_time_s=0.001, predicted_x_m=xs, predicted_y_m=ys)


def test_prediction_is_drawn_and_removed_when_a_step_has_none() -> None:
    d = FoxgloveDeriver(None, timestamp_ns=lambda s: EPOCH_NS + s)
    (x,) = d.feed(keys.SOLVE.key(V), solve(100, [0.0, 1.0, 2.0], [0.0, 0.5, 1.5]))
    name, upd = decode(x)
    assert x.topic == f"foxglove/{V}/scene/prediction" and name == "foxglove.SceneUpdate"
    (entity,) = upd.entities
    assert entity.id == "prediction" and entity.frame_id == f"{V}/ned"
    assert [(p.x, p.y) for p in entity.lines[0].points] == [(0.0, 0.0), (1.0, 0.5), (2.0, 1.5)]
    assert t_ns(entity.timestamp) == EPOCH_NS + 100
    (x,) = d.feed(keys.SOLVE.key(V), solve(200, [], []))
    _, upd = decode(x)
    assert not upd.entities and [e.id for e in upd.deletions] == ["prediction"]


def test_log_message_levels() -> None:
    for level, want in (("DEBUG", 1), ("INFO", 2), ("WARNING", 3), ("ERROR", 4), ("CRITICAL", 5),
                        ("", 0)):
        name, msg = decode(log_message(7_000_000_001, level, "controller", "", "text"))
        assert name == "foxglove.Log"
        assert (msg.level, msg.name, msg.message, t_ns(msg.timestamp)) == (want, "controller", "text",
                                                                          7_000_000_001)
    _, msg = decode(log_message(1, "INFO", "sim", "seaway_sim.core", "stepped"))
    assert msg.message == "seaway_sim.core: stepped"  # the logger's name leads, as in the text log
