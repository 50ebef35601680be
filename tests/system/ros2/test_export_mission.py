"""``seaway export ros2`` of a whole mission's recording, as ``./run`` makes one (the lake mission,
here in lockstep to be quick): ``rosbags`` reads every CDR channel message for message, including
the two ``nav_msgs/Path`` topics a replayed recording lacks (the accepted mission and the MPC's
predicted trajectory) and the battery, each against the Seaway message it was made from."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from seaway.contract import keys
from seaway.recording import reader

from tests.conftest import BIN, solver_built

pytestmark = pytest.mark.system


def _stamp(h) -> int:
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_rosbags_reads_every_cdr_channel_of_a_mission_run(tmp_path: Path) -> None:
    solver_built("cc-empc", "paper-boat")  # a normal run, not a machine's first
    run = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch",
                           "--run-dir", str(run)], capture_output=True, text=True, timeout=360,
                          check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "mission complete" in done.stdout, done.stdout[-3000:]
    rec = run / "recording.mcap"
    out = tmp_path / "bag.mcap"
    ex = subprocess.run([str(BIN / "seaway"), "export", "ros2", str(rec), str(out)],
                        capture_output=True, text=True, timeout=180, check=False)
    assert ex.returncode == 0, ex.stdout + ex.stderr

    wanted = [keys.NAV_STATE, keys.GNSS, keys.MISSION_ACCEPTED, keys.SOLVE, keys.THRUST,
              keys.VEHICLE_BATTERY]
    dec = reader.decode_vessel([rec], None, [k.suffix for k in wanted])
    seaway = {k.suffix: [x for x in dec.get(k.suffix) if x is not None] for k in wanted}
    got: dict[str, list] = {}
    with AnyReader([out]) as bag:
        types = {c.topic.split("/", 2)[-1]: c.msgtype for c in bag.connections}  # /<vessel>/...
        for con, _t, raw in bag.messages():
            got.setdefault(con.topic.split("/", 2)[-1], []).append(bag.deserialize(raw, con.msgtype))
    assert types["mission/path"] == types["mpc/predicted_path"] == "nav_msgs/msg/Path"
    assert types["battery"] == "sensor_msgs/msg/BatteryState"

    # message for message: as many as Seaway recorded, in the same order, stamped the same
    for topic, key in (("odom", keys.NAV_STATE), ("gnss/fix", keys.GNSS),
                       ("mission/path", keys.MISSION_ACCEPTED), ("mpc/predicted_path", keys.SOLVE),
                       ("thrust/wrench", keys.THRUST), ("battery", keys.VEHICLE_BATTERY)):
        ours = seaway[key.suffix]
        assert len(got[topic]) == len(ours) > 0, topic
        assert [_stamp(x.header) for x in got[topic]] == [x.stamp_ns for x in ours], topic

    # the mission: its waypoints in map (ENU: x east, y north)
    for path, acc in zip(got["mission/path"], seaway[keys.MISSION_ACCEPTED.suffix], strict=True):
        wps = acc.waypoints_m()
        assert len(path.poses) == len(wps) >= 2
        for pose, (n, e) in zip(path.poses, wps, strict=True):
            p = pose.pose.position
            assert (p.x, p.y) == pytest.approx((e, n), abs=1e-9)
    # the MPC's prediction at each solve, point for point
    for path, solve in zip(got["mpc/predicted_path"], seaway[keys.SOLVE.suffix], strict=True):
        assert len(path.poses) == len(solve.predicted_x_m)
        for pose, n, e in zip(path.poses, solve.predicted_x_m, solve.predicted_y_m, strict=True):
            assert (pose.pose.position.x, pose.pose.position.y) == pytest.approx((e, n), abs=1e-9)
    # the battery: ROS's units and signs (fraction 0..1, current negative while discharging)
    for b, ours in zip(got["battery"], seaway[keys.VEHICLE_BATTERY.suffix], strict=True):
        if ours.voltage_v is not None:
            assert b.voltage == pytest.approx(ours.voltage_v, rel=1e-6)
        if ours.remaining_frac is not None:
            assert b.percentage == pytest.approx(ours.remaining_frac, rel=1e-6)
        if ours.current_a is not None:
            assert b.current == pytest.approx(-ours.current_a, rel=1e-6)
        else:
            assert math.isnan(b.current)
