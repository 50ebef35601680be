"""The simulated PX4's geofence (``px4_geofence`` and its hooks in ``px4_autopilot``): the mission
protocol for fence and rally items as PX4 answers it, zones that PX4 discards, and a breach
answered by GF_ACTION with PX4's text. Time passed in; real packed MAVLink messages."""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as ml
from seaway.contract.messages import GnssFix
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config
from seaway_sim.px4_wire import HOLD, MANUAL, RTL, custom_mode

from tests.unit.sim.test_sim_px4_autopilot import (
    HOME,
    MS,
    S,
    _texts,
    armed_driving,
    manual,
    rx,
    set_mode,
)

FENCE, RALLY = ml.MAV_MISSION_TYPE_FENCE, ml.MAV_MISSION_TYPE_RALLY


def at(north_m: float, east_m: float) -> tuple[int, int]:
    lat, lon, _ = HOME.to_geodetic(north_m, east_m)
    return round(math.degrees(lat) * 1e7), round(math.degrees(lon) * 1e7)


def fix(north_m: float, east_m: float = 0.0) -> GnssFix:
    lat, lon, _ = HOME.to_geodetic(north_m, east_m)
    return GnssFix(stamp_ns=0, lat_rad=lat, lon_rad=lon, alt_m=0.0, fix_type=3)


def square(half_m: float) -> list[tuple[int, float, tuple[int, int]]]:
    corners = [(half_m, -half_m), (half_m, half_m), (-half_m, half_m), (-half_m, -half_m)]
    return [(ml.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4.0, at(*c)) for c in corners]


def driving(ap: Px4Autopilot, now_ns: int) -> tuple[float, float]:
    """The thrust at ``now_ns`` with the MANUAL_CONTROL stream kept up (full ahead)."""
    ap.handle(manual(200, 900), now_ns - 100 * MS)
    return ap.thrust_n(now_ns)


def upload(ap: Px4Autopilot, items, mtype: int = FENCE, now_ns: int = 0) -> int:
    """The whole upload as a ground station makes it; the final MISSION_ACK's result."""
    out = ap.handle(rx(ml.MAVLink_mission_count_message(1, 1, len(items), mtype)), now_ns)
    while True:
        (reply,) = out
        if reply.get_type() == "MISSION_ACK":
            return reply.type
        assert reply.get_type() == "MISSION_REQUEST_INT" and reply.mission_type == mtype
        command, p1, (x, y) = items[reply.seq]
        out = ap.handle(rx(ml.MAVLink_mission_item_int_message(
            1, 1, reply.seq, ml.MAV_FRAME_GLOBAL, command, 0, 1, p1, 0, 0, 0, x, y, 0, mtype)),
            now_ns)


def download(ap: Px4Autopilot, mtype: int) -> list:
    (count,) = ap.handle(rx(ml.MAVLink_mission_request_list_message(1, 1, mtype)), 0)
    return [ap.handle(rx(ml.MAVLink_mission_request_int_message(1, 1, k, mtype)), 0)[0]
            for k in range(count.count)]


def test_fence_and_rally_upload_and_download_as_px4():
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    items = [*square(20.0), (ml.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 3.0, at(5, 5))]
    assert upload(ap, items) == ml.MAV_MISSION_ACCEPTED
    rally = [(ml.MAV_CMD_NAV_RALLY_POINT, 0.0, at(-5, 0))]
    assert upload(ap, rally, RALLY) == ml.MAV_MISSION_ACCEPTED
    held = download(ap, FENCE)
    assert [(m.command, m.param1, m.x, m.y) for m in held] == [(c, p, *xy) for c, p, xy in items]
    assert [(m.command, m.x, m.y) for m in download(ap, RALLY)] == [(c, *xy) for c, _, xy in rally]
    assert upload(ap, [], RALLY) == ml.MAV_MISSION_ACCEPTED and download(ap, RALLY) == []


def test_too_many_items_too_few_vertices_and_the_mission_type_are_refused():
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    big = [(ml.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 65.0, at(k, 0)) for k in range(65)]
    assert upload(ap, big) == ml.MAV_MISSION_NO_SPACE
    thin = [(ml.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 2.0, at(k, 0)) for k in range(2)]
    assert upload(ap, thin) == ml.MAV_MISSION_INVALID_PARAM1
    assert (ml.MAV_SEVERITY_CRITICAL, "Fence: too few vertices") in _texts(ap, S)
    (ack,) = ap.handle(rx(ml.MAVLink_mission_count_message(1, 1, 3, 0)), 0)
    assert ack.type == ml.MAV_MISSION_UNSUPPORTED


def test_leaving_the_fence_armed_takes_gf_action_hold_with_pxs_text_until_a_mode_change():
    ap = armed_driving()
    ap.sensor_telemetry([fix(0.0)], [], epoch_ns=0)
    assert upload(ap, square(10.0), now_ns=1 * S) == ml.MAV_MISSION_ACCEPTED
    assert driving(ap, 2 * S) != (0.0, 0.0)  # inside: driving
    ap.sensor_telemetry([fix(12.0)], [], epoch_ns=0)  # out of the keep-in square
    assert driving(ap, 3 * S) == (0.0, 0.0)
    assert ap.heartbeat().custom_mode == custom_mode(HOLD)
    texts = _texts(ap, 3 * S)
    # PX4's 51-character text in STATUSTEXT's 50 (PX4 itself chunks; the imitation truncates)
    assert (ml.MAV_SEVERITY_CRITICAL, "Geofence violation: approaching or outside geofenc") in texts
    ap.sensor_telemetry([fix(13.0)], [], epoch_ns=0)
    assert driving(ap, 4 * S) == (0.0, 0.0)
    assert _texts(ap, 4 * S) == []  # said once per breach
    assert set_mode(ap, 5 * S, 1) == ml.MAV_RESULT_ACCEPTED  # the operator takes it back
    assert ap.heartbeat().custom_mode == custom_mode(MANUAL)
    assert driving(ap, 5 * S + 100 * MS) != (0.0, 0.0)


def test_gf_action_return_and_none():
    ap = armed_driving(GF_ACTION=3)
    ap.sensor_telemetry([fix(0.0)], [], epoch_ns=0)
    upload(ap, square(10.0), now_ns=1 * S)
    ap.update(2 * S)
    ap.sensor_telemetry([fix(12.0)], [], epoch_ns=0)
    ap.update(3 * S)
    assert ap.heartbeat().custom_mode == custom_mode(RTL)
    off = armed_driving(GF_ACTION=0)
    off.sensor_telemetry([fix(0.0)], [], epoch_ns=0)
    upload(off, square(10.0), now_ns=1 * S)
    off.sensor_telemetry([fix(12.0)], [], epoch_ns=0)
    assert driving(off, 3 * S) != (0.0, 0.0) and _texts(off, 3 * S) == []


def test_a_zone_that_would_be_breached_at_once_is_discarded_as_px4_does():
    ap = armed_driving()  # home is not set (no fix at arming)
    ap.sensor_telemetry([fix(30.0)], [], epoch_ns=0)  # armed, outside the square uploaded next
    assert upload(ap, square(10.0), now_ns=2 * S) == ml.MAV_MISSION_ACCEPTED
    assert driving(ap, 3 * S) != (0.0, 0.0)  # no breach: the zone was discarded
    assert (ml.MAV_SEVERITY_CRITICAL,
            "Geofence invalid, doesn't contain current vehicle ") in _texts(ap, 3 * S)
