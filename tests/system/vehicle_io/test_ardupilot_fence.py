"""The operating area as ArduPilot's own fence, on its own firmware (Rover SITL, issues #57, #63).

vehicle_io (SERIAL0) gets the area on ``area/active`` (published here, as the controller does) and
uploads it; the test reads back what the firmware holds on its own link (SERIAL2, a plain
pymavlink connection, system 251): the fence and rally lists over the mission protocol and the
FENCE_* parameters, against positions computed here from the run's origin. Then the fence holds the
line: armed in MANUAL, the area is changed so that a keep-out circle covers the vessel, ArduPilot
breaches and takes the vessel into HOLD, and vehicle_io names the cause ``fence``.

Skipped, saying why, only when the firmware binary is absent.
"""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from seaway.contract import keys
from seaway.contract.messages import ActiveArea, ModeRequest
from seaway.vessel.frames import GeoOrigin
from seaway_vehicle_io.mav import mavlink, mavutil

from tests.system.vehicle_io.ardupilot_sitl import needs_sitl
from tests.system.vehicle_io.test_ardupilot_sitl import (  # noqa: F401  (the sitl fixture)
    EKF_READY_TIMEOUT_S,
    REQUEST_TIMEOUT_S,
    StatusWatch,
    alive,
    arm,
    sitl,
    start_vio,
)

pytestmark = [pytest.mark.system, pytest.mark.slow]

ORIGIN = GeoOrigin.from_degrees(28.18, 112.94, 30.0)  # the lake scenario's, the SITL's home
KEEP_IN = [(150.0, -150.0), (150.0, 150.0), (-150.0, 150.0), (-150.0, -150.0)]
KEEP_OUT_POLY = [(60.0, 60.0), (60.0, 90.0), (90.0, 75.0)]
KEEP_OUT_CIRCLE = ((60.0, -60.0), 15.0)
RALLY = [(-40.0, 40.0), (40.0, -100.0)]
MODE_HOLD = 4


def active_area(since_ns: int, circle: tuple[tuple[float, float], float] = KEEP_OUT_CIRCLE
                ) -> ActiveArea:
    (cx, cy), r = circle
    return ActiveArea.make(
        stamp_ns=since_ns, since_ns=since_ns, source="test",
        keep_in={"name": "lake", "vertices": [{"x_m": x, "y_m": y} for x, y in KEEP_IN]},
        keep_out_polygons=[{"name": "reeds",
                            "vertices": [{"x_m": x, "y_m": y} for x, y in KEEP_OUT_POLY]}],
        keep_out_circles=[{"name": "buoy", "x_m": cx, "y_m": cy, "radius_m": r}],
        rally_points=[{"x_m": x, "y_m": y} for x, y in RALLY])


def oversized_area(since_ns: int, keep_outs: int = 12) -> ActiveArea:
    """A 100-vertex keep-in and ``keep_outs`` 100-vertex keep-out polygons: 1300 fence items."""

    def ring(cx: float, cy: float, r: float) -> list[dict[str, float]]:
        return [{"x_m": cx + r * math.cos(2 * math.pi * k / 100),
                 "y_m": cy + r * math.sin(2 * math.pi * k / 100)} for k in range(100)]

    return ActiveArea.make(
        stamp_ns=since_ns, since_ns=since_ns, source="test", keep_in={"vertices": ring(0, 0, 400)},
        keep_out_polygons=[{"vertices": ring(150 * math.cos(k), 150 * math.sin(k), 10)}
                           for k in range(keep_outs)])


def e7(north_m: float, east_m: float) -> tuple[int, int]:
    lat, lon, _ = ORIGIN.to_geodetic(north_m, east_m, 0.0)
    return round(math.degrees(lat) * 1e7), round(math.degrees(lon) * 1e7)


class Reader:
    """The test's own link to the firmware (SERIAL2): mission-protocol downloads, parameter reads."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=251,
                                               source_component=190, dialect="ardupilotmega",
                                               autoreconnect=False)
        assert self.conn.wait_heartbeat(timeout=30) is not None, "no HEARTBEAT on SERIAL2"

    def download(self, mission_type: int) -> list[Any]:
        c = self.conn
        c.mav.mission_request_list_send(c.target_system, 1, mission_type)
        count = c.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
        assert count is not None and count.mission_type == mission_type, count
        items = []
        for seq in range(count.count):
            c.mav.mission_request_int_send(c.target_system, 1, seq, mission_type)
            got = c.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=5)
            assert got is not None and got.seq == seq and got.mission_type == mission_type, got
            items.append(got)
        c.mav.mission_ack_send(c.target_system, 1, mavlink.MAV_MISSION_ACCEPTED, mission_type)
        return items

    def param(self, name: str) -> float:
        c = self.conn
        c.mav.param_request_read_send(c.target_system, 1, name.encode(), -1)
        end = time.monotonic() + 5
        while time.monotonic() < end:
            m = c.recv_match(type="PARAM_VALUE", blocking=True, timeout=1)
            if m is not None and m.param_id == name:
                return float(m.param_value)
        raise AssertionError(f"no PARAM_VALUE {name}")

    def close(self) -> None:
        self.conn.close()


@needs_sitl
def test_vehicle_io_uploads_the_area_as_ardupilots_fence_and_the_fence_holds_the_line(
        zenoh_env, procs, bus, tmp_path, sitl):  # noqa: F811
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url)
    status.wait(lambda s: s.link_ok and s.autopilot == "ardupilot", 90, "vehicle_io's link")
    areas = bus.publisher(keys.AREA_ACTIVE)
    first = active_area(time.time_ns())
    areas.put(first)
    t0 = time.monotonic()
    _, st = status.wait(lambda s: s.autopilot_fence is not None
                        and s.autopilot_fence.state not in ("uploading",), 60,
                        "the fence's verdict")
    took_s = time.monotonic() - t0
    alive(vio, procs, sitl)
    fence = st.autopilot_fence
    assert fence is not None and fence.state == "verified", fence
    assert (fence.fence_items, fence.rally_points) == (4 + 3 + 1, 2)
    print(f"fence verified {took_s:.1f} s after the area was published: {fence.detail}")

    # -- what the firmware holds, read on its own link ------------------------------------------
    reader = Reader(5762 + 10 * sitl.instance)
    try:
        held = reader.download(mavlink.MAV_MISSION_TYPE_FENCE)
        rally = reader.download(mavlink.MAV_MISSION_TYPE_RALLY)
        params = {p: reader.param(p) for p in ("FENCE_ENABLE", "FENCE_TYPE", "FENCE_ACTION")}
    finally:
        reader.close()
    want = ([(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4.0, e7(*v)) for v in KEEP_IN]
            + [(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, 3.0, e7(*v))
               for v in KEEP_OUT_POLY]
            + [(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, KEEP_OUT_CIRCLE[1],
                e7(*KEEP_OUT_CIRCLE[0]))])
    assert len(held) == len(want), [(m.command, m.param1) for m in held]
    for m, (command, param1, (lat, lon)) in zip(held, want, strict=True):
        assert m.command == command and m.param1 == pytest.approx(param1, abs=0.01), m
        assert abs(m.x - lat) <= 1 and abs(m.y - lon) <= 1, (m, lat, lon)
    assert [(r.command, *(round(v) for v in (r.x, r.y))) for r in rally] == [
        (mavlink.MAV_CMD_NAV_RALLY_POINT, *e7(*p)) for p in RALLY]
    assert params == {"FENCE_ENABLE": 1.0, "FENCE_TYPE": 4.0, "FENCE_ACTION": 2.0}
    print(f"read back on SERIAL2: {len(held)} fence items, {len(rally)} rally points, {params}")

    # -- more than the firmware stores: refused, naming the fields; the fence it has stays ------
    big = oversized_area(time.time_ns())
    areas.put(big)
    _, refused = status.wait(lambda s: s.autopilot_fence is not None
                             and s.autopilot_fence.area_since_ns == big.since_ns
                             and s.autopilot_fence.state != "uploading", 60,
                             "the verdict on an area too big for the firmware")
    print(f"oversized area: {refused.autopilot_fence.state}: {refused.autopilot_fence.detail}")
    assert refused.autopilot_fence.state == "refused", refused.autopilot_fence
    assert "NO_SPACE" in refused.autopilot_fence.detail
    assert "keep_in (100 vertices) + keep_out_polygons (" in refused.autopilot_fence.detail
    reader = Reader(5762 + 10 * sitl.instance)
    try:
        assert len(reader.download(mavlink.MAV_MISSION_TYPE_FENCE)) == len(want)  # unchanged
    finally:
        reader.close()

    # -- the line holds: armed in MANUAL, a keep-out circle over the vessel ----------------------
    reply, t_arm = arm(bus), time.monotonic()
    while not reply.accepted:
        assert time.monotonic() - t_arm < EKF_READY_TIMEOUT_S, f"never armed: {reply.reason}"
        time.sleep(2.0)
        reply = arm(bus)
        alive(vio, procs, sitl)
    assert bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode="MANUAL"),
                       timeout_s=REQUEST_TIMEOUT_S).accepted
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and s.hold_reason is None, 10,
                "armed in MANUAL", fresh=True)
    shrunk = active_area(time.time_ns(), circle=((0.0, 0.0), 30.0))  # the vessel is at the origin
    t_put = time.monotonic()
    areas.put(shrunk)
    t_hold, first = status.wait(lambda s: s.hold_reason is not None, 30,
                                "the autopilot's fence taking the vessel", fresh=True)
    # Rover says a breach only in SYS_STATUS (1 Hz): the bare mode change may come first, and
    # the cause names it when the health bit follows (failsafe_cause.CAUSE_WINDOW_S).
    t_named, named = status.wait(lambda s: s.hold_reason == "fence", 10,
                                 "the hold named 'fence'", fresh=False)
    alive(vio, procs, sitl)
    print(f"breach: HOLD {t_hold - t_put:.1f} s after the shrunk area was published (first said: "
          f"{first.hold_reason}), named 'fence' {t_named - t_put:.1f} s after: "
          f"{named.hold_reason_detail!r}")
    assert named.stamp_ns >= first.stamp_ns and named.mode == "HOLD", named
    assert "fence" in named.hold_reason_detail.lower(), named.hold_reason_detail
    status.wait(lambda s: s.autopilot_fence is not None
                and s.autopilot_fence.area_since_ns == shrunk.since_ns
                and s.autopilot_fence.state == "verified", 30,
                "the shrunk area verified on the autopilot")
    latest = status.poll()[-1][1]
    assert latest.hold_reason == "fence" and latest.mode == "HOLD", latest  # until Seaway's own mode
