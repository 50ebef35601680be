"""Issue 63 in vehicle_io's pure core, driven with real packed MAVLink: the autopilot's health
(HEARTBEAT system_status, SYS_STATUS AHRS/GPS bits, its estimator's flags) withholds the thrust as
'autopilot_unhealthy' saying what it lacks; a failsafe the autopilot still stands in is published
as ``failsafe_latched`` (its health bit still unhealthy, or its battery flag low)."""

from __future__ import annotations

from typing import Any

from seaway_vehicle_io.autopilot_health import EST_POS_HORIZ_ABS, Health
from seaway_vehicle_io.core import Now
from seaway_vehicle_io.failsafe_cause import MAV_SYS_STATUS_SENSOR_BATTERY
from seaway_vehicle_io.mav import mavlink

from tests.unit.vehicle_io.test_hold_reason import AP_MODES, HEALTH, MS, WALL0, S, at, status, wire
from tests.unit.vehicle_io.test_hold_reason import connected as _connected

AHRS, GPS = mavlink.MAV_SYS_STATUS_AHRS, mavlink.MAV_SYS_STATUS_SENSOR_GPS
ALL = HEALTH | AHRS | GPS


def heartbeat(system_status: int, mode: str = "MANUAL") -> Any:
    return wire(mavlink.MAVLink_heartbeat_message(11, 3, 1 | 128, AP_MODES[mode], system_status, 3))


def sys_status(healthy: int) -> Any:
    return wire(mavlink.MAVLink_sys_status_message(ALL, ALL, healthy, 0, 12000, 0, 100, 0, 0, 0, 0,
                                                   0, 0))


def ekf(flags: int) -> Any:
    return wire(mavlink.MAVLink_ekf_status_report_message(flags, 0.1, 0.1, 0.1, 0.1, 0.1))


def connected():
    core = _connected()
    core.on_mavlink(sys_status(ALL), at(S))
    return core


def test_an_estimator_not_using_gnss_withholds_the_thrust_saying_so():
    core = connected()
    assert status(core, S).thrust_withheld is None
    core.on_mavlink(ekf(0x1 | 0x2 | 0x4), at(2 * S))  # attitude and velocity, no absolute position
    st = status(core, 2 * S)
    assert st.thrust_withheld == "autopilot_unhealthy"
    assert "estimator not using GNSS yet (EKF_STATUS_REPORT flags 0x7)" in st.autopilot_unhealthy_detail
    core.on_mavlink(ekf(0x7 | EST_POS_HORIZ_ABS), at(3 * S))
    st = status(core, 3 * S)
    assert st.thrust_withheld is None and st.autopilot_unhealthy_detail == ""


def test_a_critical_status_and_unhealthy_sensors_are_named():
    core = connected()
    core.on_mavlink(heartbeat(mavlink.MAV_STATE_CRITICAL), at(2 * S))
    core.on_mavlink(sys_status(ALL & ~GPS), at(2 * S))
    st = status(core, 2 * S)
    assert st.thrust_withheld == "autopilot_unhealthy"
    assert "status CRITICAL (HEARTBEAT)" in st.autopilot_unhealthy_detail
    assert "GPS unhealthy (SYS_STATUS)" in st.autopilot_unhealthy_detail
    core.on_mavlink(heartbeat(mavlink.MAV_STATE_ACTIVE), at(3 * S))
    core.on_mavlink(sys_status(ALL), at(3 * S))
    assert status(core, 3 * S).thrust_withheld is None


def test_disarmed_comes_before_unhealthy():
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 0, mavlink.MAV_STATE_CRITICAL,
                                                           3)), at(2 * S))
    assert status(core, 2 * S).thrust_withheld == "disarmed"


def test_ardupilots_battery_failsafe_stays_latched_after_the_operator_takes_the_vessel_back():
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(
        4, b"Battery 1 is low 11.00V used 500 mAh", 0, 0)), at(2 * S))
    core.on_mavlink(sys_status(ALL & ~MAV_SYS_STATUS_SENSOR_BATTERY), at(2100 * MS))
    core.on_mavlink(heartbeat(mavlink.MAV_STATE_ACTIVE, "HOLD"), at(2200 * MS))
    st = status(core, 2300 * MS)
    assert st.hold_reason == "battery" and st.failsafe_latched == "battery"
    assert "still unhealthy" in st.failsafe_latched_detail
    core.on_mavlink(heartbeat(mavlink.MAV_STATE_ACTIVE, "MANUAL"), at(3 * S))  # someone took it
    st = status(core, 3 * S)
    assert st.thrust_withheld is None and st.failsafe_latched == "battery"


def test_a_bit_unhealthy_from_the_first_message_on_is_no_latched_failsafe():
    h = Health()
    h.sys_status(ALL, ALL, ALL & ~mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER)  # never had a receiver
    assert h.failsafe_bits == 0
    h.sys_status(ALL, ALL, ALL)
    h.sys_status(ALL, ALL, ALL & ~mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER)  # now it is lost
    assert h.failsafe_bits == mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER


def test_pxs_battery_warning_is_latched_from_battery_status():
    core = connected()
    msg = mavlink.MAVLink_battery_status_message(0, 0, 0, 2500, [12000] + [65535] * 9, 100, 500, -1,
                                                 40, 0, 2, [0, 0, 0, 0], 0, 0)  # charge_state LOW
    core.on_mavlink(wire(msg), at(2 * S))
    st = status(core, 2 * S)
    assert st.failsafe_latched == "battery" and "charge_state" in st.failsafe_latched_detail


def test_a_reboot_ends_the_latched_battery_failsafe():
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 60_000)), at(2 * S))
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(
        4, b"Battery 1 is low 11.00V used 500 mAh", 0, 0)), at(3 * S))
    assert status(core, 3 * S).failsafe_latched == "battery"
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 1_000)), at(4 * S))  # rebooted?
    assert status(core, 4 * S).failsafe_latched == "battery"  # one packet going back is not proof
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 2_000)), at(5 * S))  # its clock runs
    assert status(core, 5 * S).failsafe_latched is None


def test_a_wall_clock_step_keeps_the_latched_battery_failsafe():
    """NTP stepping the companion's wall clock 5 s is not an autopilot reboot: the battery
    failsafe ArduPilot said once stays latched, and the stamps follow the new wall time."""
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(
        4, b"Battery 1 is low 11.00V used 500 mAh", 0, 0)), at(2 * S))
    step = 5 * S
    for k in range(40):  # 4 s of 10 Hz ATTITUDE; the wall clock set 5 s ahead after 1 s
        mono = 3 * S + k * 100 * MS
        now = Now(WALL0 + mono + (step if k >= 10 else 0), mono)
        out = core.on_mavlink(wire(mavlink.MAVLink_attitude_message(
            100_000 + k * 100, 0.0, 0.0, 0.5, 0.0, 0.0, 0.1)), now)
    assert (core.offset.steps, core.offset.resets) == (1, 0)
    assert core.status(now).failsafe_latched == "battery"
    (att,) = [o.message for o in out if type(o.message).__name__ == "Attitude"]
    assert att.stamp_ns == now.wall_ns


def test_pxs_later_causeless_failsafe_text_keeps_the_battery_it_named_before():
    from seaway_vehicle_io.failsafe_cause import FailsafeCause

    cause = FailsafeCause()
    cause.said("battery", "Low battery level, return advised", 0)
    cause.said("other", "Failsafe activated: entering Hold for 5 seconds", 8 * S)  # past the window
    cause.mode_changed("MANUAL", "HOLD", 8 * S + 100 * MS)
    assert cause.cause == "battery", cause
