"""Which failsafe fired, named for the operator (``VehicleStatus.hold_reason``): the texts PX4 1.18
and ArduPilot Rover 4.7 send (taken from their sources and events metadata), SYS_STATUS health
bits, and a mode change vehicle_io did not ask for. Pure logic, and the core driven with real
packed MAVLink messages and time passed in."""

from __future__ import annotations

from typing import Any

import pytest
from seaway.contract.messages import VehicleStatus
from seaway.contract.units import NS_PER_S
from seaway_vehicle_io.commands import MAV_CMD_DO_SET_MODE
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import Now, VehicleIoCore
from seaway_vehicle_io.failsafe_cause import (
    MAV_SYS_STATUS_GEOFENCE,
    MAV_SYS_STATUS_SENSOR_BATTERY,
    MAV_SYS_STATUS_SENSOR_RC_RECEIVER,
    FailsafeCause,
    classify_text,
    cleared_cause,
)
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.thrust import ThrusterLimits

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
LIM = ThrusterLimits(75.0, 75.0, 0.0)
AP_MODES = {"MANUAL": 0, "HOLD": 4, "RTL": 11}
HEALTH = MAV_SYS_STATUS_SENSOR_RC_RECEIVER | MAV_SYS_STATUS_GEOFENCE | MAV_SYS_STATUS_SENSOR_BATTERY


@pytest.mark.parametrize(
    ("text", "cause"),
    [
        # ArduPilot Rover 4.7 (Rover/failsafe.cpp "%s Failsafe", AP_BattMonitor, ekf_check)
        ("Radio Failsafe", "radio_loss"),
        ("GCS Failsafe", "gcs_link_loss"),
        ("Battery 1 is low 11.00V used 500 mAh", "battery"),
        ("Battery 1 is critical 10.50V used 900 mAh", "battery"),
        ("EKF failsafe", "other"),
        ("Radio Failsafe Cleared", None),
        ("PreArm: Battery 1 low voltage failsafe", None),  # an arming check, not a failsafe in force
        ("Failsafe - Continuing Auto Mode", "other"),
        # PX4 1.18 events (all_events.json: commander_failsafe_enter*, commander_rc_lost, ...)
        ("Manual control loss: switching to Hold in 5 seconds", "radio_loss"),
        ("Manual control lost", "radio_loss"),
        ("Manual control lost: switching to Hold", "radio_loss"),  # NAV_RCL_ACT 7
        ("GCS connection loss: switching to Return", "gcs_link_loss"),
        ("Connection to ground control station lost", "gcs_link_loss"),
        ("Low battery level, return advised", "battery"),
        ("Critical battery level: switching to Return", "battery"),
        ("Emergency battery level, land immediately", "battery"),
        ("Geofence violation: approaching or outside geofence", "fence"),
        ("Failsafe activated: switching to Hold", "other"),
        ("Failsafe warning:", None),  # PX4 1.18 SITL, disarmed: a warning with no cause, no action
        ("Failsafe warning: Low battery level", "battery"),
        ("Geofence violation for waypoint 3", None),  # a mission check, not a breach
        ("GCS connection regained", None),
        ("Arming denied: Resolve system health failures first", None),
    ],
)
def test_the_firmware_texts_name_their_cause(text, cause):
    assert classify_text(text) == cause


def test_a_named_failsafe_around_an_unasked_mode_change_is_its_cause_in_either_order():
    before = FailsafeCause()
    before.said("radio_loss", "Radio Failsafe", 0)
    before.mode_changed("MANUAL", "HOLD", 200 * MS)
    assert before.cause == "radio_loss" and "HOLD" in before.detail
    after = FailsafeCause()
    after.mode_changed("MANUAL", "HOLD", 0)
    assert after.cause == "gcs_mode_change"
    after.said("other", "Failsafe activated: switching to Hold", 300 * MS)  # vaguer: kept
    assert after.cause == "gcs_mode_change"
    after.said("battery", "Battery 1 is low 11.00V used 500 mAh", 500 * MS)
    assert after.cause == "battery"
    after.said("other", "EKF failsafe", 600 * MS)  # vaguer than the one standing
    assert after.cause == "battery"


def test_an_unasked_mode_change_with_no_failsafe_said_is_someone_else():
    c = FailsafeCause()
    c.said("battery", "Battery 1 is low", 0)
    assert c.own_mode_accepted() and c.cause is None  # the operator took it back
    c.mode_changed("MANUAL", "HOLD", 60 * S)  # a minute later, nothing said
    assert c.cause == "gcs_mode_change"


def test_a_failsafe_moving_on_by_itself_keeps_its_cause():
    """PX4 holds for COM_FAIL_ACT_T, then takes its action: the second mode change is its own."""
    c = FailsafeCause()
    c.said("battery", "Critical battery level: switching to Return in 5 seconds", 0)
    c.mode_changed("MANUAL", "HOLD", 100 * MS)
    c.mode_changed("HOLD", "RTL", 5100 * MS)
    assert c.cause == "battery" and "RTL" in c.detail


def test_health_bits_name_a_cause_when_they_go_unhealthy_and_hold_it_while_they_stay():
    c = FailsafeCause()
    assert not c.health(HEALTH, HEALTH, HEALTH & ~MAV_SYS_STATUS_SENSOR_RC_RECEIVER, 0)
    assert c.cause is None  # unhealthy from the first message: an RC never fitted
    assert c.health(HEALTH, HEALTH, HEALTH, S) is False
    assert c.health(HEALTH, HEALTH, HEALTH & ~MAV_SYS_STATUS_GEOFENCE, 2 * S)
    assert c.cause == "fence"
    assert not c.own_mode_accepted() and c.cause == "fence"  # still breached
    c.health(HEALTH, HEALTH, HEALTH, 3 * S)
    assert c.own_mode_accepted() and c.cause is None


# -- the core ---------------------------------------------------------------------------------------


def wire(msg: Any) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


def heartbeat(mode: str) -> Any:
    return wire(mavlink.MAVLink_heartbeat_message(11, 3, 1 | 128, AP_MODES[mode], 4, 3))


def sys_status(healthy: int) -> Any:
    return wire(
        mavlink.MAVLink_sys_status_message(HEALTH, HEALTH, healthy, 0, 12000, 0, 100, 0, 0, 0, 0, 0, 0)
    )


def connected() -> VehicleIoCore:
    core = VehicleIoCore(
        VehicleIoConfig(autopilot="auto", check_failsafe_params=False, message_rates_hz={}), LIM, at(0)
    )
    core.on_mavlink(heartbeat("MANUAL"), at(0))
    core.on_mavlink(heartbeat("MANUAL"), at(S))
    core.on_mavlink(sys_status(HEALTH), at(S))
    return core


def status(core: VehicleIoCore, t_ns: int) -> VehicleStatus:
    st = core.status(at(t_ns))
    return VehicleStatus.decode(st.encode())  # what the operator's page reads


def test_a_mode_change_from_a_second_ground_station_is_named_and_logged(caplog):
    core = connected()
    core.on_mavlink(heartbeat("HOLD"), at(2 * S))
    st = status(core, 2 * S)
    assert st.mode == "HOLD" and st.hold_reason == "gcs_mode_change"
    assert any(r.levelname == "WARNING" and "gcs_mode_change" in r.getMessage() for r in caplog.records)


def test_seaways_own_mode_change_is_no_hold_and_clears_one():
    core = connected()
    core.on_mavlink(heartbeat("HOLD"), at(2 * S))
    assert not isinstance(core.mode_command("MANUAL"), str)
    core.on_mavlink(heartbeat("MANUAL"), at(3 * S))  # its HEARTBEAT before its ACK
    assert status(core, 3 * S).hold_reason == "gcs_mode_change"  # not cleared before the ACK
    core.command_accepted(MAV_CMD_DO_SET_MODE, (1.0, 0.0, 0.0), "MANUAL")
    assert status(core, 3 * S).hold_reason is None
    assert not isinstance(core.mode_command("HOLD"), str)
    core.on_mavlink(heartbeat("HOLD"), at(4 * S))  # asked by Seaway: nobody else's doing
    assert status(core, 4 * S).hold_reason is None


def test_ardupilots_radio_failsafe_text_names_the_hold():
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(4, b"Radio Failsafe", 0, 0)), at(2 * S))
    core.on_mavlink(heartbeat("HOLD"), at(2100 * MS))
    st = status(core, 2100 * MS)
    assert st.hold_reason == "radio_loss" and "Radio Failsafe" in st.hold_reason_detail


def test_ardupilots_silent_fence_breach_is_named_from_sys_status():
    core = connected()
    core.on_mavlink(sys_status(HEALTH & ~MAV_SYS_STATUS_GEOFENCE), at(2 * S))
    core.on_mavlink(heartbeat("HOLD"), at(2200 * MS))
    assert status(core, 2200 * MS).hold_reason == "fence"


def test_a_low_battery_text_without_a_mode_change_is_shown_too():
    core = connected()
    core.on_mavlink(
        wire(mavlink.MAVLink_statustext_message(4, b"Battery 1 is low 11.00V used 500 mAh", 0, 0)), at(2 * S)
    )
    assert status(core, 2 * S).hold_reason == "battery"


def test_a_second_station_returning_to_seaways_last_mode_is_still_someone_else():
    core = connected()
    assert not isinstance(core.mode_command("HOLD"), str)
    core.command_accepted(MAV_CMD_DO_SET_MODE, (1.0, 4.0, 0.0), "HOLD")
    core.on_mavlink(heartbeat("HOLD"), at(2 * S))
    assert status(core, 2 * S).hold_reason is None  # Seaway's own
    core.on_mavlink(heartbeat("MANUAL"), at(3 * S))
    core.on_mavlink(heartbeat("HOLD"), at(4 * S))  # HOLD again, but Seaway did not ask this time
    st = status(core, 4 * S)
    assert st.hold_reason == "gcs_mode_change" and "MANUAL -> HOLD" in st.hold_reason_detail


@pytest.mark.parametrize(("text", "cause"), [
    ("GCS Failsafe Cleared", "gcs_link_loss"),  # Rover/failsafe.cpp "%s Failsafe Cleared", at INFO
    ("Radio Failsafe Cleared", "radio_loss"),
    ("GCS Failsafe", None),  # in force: classify_text's
    ("Battery 1 is low 11.00V used 500 mAh", None),
])
def test_a_cleared_text_names_the_failsafe_that_had_fired(text, cause):
    assert cleared_cause(text) == cause


def lose_the_link(core: VehicleIoCore, t_ns: int) -> None:
    core.tick(at(t_ns))
    assert not status(core, t_ns).link_ok


def test_a_hold_made_while_the_link_was_down_is_named_when_it_comes_back():
    """Issue 63: a 10 s radio fade on ArduPilot SITL with FS_GCS_ENABLE. Its "GCS Failsafe" text
    went out while nothing reached vehicle_io; the link came back in HOLD with no cause (before: no
    hold_reason at all, the operator saw a plain 'mode HOLD'). The mode change is seen across the
    loss, and the INFO "GCS Failsafe Cleared" that follows names it."""
    core = connected()
    lose_the_link(core, 5 * S)
    core.on_mavlink(heartbeat("HOLD"), at(12 * S))
    st = status(core, 12 * S)
    assert st.link_ok and st.hold_reason == "other" and "MANUAL -> HOLD" in st.hold_reason_detail
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(6, b"GCS Failsafe Cleared", 0, 0)),
                    at(12500 * MS))
    st = status(core, 12500 * MS)
    assert st.hold_reason == "gcs_link_loss" and "GCS Failsafe Cleared" in st.hold_reason_detail


def test_a_cleared_text_alone_names_no_hold_and_a_reboot_is_no_mode_change():
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(6, b"GCS Failsafe Cleared", 0, 0)), at(2 * S))
    assert status(core, 2 * S).hold_reason is None  # the mode is still Seaway's
    lose_the_link(core, 6 * S)
    disarmed_hold = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, AP_MODES["HOLD"], 4, 3))
    core.on_mavlink(disarmed_hold, at(9 * S))  # rebooted: disarmed, in its initial mode
    assert status(core, 9 * S).hold_reason is None


def test_the_cleared_text_may_come_before_the_heartbeat_that_brings_the_link_back():
    """ArduPilot sends "GCS Failsafe Cleared" the moment vehicle_io's HEARTBEAT reaches it, often
    before its own next HEARTBEAT re-locks the link (measured on SITL): it still names the hold."""
    core = connected()
    lose_the_link(core, 5 * S)
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(6, b"GCS Failsafe Cleared", 0, 0)),
                    at(11500 * MS))
    core.on_mavlink(heartbeat("HOLD"), at(12 * S))
    st = status(core, 12 * S)
    assert st.hold_reason == "gcs_link_loss" and "GCS Failsafe Cleared" in st.hold_reason_detail
    assert "MANUAL -> HOLD" in st.hold_reason_detail


def test_a_fast_reboot_is_no_mode_change_and_clears_the_cause():
    """ArduPilot SITL's forced reboot re-executes it in ~3 s: the link never drops, and its first
    HEARTBEATs say INITIALISING. That was named a mode change by someone else (issue 63)."""
    core = connected()
    core.on_mavlink(wire(mavlink.MAVLink_statustext_message(4, b"Radio Failsafe", 0, 0)), at(2 * S))
    core.on_mavlink(heartbeat("HOLD"), at(2100 * MS))
    assert status(core, 2100 * MS).hold_reason == "radio_loss"
    booting = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 16, 3, 3))  # INITIALISING, disarmed
    core.on_mavlink(booting, at(3 * S))
    core.on_mavlink(wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 0, 4, 3)), at(4 * S))  # MANUAL
    st = status(core, 4 * S)
    assert st.link_ok and st.mode == "MANUAL" and st.hold_reason is None, st


def test_px4_giving_the_mode_back_after_an_unheard_failsafe_is_not_someone_else():
    """PX4 SITL, a 10 s fade: the link came back in RTL (its manual-control loss failsafe, unheard),
    then PX4 itself gave MANUAL back once vehicle_io's MANUAL_CONTROL reached it. That second
    change was named gcs_mode_change (issue 63)."""
    core = connected()
    lose_the_link(core, 5 * S)
    core.on_mavlink(heartbeat("RTL"), at(12 * S))
    assert status(core, 12 * S).hold_reason == "other"
    core.on_mavlink(heartbeat("MANUAL"), at(13 * S))
    st = status(core, 13 * S)
    assert st.hold_reason == "other" and "RTL -> MANUAL" in st.hold_reason_detail, st


PX4_MODES = {"MANUAL": 1 << 16, "HOLD": (4 << 16) | (3 << 24)}  # main << 16 | sub << 24


def px4_heartbeat(mode: str, armed: bool) -> Any:
    return wire(mavlink.MAVLink_heartbeat_message(10, 12, 1 | (128 if armed else 0), PX4_MODES[mode], 4, 3))


def system_time(time_boot_ms: int, t_ns: int) -> Any:
    return wire(mavlink.MAVLink_system_time_message((WALL0 + t_ns) // 1000, time_boot_ms))


def px4_armed_in_manual() -> VehicleIoCore:
    core = VehicleIoCore(
        VehicleIoConfig(autopilot="auto", check_failsafe_params=False, message_rates_hz={}), LIM, at(0)
    )
    core.on_mavlink(px4_heartbeat("MANUAL", armed=True), at(0))
    core.on_mavlink(system_time(600_000, S), at(S))
    core.on_mavlink(px4_heartbeat("MANUAL", armed=True), at(S))
    return core


def test_px4_back_from_a_kill_faster_than_the_link_timeout_is_nobodys_mode_change():
    """PX4 SITL SIGKILLed mid-mission and started again: it was back within the 3 s link timeout,
    its first HEARTBEAT disarmed and in the Hold it boots into. That was named gcs_mode_change
    (mode MANUAL -> HOLD, not asked by Seaway) in the operator's pause reason (issue 63)."""
    core = px4_armed_in_manual()
    core.on_mavlink(px4_heartbeat("HOLD", armed=False), at(2500 * MS))
    st = status(core, 2500 * MS)
    assert st.link_ok and not st.armed and st.mode == "HOLD"
    assert st.hold_reason is None, st
    core.on_mavlink(system_time(900, 3 * S), at(3 * S))  # its clock restarted: it rebooted
    assert status(core, 3 * S).hold_reason is None


def test_a_reboot_without_a_link_loss_forgets_the_standing_cause():
    core = px4_armed_in_manual()
    core.on_mavlink(px4_heartbeat("HOLD", armed=True), at(2 * S))
    assert status(core, 2 * S).hold_reason == "gcs_mode_change"
    core.on_mavlink(px4_heartbeat("HOLD", armed=False), at(3 * S))
    core.on_mavlink(system_time(900, 3100 * MS), at(3100 * MS))  # its clock restarted
    core.on_mavlink(system_time(1900, 4100 * MS), at(4100 * MS))  # and runs on: a reboot
    st = status(core, 4100 * MS)
    assert st.hold_reason is None and st.hold_reason_detail == "", st


def test_px4_moving_to_its_start_up_mode_after_the_link_comes_back_is_nobodys_mode_change():
    """The same kill, slower than the link timeout: the link comes back disarmed in MANUAL, then
    PX4 settles in Hold by itself."""
    core = px4_armed_in_manual()
    lose_the_link(core, 5 * S)
    core.on_mavlink(px4_heartbeat("MANUAL", armed=False), at(8 * S))
    core.on_mavlink(px4_heartbeat("HOLD", armed=False), at(9 * S))
    st = status(core, 9 * S)
    assert st.link_ok and st.mode == "HOLD" and st.hold_reason is None, st
