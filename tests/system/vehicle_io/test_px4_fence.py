"""The operating area as PX4's geofence: on the simulator's PX4 imitation (upload, read-back and a
breach that PX4's GF_ACTION Hold answers), and on PX4's own firmware (SITL: upload and read-back
on its own link). Issues #57 and #63.

vehicle_io gets the area on ``area/active`` (published here, as the controller does). Real
processes, real MAVLink bytes: ``seaway-sim`` (real time, its PX4 endpoint) or PX4 SITL.
"""

from __future__ import annotations

import math
import subprocess
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    ActiveArea,
    ArmRequest,
    LocalPosition,
    ModeRequest,
    ThrustCommand,
)
from seaway.runtime.bus import Bus
from seaway.vessel.frames import GeoOrigin
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.profile import decode_param_value

from tests.conftest import BIN, Procs, wait_for
from tests.system.vehicle_io.px4_sitl import Px4Sitl, boat_params, needs_px4
from tests.system.vehicle_io.test_ardupilot_sitl import StatusWatch
from tests.system.vehicle_io.test_mavlink_authority import udp_port

pytestmark = [pytest.mark.system, pytest.mark.slow]

VIO = BIN / "seaway-vehicle-io"
SIM = BIN / "seaway-sim"
ORIGIN = GeoOrigin.from_degrees(28.18, 112.94, 30.0)  # the lake scenario's
REQUEST_TIMEOUT_S = 5.0


def area(center: tuple[float, float], half_m: float) -> ActiveArea:
    """A keep-in square of ``half_m`` round ``center``, a keep-out circle, two rally points."""
    cx, cy = center
    square = [(cx + half_m, cy - half_m), (cx + half_m, cy + half_m),
              (cx - half_m, cy + half_m), (cx - half_m, cy - half_m)]
    now = time.time_ns()
    return ActiveArea.make(
        stamp_ns=now, since_ns=now, source="test",
        keep_in={"vertices": [{"x_m": x, "y_m": y} for x, y in square]},
        keep_out_circles=[{"name": "buoy", "x_m": cx - half_m / 2, "y_m": cy - half_m / 2,
                           "radius_m": half_m / 5}],
        rally_points=[{"x_m": cx + half_m / 2, "y_m": cy}, {"x_m": cx, "y_m": cy + half_m / 2}])


def e7(north_m: float, east_m: float) -> tuple[int, int]:
    lat, lon, _ = ORIGIN.to_geodetic(north_m, east_m, 0.0)
    return round(math.degrees(lat) * 1e7), round(math.degrees(lon) * 1e7)


def start_vio(procs: Procs, env: dict[str, str], tmp: Path, url: str) -> subprocess.Popen:
    path = tmp / f"vio-{len(procs.procs)}.toml"
    path.write_text(f'mavlink = "{url}"\nautopilot = "px4"\n')
    return procs.start([str(VIO), "--config", str(path), "--scenario", "lake"], env,
                       name=f"vio-{len(procs.procs)}")


def request(bus: Bus, spec: keys.KeySpec, msg):
    return bus.request(spec, msg, timeout_s=REQUEST_TIMEOUT_S)


def verified(status: StatusWatch, a: ActiveArea, what: str):
    _, st = status.wait(lambda s: s.autopilot_fence is not None
                        and s.autopilot_fence.area_since_ns == a.since_ns
                        and s.autopilot_fence.state != "uploading", 60, what)
    assert st.autopilot_fence.state == "verified", st.autopilot_fence
    return st


def test_the_sims_px4_takes_the_fence_and_holds_the_line(zenoh_env, procs, bus, tmp_path):
    """Upload and read-back on the imitation; then, armed in MANUAL, the vessel driven out of the
    keep-in area: PX4's Hold, its text, and vehicle_io's hold_reason 'fence'."""
    port = udp_port()
    sim = procs.start([str(SIM), "--scenario", "lake", "--mavlink", f"udpin:127.0.0.1:{port}"],
                      zenoh_env, "sim")
    status = StatusWatch(bus)
    positions = bus.subscribe(keys.LOCAL_POSITION)
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}")
    status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60, "vehicle_io's link to the sim")
    start: LocalPosition = wait_for(positions.latest, 30, what="a LocalPosition")
    a = area((start.x_m, start.y_m), 6.0)
    bus.publisher(keys.AREA_ACTIVE).put(a)
    st = verified(status, a, "the fence's verdict on the imitation")
    assert (st.autopilot_fence.fence_items, st.autopilot_fence.rally_points) == (5, 2)
    assert "GF_ACTION=2 (Hold mode)" in st.autopilot_fence.action
    print(f"imitation: {st.autopilot_fence.detail}")

    assert request(bus, keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                            mode="MANUAL")).accepted
    assert request(bus, keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(),
                                                          arm=True)).accepted
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and s.thrust_withheld is None, 10,
                "armed in MANUAL", fresh=True)
    thrust = bus.publisher(keys.THRUST)
    t0 = time.monotonic()
    held = None
    while held is None:  # full ahead until the autopilot stops it
        assert time.monotonic() - t0 < 60, "never left the keep-in area"
        thrust.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=60.0,
                                      thrust_starboard_n=60.0, source="test"))
        time.sleep(0.05)
        held = next((s for _, s in status.poll() if s.hold_reason is not None), None)
    _, named = status.wait(lambda s: s.hold_reason is not None and s.mode == "HOLD", 5,
                           "HOLD with its cause")
    where = positions.latest()
    out_m = max(abs(where.x_m - start.x_m), abs(where.y_m - start.y_m)) if where else float("nan")
    print(f"imitation breach after {time.monotonic() - t0:.1f} s, {out_m:.1f} m from the start: "
          f"{named.hold_reason} ({named.hold_reason_detail})")
    assert named.hold_reason == "fence", named
    assert "Geofence violation" in named.hold_reason_detail, named.hold_reason_detail
    assert named.thrust_withheld == "mode"
    assert "Geofence violation: approaching or outside geofenc" in procs.log(vio)  # 50 chars
    assert sim.poll() is None and vio.poll() is None


def at_the_runs_origin(monkeypatch: pytest.MonkeyPatch) -> None:
    """PX4 SITL's SIH starts where PX4_HOME_* say (``px4-rc.sihsim``): here, the run's origin.
    Elsewhere, the fence would lie half a world away and PX4 would discard it (see below)."""
    for name, value in (("LAT", 28.18), ("LON", 112.94), ("ALT", 30.0)):
        monkeypatch.setenv(f"PX4_HOME_{name}", str(value))


@needs_px4
def test_px4s_own_firmware_takes_the_fence_and_it_reads_back(zenoh_env, procs, bus, tmp_path,
                                                             monkeypatch):
    """PX4 SITL 1.18: vehicle_io's upload verified, and the same lists read back on the SIH link."""
    at_the_runs_origin(monkeypatch)
    px4 = Px4Sitl(tmp_path)
    try:
        status = StatusWatch(bus)
        vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
        status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60, "vehicle_io's link to PX4")
        a = area((0.0, 0.0), 100.0)
        t0 = time.monotonic()
        bus.publisher(keys.AREA_ACTIVE).put(a)
        st = verified(status, a, "the fence's verdict on PX4 SITL")
        print(f"PX4 SITL: verified {time.monotonic() - t0:.1f} s after the area: "
              f"{st.autopilot_fence.detail}")
        fence = px4.observer.download(mavlink.MAV_MISSION_TYPE_FENCE)
        rally = px4.observer.download(mavlink.MAV_MISSION_TYPE_RALLY)
        square = [(100.0, -100.0), (100.0, 100.0), (-100.0, 100.0), (-100.0, -100.0)]
        want = ([(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4.0, e7(*v)) for v in square]
                + [(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 20.0, e7(-50.0, -50.0))])
        assert [(m.command, m.param1) for m in fence] == [(c, p) for c, p, _ in want]
        for m, (_, _, (lat, lon)) in zip(fence, want, strict=True):
            assert abs(m.x - lat) <= 1 and abs(m.y - lon) <= 1, (m, lat, lon)
        assert [(r.command, r.x, r.y) for r in rally] == [
            (mavlink.MAV_CMD_NAV_RALLY_POINT, *e7(50.0, 0.0)),
            (mavlink.MAV_CMD_NAV_RALLY_POINT, *e7(0.0, 50.0))]
        px4.observer.params.pop("GF_ACTION", None)
        px4.observer.sih.mav.param_request_read_send(px4.instance + 1, 1, b"GF_ACTION", -1)
        value, ptype = wait_for(lambda: px4.observer.params.get("GF_ACTION"), 10,
                                what="GF_ACTION on the SIH link")
        assert decode_param_value(value, ptype) == 2.0
        print(f"PX4 SITL read back on the SIH link: {len(fence)} fence items, {len(rally)} rally "
              "points, GF_ACTION 2")
        assert status.poll()[-1][1].autopilot_fence.state == "verified"  # not discarded since
        assert vio.poll() is None and px4.proc.poll() is None, px4.log()[-3000:]
    finally:
        px4.kill()


@needs_px4
def test_px4s_own_geofence_holds_the_line_and_its_cause_is_named(zenoh_env, procs, bus, tmp_path,
                                                                 monkeypatch):
    """PX4 SITL 1.18 (SIH differential rover, the boat's parameters), started at the run's origin:
    armed in MANUAL, driven full ahead out of a keep-in square; PX4's geofence (GF_ACTION 2) takes
    it into Hold, and vehicle_io names the cause 'fence' with PX4's words."""
    at_the_runs_origin(monkeypatch)
    px4 = Px4Sitl(tmp_path, params=boat_params())
    try:
        status = StatusWatch(bus)
        positions = bus.subscribe(keys.LOCAL_POSITION)
        vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
        status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60, "vehicle_io's link to PX4")
        start: LocalPosition = wait_for(positions.latest, 60, what="a LocalPosition")
        a = area((start.x_m, start.y_m), 8.0)
        bus.publisher(keys.AREA_ACTIVE).put(a)
        verified(status, a, "the fence's verdict on PX4 SITL")
        assert request(bus, keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                                mode="MANUAL")).accepted
        t_arm = time.monotonic()
        while not request(bus, keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(),
                                                                 arm=True)).accepted:
            assert time.monotonic() - t_arm < 60, "PX4 never armed"
            time.sleep(1.0)
        status.wait(lambda s: s.armed and s.mode == "MANUAL" and s.thrust_withheld is None, 10,
                    "armed in MANUAL", fresh=True)
        thrust = bus.publisher(keys.THRUST)
        t0 = time.monotonic()
        while not any(s.hold_reason is not None for _, s in status.poll()):
            if time.monotonic() - t0 >= 90:
                last = positions.latest()
                fast = max((math.hypot(vx, vy) for _, vx, vy in list(px4.observer.speeds)),
                           default=None)
                raise AssertionError(
                    f"PX4 never held: at {last and (last.x_m - start.x_m, last.y_m - start.y_m)} "
                    f"from the start, fastest {fast} m/s, motors "
                    f"{list(px4.observer.motors)[-1:]}, texts {list(px4.observer.texts)[-5:]}, "
                    f"status {status.poll()[-1][1]}")
            thrust.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=60.0,
                                          thrust_starboard_n=60.0, source="test"))
            time.sleep(0.05)
        # vehicle_io may name the breach from PX4's fence health bit a moment before PX4's Hold
        # shows in its HEARTBEAT: wait for both.
        _, named = status.wait(lambda s: s.hold_reason == "fence" and s.mode == "HOLD", 10,
                               "PX4 in HOLD with the hold named 'fence'")
        print(f"PX4 SITL breach after {time.monotonic() - t0:.1f} s: mode {named.mode}, "
              f"{named.hold_reason} ({named.hold_reason_detail}); texts "
              f"{[t for _, t in px4.observer.texts][-4:]}")
        assert named.mode == "HOLD" and "eofence" in named.hold_reason_detail, named
        assert vio.poll() is None and px4.proc.poll() is None, px4.log()[-3000:]
    finally:
        px4.kill()


@needs_px4
def test_a_fence_px4_accepts_but_discards_is_not_called_verified(zenoh_env, procs, bus, tmp_path):
    """PX4 at SIH's default home (Zurich), the run's area at the lake: PX4 ACKs the upload and
    the lists read back as sent, but its navigator drops every zone for not containing home and
    says so in text only. vehicle_io reports a mismatch, not a verified fence."""
    px4 = Px4Sitl(tmp_path)
    try:
        status = StatusWatch(bus)
        vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
        status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60, "vehicle_io's link to PX4")
        wait_for(lambda: any(s.rates_hz.get("HOME_POSITION") for _, s in status.poll()), 60,
                 what="PX4's home position")
        a = area((0.0, 0.0), 100.0)
        bus.publisher(keys.AREA_ACTIVE).put(a)
        _, st = status.wait(lambda s: s.autopilot_fence is not None
                            and s.autopilot_fence.state == "mismatch", 30,
                            "the fence judged not enforced")
        print(f"PX4 SITL away from the area: {st.autopilot_fence.detail}")
        assert "doesn't contain Home position" in st.autopilot_fence.detail
        assert vio.poll() is None
    finally:
        px4.kill()
