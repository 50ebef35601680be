"""The thrust pair -> PX4 Manual-mode mapping, measured on PX4's own firmware (SITL, SIH, 10046).

vehicle_io (a real process, its default PX4 configuration) commands thrust pairs with a difference;
the test reads what PX4's control allocation puts on each motor (HIL_ACTUATOR_CONTROLS on the SIH
link) and what the simulated rover does (HIL_STATE_QUATERNION: speed, yaw rate). The airframe's own
RD_YAW_STK_GAIN (0.6) is left in place: the mapping must undo it, from the value it read.

Skipped, saying why, only when the firmware binary is absent.
"""

from __future__ import annotations

import math
import time

import pytest

from tests.system.vehicle_io.px4_sitl import Px4Sitl, boat_params, needs_px4
from tests.system.vehicle_io.test_ardupilot_sitl import StatusWatch, hold_thrust
from tests.system.vehicle_io.test_px4_sitl import THRUST_MAX_N, armed_in_manual, start_vio

pytestmark = [pytest.mark.system, pytest.mark.slow]

AIRFRAME_YAW_STICK_GAIN = 0.6  # 10046_sihsim_rover_differential's RD_YAW_STK_GAIN
# (port, starboard) [N] on the 75 N paper boat: differences up to 1.2 of full scale (2 x 0.6), the
# most this airframe's gain lets through; ahead, astern, and turning on the spot.
PAIRS = ((40.0, 10.0), (10.0, 40.0), (60.0, 30.0), (30.0, -15.0), (-30.0, 15.0), (45.0, -45.0),
         (-20.0, -40.0))
MOTOR_TOL = 0.012  # PX4's motor output vs the commanded share of full thrust (wire: 0.002)


@pytest.fixture
def px4(tmp_path):
    params = {**boat_params(), "COM_ARM_ODID": 2, "RD_YAW_STK_GAIN": AIRFRAME_YAW_STICK_GAIN}
    s = Px4Sitl(tmp_path, params=params)
    try:
        yield s
    finally:
        s.kill()


@needs_px4
def test_each_motor_gets_its_share_of_a_thrust_pair_on_px4(zenoh_env, procs, bus, tmp_path, px4):
    """Each motor at the commanded share of full thrust (within 1.2 % of full scale) for pairs
    with a difference, though PX4 scales the roll stick by RD_YAW_STK_GAIN 0.6."""
    obs = px4.observer
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
    status.wait(lambda s: s.link_ok and s.autopilot_loss_failsafe is not None, 60,
                "vehicle_io's link and verdict")
    armed_in_manual(bus, procs, vio, px4)
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and s.thrust_withheld is None, 10,
                "armed in MANUAL, thrust forwarded", fresh=True)
    errors = []
    for port, stbd in PAIRS:
        hold_thrust(bus, port, stbd, 0.8)
        t = time.monotonic()
        hold_thrust(bus, port, stbd, 1.2)
        got = obs.motors_since(t)
        assert len(got) >= 5, "too few HIL_ACTUATOR_CONTROLS"
        left = sum(m.left for m in got) / len(got)
        right = sum(m.right for m in got) / len(got)
        yaw = obs.mean_yaw_rate_since(t)
        speeds = [math.hypot(vx, vy) for (m, vx, vy) in list(obs.speeds) if m >= t]
        print(f"port {port:+5.1f} N stbd {stbd:+5.1f} N -> Motor2 (left) {left:+.3f} "
              f"Motor1 (right) {right:+.3f}, want {port / THRUST_MAX_N:+.3f} "
              f"{stbd / THRUST_MAX_N:+.3f}; yaw rate {yaw:+.3f} rad/s, "
              f"speed {sum(speeds) / max(len(speeds), 1):.2f} m/s")
        errors.append((abs(left - port / THRUST_MAX_N), abs(right - stbd / THRUST_MAX_N)))
        assert abs(left - port / THRUST_MAX_N) <= MOTOR_TOL, (port, stbd, left, right)
        assert abs(right - stbd / THRUST_MAX_N) <= MOTOR_TOL, (port, stbd, left, right)
        assert (yaw > 0.02) == (port > stbd + 1.0), (port, stbd, yaw)  # clockwise when port leads
    print(f"worst motor error: {max(max(e) for e in errors):.4f} of full scale")
