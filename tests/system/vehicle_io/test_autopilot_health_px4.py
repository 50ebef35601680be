"""What Seaway believes about PX4's own firmware (issue #63): a mission starts only once the
autopilot is healthy; its low-battery failsafe reaches the mission with its cause, the energy budget
says which estimate of the battery it takes, and resume is refused while the failsafe stands.

vehicle_io, the estimator and the controller run against PX4 SITL (SIH, airframe 10046,
``autopilot_stack``) with the NED origin at SIH's home; the test watches the firmware on the SIH
link and sets its parameters there.
"""

from __future__ import annotations

import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import HOLD_REASON_TEXT

from tests.conftest import wait_for
from tests.system.vehicle_io.autopilot_stack import Watch, start_stack
from tests.system.vehicle_io.px4_sitl import Px4Sitl, boat_params, needs_px4

pytestmark = [pytest.mark.system, pytest.mark.slow]

VESSEL = "paper-boat"  # the lake scenario's
SIH_HOME = "47.397742,8.545594"  # SIH_LOC_LAT0, SIH_LOC_LON0 (PX4's defaults)
MISSION = "truth"
TASK_POWER_W = 150.0  # cruises outside the vessel file's 10 N dead zone


def nonzero(cmd) -> bool:
    return (cmd.thrust_port_n, cmd.thrust_starboard_n) != (0.0, 0.0)


@needs_px4
@pytest.mark.timeout(600)
def test_a_mission_waits_while_pxs_estimator_is_not_using_gnss(zenoh_env, procs, bus, tmp_path):
    """PX4 boots without a GNSS fix (SIH's ``SIM_GPS_USED`` 0): it arms in MANUAL and keeps sending
    a dead-reckoned GLOBAL_POSITION_INT, but its ESTIMATOR_STATUS has no absolute position. The
    mission sent at start waits, saying so, past the arming; it starts by itself once the fix is
    back and PX4 uses it, and no thrust is commanded before."""
    px4 = Px4Sitl(tmp_path, params={**boat_params(), "SIM_GPS_USED": 0})
    try:
        stack = start_stack(procs, zenoh_env, tmp_path, px4.vio_url, "px4", VESSEL, SIH_HOME)
        w = Watch(bus)
        w.first(keys.VEHICLE_STATUS, lambda s: True, 60, "vehicle_io's first status")
        time.sleep(1.0)
        reply = w.send_mission(MISSION, 30.0, TASK_POWER_W)
        assert reply.accepted and reply.detail["state"] == "waiting", reply
        w.first(keys.VEHICLE_STATUS, lambda s: s.link_ok, 60, "the link to PX4")
        assert w.set_mode("MANUAL").accepted
        t_armed = w.arm_until_accepted(60)
        w.first(keys.VEHICLE_STATUS, lambda s: s.armed and s.mode == "MANUAL", 10, "armed in MANUAL")
        time.sleep(5.0)
        st = w.latest(keys.VEHICLE_STATUS)
        assert st.thrust_withheld == "autopilot_unhealthy", st
        assert "not using GNSS" in st.autopilot_unhealthy_detail, st.autopilot_unhealthy_detail
        # Sent again now, it says what it waits for (the state flows: PX4 dead-reckons).
        again = w.send_mission(MISSION, 30.0, TASK_POWER_W)
        assert again.accepted and again.detail["state"] == "waiting", again
        assert "not using GNSS" in again.reason, again.reason
        assert not [c for _, c in w.of(keys.THRUST) if c.source == "cc-empc" and nonzero(c)]
        px4.observer.set_param("SIM_GPS_USED", 10)
        t_fix = time.monotonic()
        t_active, _ = w.mission_in(MISSION, "active", 120)
        t_thrust, _ = w.first(keys.THRUST, lambda c: c.source == "cc-empc" and nonzero(c), 60,
                              "the first thrust of the mission")
        t_healthy = next(t for t, s in w.of(keys.VEHICLE_STATUS)
                         if t > t_fix and s.thrust_withheld is None)
        print(f"armed {t_armed:.1f}, fix back {t_fix:.1f}, healthy {t_healthy:.1f}, mission active "
              f"{t_active:.1f}, first thrust {t_thrust:.1f}; waited: {again.reason}")
        assert t_thrust >= t_healthy > t_fix
        for p in stack.values():
            assert p.poll() is None, procs.log(p)[-3000:]
    finally:
        px4.kill()


@needs_px4
@pytest.mark.timeout(600)
def test_pxs_battery_failsafe_pauses_with_its_cause_and_resume_waits_for_it(zenoh_env, procs, bus,
                                                                           tmp_path):
    """Under way, SIH drains its pack in 30 s (``SIM_BAT_DRAIN``) to 10 %: PX4's own figure
    falls far below what the controller counted, and the budget takes it, saying so. Critical at
    12.5 % (``BAT_CRIT_THR``) PX4 returns (``COM_LOW_BAT_ACT`` 3): the mission pauses naming the
    battery. Taken back to MANUAL, resume is refused while PX4's battery stays critical."""
    px4 = Px4Sitl(tmp_path, params={**boat_params(), "COM_LOW_BAT_ACT": 3, "BAT_CRIT_THR": 0.125,
                                    "BAT_LOW_THR": 0.25, "SIM_BAT_MIN_PCT": 10})
    try:
        stack = start_stack(procs, zenoh_env, tmp_path, px4.vio_url, "px4", VESSEL, SIH_HOME)
        w = Watch(bus)
        w.first(keys.VEHICLE_STATUS, lambda s: s.link_ok and s.thrust_withheld != "no_link", 60,
                "the link to PX4")
        assert w.set_mode("MANUAL").accepted
        w.arm_until_accepted(60)
        w.first(keys.VEHICLE_STATUS, lambda s: s.thrust_withheld is None, 60, "a healthy PX4")
        # 'warn' and forced past the check (longer than the pack): flown on whatever the budget
        # says, so that PX4's failsafe is what stops it
        reply = w.send_mission(MISSION, 300.0, TASK_POWER_W, "warn", force=True)
        assert reply.accepted, reply.reason
        w.mission_in(MISSION, "active", 60)
        px4.observer.set_param("SIM_BAT_DRAIN", 30)
        # The budget takes the lowest of PX4's own figure and the one from PX4's voltage (both
        # the autopilot's word; which is lower depends on the pack's curve), saying which.
        _, low = w.first(keys.MISSION_ENERGY, lambda b: b.battery_source in ("autopilot", "voltage")
                         and b.battery_remaining_j is not None and b.battery_remaining_j < 0.5 * (
                             w.latest(keys.VEHICLE_BATTERY).capacity_j or 1.0), 120,
                         "the budget taking PX4's falling figure")
        battery = w.latest(keys.VEHICLE_BATTERY)
        print(f"PX4: {battery.remaining_frac} at {battery.voltage_v} V ({battery.autopilot_level}); "
              f"budget {low.battery_remaining_j:.0f} J ({low.battery_source})")
        tolerance = 0.05 * battery.capacity_j
        if low.battery_source == "autopilot":
            assert low.battery_remaining_j == pytest.approx(battery.remaining_j, abs=tolerance)
        else:
            assert low.battery_remaining_j <= battery.remaining_j + tolerance
        # (The paper's boat modelled on SIH's rover is below its ground friction here: the
        # controller may pause for a motion fault first, 'not_moving'. PX4's failsafe then names
        # the pause's cause anew.)
        _, paused = w.first(keys.MISSION_STATUS, lambda m: m.state == "paused"
                            and "battery" in m.reason, 120, "the pause naming the battery")
        print(f"paused: {paused.reason}")
        assert HOLD_REASON_TEXT["battery"] in paused.reason, paused.reason
        # Taken back during PX4's 5 s Hold, before its Return drives home and disarms there
        wait_for(lambda: w.set_mode("MANUAL").accepted, 10, interval_s=0.5, what="MANUAL again")
        w.first(keys.VEHICLE_STATUS, lambda s: s.mode == "MANUAL" and s.thrust_withheld is None,
                15, "the thrust applied again in MANUAL")
        refused = w.command("resume")
        print(f"resume: {refused.reason}")
        assert not refused.accepted and "battery failsafe" in refused.reason, refused
        for p in stack.values():
            assert p.poll() is None, procs.log(p)[-3000:]
    finally:
        px4.kill()
