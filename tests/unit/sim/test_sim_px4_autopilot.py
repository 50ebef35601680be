"""The simulated PX4's state machine, with time passed in: arming, modes, failsafe, params, garbage."""

from __future__ import annotations

import math
import struct

import pytest
from pymavlink.dialects.v20 import common as ml
from seaway.contract.config import Origin
from seaway.contract.units import NS_PER_S
from seaway.simkit.sensors import origin_of
from seaway_sim import px4_params
from seaway_sim.battery import NOMINAL_PACK, SimPack
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config
from seaway_sim.px4_wire import HOLD, MANUAL, RTL, custom_mode

MS = 1_000_000
S = NS_PER_S
GCS = ml.MAVLink(None, 255, 190)  # the sender: src ids for the ACK's target fields


def rx(msg):
    """The message as the sim would receive it: packed and parsed (so header fields are set)."""
    parser = ml.MAVLink(None)
    return parser.parse_buffer(msg.pack(GCS))[0]


def manual(y: int = 0, z: int = 500, x: int = 0, r: int = 0, target: int = 1):
    return rx(ml.MAVLink_manual_control_message(target, x, y, z, r, 0))


def command(cmd: int, *params: float, target: int = 1):
    p = list(params) + [0.0] * (7 - len(params))
    return rx(ml.MAVLink_command_long_message(target, 1, cmd, 0, *p))


def arm(ap: Px4Autopilot, now_ns: int, value: float = 1.0, force: float = 0.0) -> int:
    (ack,) = ap.handle(command(ml.MAV_CMD_COMPONENT_ARM_DISARM, value, force), now_ns)
    assert ack.get_type() == "COMMAND_ACK" and ack.command == ml.MAV_CMD_COMPONENT_ARM_DISARM
    assert (ack.target_system, ack.target_component) == (255, 190)
    return ack.result


def set_mode(ap: Px4Autopilot, now_ns: int, main: int, sub: int = 0) -> int:
    (ack,) = ap.handle(command(ml.MAV_CMD_DO_SET_MODE, 1, main, sub), now_ns)
    return ack.result


def armed_driving(y: int = 200, z: int = 900, **params) -> Px4Autopilot:
    """Armed in MANUAL at t = 1 s, streaming (y, z) since t = 0.9 s."""
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0, param_overrides=tuple(params.items())))
    ap.handle(manual(y, z), 900 * MS)
    assert set_mode(ap, 950 * MS, 1) == ml.MAV_RESULT_ACCEPTED
    assert arm(ap, 1 * S) == ml.MAV_RESULT_ACCEPTED
    return ap


def test_boots_disarmed_in_hold_with_zero_thrust_and_px4_heartbeat() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    hb = ap.heartbeat()
    assert (hb.type, hb.autopilot) == (ml.MAV_TYPE_GROUND_ROVER, ml.MAV_AUTOPILOT_PX4)
    # PX4 boots in Hold (AUTO.LOITER), as measured on the 1.18 SITL
    assert hb.custom_mode == 0x03040000 and hb.system_status == ml.MAV_STATE_STANDBY
    assert hb.base_mode & ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED
    ap.handle(manual(0, 1000), 0)
    assert ap.thrust_n(10 * MS) == (0.0, 0.0)  # disarmed: nothing, whatever the sticks say


def test_arming_in_manual_is_refused_without_a_manual_control_stream() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    # Disarmed, MANUAL is taken without manual control (PX4 refuses the arming instead).
    assert set_mode(ap, 0, 1) == ml.MAV_RESULT_ACCEPTED
    assert arm(ap, 1 * S) == ml.MAV_RESULT_TEMPORARILY_REJECTED
    ap.handle(manual(), 1 * S)
    assert arm(ap, 1 * S + 100 * MS) == ml.MAV_RESULT_ACCEPTED
    assert ap.heartbeat().base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED
    assert ap.heartbeat().system_status == ml.MAV_STATE_ACTIVE


def test_arming_after_the_stream_went_stale_is_refused() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    ap.handle(manual(), 0)
    assert set_mode(ap, 0, 1) == ml.MAV_RESULT_ACCEPTED
    assert arm(ap, 501 * MS) == ml.MAV_RESULT_TEMPORARILY_REJECTED


def test_arming_in_hold_needs_no_manual_control_but_manual_then_does() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    assert set_mode(ap, 0, 4, 3) == ml.MAV_RESULT_ACCEPTED
    assert arm(ap, 1 * S) == ml.MAV_RESULT_ACCEPTED  # in Hold: as PX4
    # Armed, a switch to MANUAL without manual control is refused (PX4: TEMPORARILY_REJECTED).
    assert set_mode(ap, 2 * S, 1) == ml.MAV_RESULT_TEMPORARILY_REJECTED
    assert ap.heartbeat().custom_mode == custom_mode(HOLD)
    assert arm(ap, 3 * S, 0.0) == ml.MAV_RESULT_ACCEPTED
    assert set_mode(ap, 3 * S, 1) == ml.MAV_RESULT_ACCEPTED  # disarmed: taken
    assert ap.heartbeat().custom_mode == custom_mode(MANUAL)


def test_thrust_follows_the_px4_mapping_while_armed_in_manual() -> None:
    ap = armed_driving(200, 900)
    assert ap.thrust_n(1 * S + 10 * MS) == pytest.approx((10.0, 6.0))  # L 1.0 port, R 0.6 stbd
    ap.handle(manual(-300, 500), 1100 * MS)
    assert ap.thrust_n(1110 * MS) == pytest.approx((-3.0, 3.0))


def test_loss_failsafe_zeroes_thrust_after_com_rc_loss_t_and_not_before() -> None:
    ap = armed_driving()
    ap.handle(manual(200, 900), 2 * S)  # the last message
    assert ap.thrust_n(2 * S + 500 * MS) == pytest.approx((10.0, 6.0))  # held up to 0.5 s
    assert not ap.in_failsafe()
    assert ap.thrust_n(2 * S + 501 * MS) == (0.0, 0.0)
    assert ap.in_failsafe()
    hb = ap.heartbeat()
    assert hb.system_status == ml.MAV_STATE_CRITICAL
    assert hb.custom_mode == custom_mode(HOLD) == 0x03040000  # Hold first (COM_FAIL_ACT_T)
    assert hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED
    full = SimPack(NOMINAL_PACK, NOMINAL_PACK.energy_j, hotel_power_w=0.0).reading(0.0, 0, 0.0)
    status = ap.sys_status(2 * S + 600 * MS, full, True, 0)
    assert not status.onboard_control_sensors_health & ml.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
    assert status.onboard_control_sensors_present & ml.MAV_SYS_STATUS_SENSOR_RC_RECEIVER


def test_com_rc_loss_t_is_the_parameter_value() -> None:
    ap = armed_driving(COM_RC_LOSS_T=1.5)
    ap.handle(manual(200, 900), 2 * S)
    assert ap.thrust_n(3 * S + 400 * MS) != (0.0, 0.0)
    assert ap.thrust_n(3 * S + 501 * MS) == (0.0, 0.0)


def test_default_action_after_the_hold_delay_is_return_shown_as_rtl() -> None:
    ap = armed_driving()
    ap.handle(manual(200, 900), 2 * S)
    ap.update(2 * S + 600 * MS)
    ap.update(2 * S + 500 * MS + 5 * S)  # COM_FAIL_ACT_T = 5 s after the loss
    assert ap.heartbeat().custom_mode == 0x05040000  # AUTO.RTL
    assert ap.armed and ap.thrust_n(8 * S) == (0.0, 0.0)


def _fix_at(north_m: float, stamp_ns: int = 0):
    from seaway.contract.messages import GnssFix

    lat, lon, _ = HOME.to_geodetic(north_m, 0.0)
    return GnssFix(stamp_ns=stamp_ns, lat_rad=lat, lon_rad=lon, alt_m=0.0, fix_type=3)


HOME = origin_of(Origin())


def _texts(ap: Px4Autopilot, now_ns: int) -> list[tuple[int, str]]:
    pack = SimPack(NOMINAL_PACK, NOMINAL_PACK.energy_j, hotel_power_w=0.0).reading(0.0, 0, 0.0)
    return [(m.severity, m.text) for m in ap.periodic_telemetry(now_ns, now_ns, 0, pack,
                                                                 True, 0)
            if m.get_type() == "STATUSTEXT"]


@pytest.mark.parametrize("disarm_land_s", [2.0, 0.7])
def test_a_return_that_begins_at_home_lands_and_disarms_after_com_disarm_land(
        disarm_land_s: float) -> None:
    # Measured on PX4 1.18 SITL: Hold ~0.7 s after the last MANUAL_CONTROL, Return 5 s later,
    # "Landing detected" with it (the rover is home), "Disarmed by landing" COM_DISARM_LAND later,
    # then the mode shown is the user's again (MANUAL, disarmed).
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0,
                                param_overrides=(("COM_DISARM_LAND", disarm_land_s),)))
    ap.sensor_telemetry([_fix_at(0.0)], [], epoch_ns=0)
    ap.handle(manual(), 900 * MS)
    assert set_mode(ap, 950 * MS, 1) == ml.MAV_RESULT_ACCEPTED
    assert arm(ap, 1 * S) == ml.MAV_RESULT_ACCEPTED  # home: here
    ap.sensor_telemetry([_fix_at(0.3)], [], epoch_ns=0)  # within NAV_ACC_RAD (0.5 m)
    ap.handle(manual(), 2 * S)
    ap.update(2 * S + 501 * MS)
    assert _texts(ap, 2 * S + 501 * MS) == [
        (ml.MAV_SEVERITY_CRITICAL, "Failsafe activated: entering Hold for 5 seconds")]
    ap.update(7 * S + 501 * MS)
    assert ap.heartbeat().custom_mode == custom_mode(RTL) and ap.armed
    assert _texts(ap, 7 * S + 501 * MS) == [(ml.MAV_SEVERITY_CRITICAL, "Failsafe activated"),
                                            (ml.MAV_SEVERITY_INFO, "Landing detected")]
    landed_ns = 7 * S + 501 * MS
    ap.update(landed_ns + round(disarm_land_s * S) - MS)
    assert ap.armed
    ap.update(landed_ns + round(disarm_land_s * S))
    assert not ap.armed and not ap.in_failsafe()
    assert ap.heartbeat().custom_mode == custom_mode(MANUAL)
    assert _texts(ap, 10 * S) == [(ml.MAV_SEVERITY_INFO, "Disarmed by landing")]


def test_a_return_that_begins_away_from_home_stays_in_return_armed() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    ap.sensor_telemetry([_fix_at(0.0)], [], epoch_ns=0)
    ap.handle(manual(), 900 * MS)
    set_mode(ap, 950 * MS, 1)
    assert arm(ap, 1 * S) == ml.MAV_RESULT_ACCEPTED
    ap.sensor_telemetry([_fix_at(0.6)], [], epoch_ns=0)  # beyond NAV_ACC_RAD: the sim cannot drive back
    ap.handle(manual(), 2 * S)
    ap.update(2 * S + 501 * MS)
    ap.update(7 * S + 501 * MS)
    ap.update(60 * S)
    assert ap.armed and ap.heartbeat().custom_mode == custom_mode(RTL)
    assert ap.thrust_n(60 * S) == (0.0, 0.0)


def test_nav_rcl_act_disarm_disarms_after_the_hold_delay() -> None:
    ap = armed_driving(NAV_RCL_ACT=6, COM_FAIL_ACT_T=1.0)
    ap.handle(manual(200, 900), 2 * S)
    ap.update(2 * S + 501 * MS)
    assert ap.armed and ap.in_failsafe()
    ap.update(3 * S + 400 * MS)
    assert ap.armed
    ap.update(3 * S + 502 * MS)
    assert not ap.armed and not ap.in_failsafe()
    assert ap.heartbeat().system_status == ml.MAV_STATE_STANDBY


def test_nav_rcl_act_terminate_latches_until_restart() -> None:
    ap = armed_driving(NAV_RCL_ACT=5, COM_FAIL_ACT_T=0.0)
    ap.handle(manual(200, 900), 2 * S)
    ap.update(2 * S + 501 * MS)
    ap.update(2 * S + 502 * MS)
    assert ap.terminated and ap.heartbeat().system_status == ml.MAV_STATE_FLIGHT_TERMINATION
    ap.handle(manual(200, 900), 3 * S)
    assert arm(ap, 3 * S) == ml.MAV_RESULT_TEMPORARILY_REJECTED
    assert ap.thrust_n(3 * S) == (0.0, 0.0)


def test_regaining_manual_control_ends_a_hold_failsafe() -> None:
    ap = armed_driving()
    ap.handle(manual(200, 900), 2 * S)
    assert ap.thrust_n(2 * S + 600 * MS) == (0.0, 0.0)
    ap.handle(manual(0, 750), 2 * S + 700 * MS)
    assert ap.thrust_n(2 * S + 710 * MS) == pytest.approx((5.0, 5.0))
    assert ap.heartbeat().system_status == ml.MAV_STATE_ACTIVE


def test_no_failsafe_when_armed_while_already_lost_until_manual_control_is_seen() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    assert set_mode(ap, 0, 4, 3) == ml.MAV_RESULT_ACCEPTED  # HOLD needs no manual control
    assert arm(ap, 1 * S) == ml.MAV_RESULT_ACCEPTED
    ap.update(5 * S)
    assert not ap.in_failsafe()  # PX4's _manual_control_lost_at_arming
    ap.handle(manual(), 6 * S)
    ap.update(6 * S + 100 * MS)
    ap.update(7 * S)
    assert ap.in_failsafe()  # seen once, then lost again: the failsafe is live


def test_com_rc_in_mode_disabled_means_no_loss_failsafe() -> None:
    ap = armed_driving()
    ap.params.set("COM_RC_IN_MODE", px4_params.MAV_PARAM_TYPE_INT32, 4)
    ap.update(10 * S)
    assert not ap.in_failsafe()
    assert ap.thrust_n(10 * S) == (0.0, 0.0)  # and no stream: nothing to drive with


def test_com_rc_in_mode_rc_only_ignores_mavlink_manual_control() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0, param_overrides=(("COM_RC_IN_MODE", 0),)))
    ap.handle(manual(), 0)
    assert ap.manual_control_lost(10 * MS)
    assert ap.counters["manual_control_ignored_rc_in_mode"] == 1


def test_hold_mode_gives_zero_thrust_and_manual_needs_the_stream() -> None:
    ap = armed_driving()
    assert set_mode(ap, 1100 * MS, 4, 3) == ml.MAV_RESULT_ACCEPTED
    assert ap.heartbeat().custom_mode == 0x03040000
    assert ap.thrust_n(1110 * MS) == (0.0, 0.0)
    # Back to MANUAL, armed, with the stream stale: refused, as PX4 refuses (measured).
    assert set_mode(ap, 3 * S, 1) == ml.MAV_RESULT_TEMPORARILY_REJECTED


@pytest.mark.parametrize(("main", "sub"), [(2, 0), (3, 0), (5, 0), (6, 0), (7, 0), (4, 4), (4, 5)])
def test_modes_not_simulated_are_temporarily_rejected(main: int, sub: int) -> None:
    ap = armed_driving()
    assert set_mode(ap, 1100 * MS, main, sub) == ml.MAV_RESULT_TEMPORARILY_REJECTED
    assert ap.heartbeat().custom_mode == custom_mode(MANUAL)


def test_disarm_is_accepted_and_zeroes_thrust_and_bad_arm_values_are_denied() -> None:
    ap = armed_driving()
    assert arm(ap, 1100 * MS, value=0.5) == ml.MAV_RESULT_ACCEPTED  # lroundf(0.5) = 1: arm, a no-op
    assert ap.armed
    assert arm(ap, 1100 * MS, value=3.0) == ml.MAV_RESULT_DENIED
    assert ap.armed
    assert arm(ap, 1100 * MS, value=0.0, force=21196) == ml.MAV_RESULT_ACCEPTED
    assert not ap.armed and ap.thrust_n(1110 * MS) == (0.0, 0.0)


def test_out_of_range_manual_control_is_rejected_whole_and_counted() -> None:
    ap = armed_driving(200, 900)
    for bad in (manual(1500, 900), manual(0, 2000), manual(0, 900, x=-1001), manual(0, 900, r=5000)):
        assert ap.handle(bad, 1100 * MS) == []
    assert ap.counters["manual_control_out_of_range"] == 4
    assert ap.last_manual_ns == 900 * MS  # rejected messages do not feed the loss timer
    assert ap.thrust_n(1110 * MS) == pytest.approx((10.0, 6.0))


def test_negative_z_is_throttle_zero_as_in_px4() -> None:
    ap = armed_driving()
    ap.handle(manual(0, -400), 1100 * MS)
    assert ap.counters["manual_control_z_negative"] == 1
    assert ap.thrust_n(1110 * MS) == (0.0, 0.0)


def test_messages_for_another_system_are_ignored() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    ap.handle(manual(target=7), 0)
    assert ap.manual_control_lost(1 * MS)
    assert ap.handle(command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1, target=7), 0) == []


def test_non_finite_command_params_are_dropped_without_ack() -> None:
    ap = armed_driving()
    assert ap.handle(command(ml.MAV_CMD_COMPONENT_ARM_DISARM, math.nan), 1100 * MS) == []
    assert ap.handle(command(ml.MAV_CMD_DO_SET_MODE, 1, math.inf), 1100 * MS) == []
    assert ap.counters["command_garbage_fields"] == 2 and ap.armed


def test_unknown_commands_are_unsupported_and_version_is_px4_bytewise() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    (ack,) = ap.handle(command(ml.MAV_CMD_NAV_TAKEOFF), 0)
    assert ack.result == ml.MAV_RESULT_UNSUPPORTED
    ack, version = ap.handle(command(ml.MAV_CMD_REQUEST_MESSAGE,
                                     ml.MAVLINK_MSG_ID_AUTOPILOT_VERSION), 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    assert version.capabilities & ml.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    assert version.flight_sw_version >> 24 == 1


def decode(pv) -> float | int:
    return px4_params.decode_value(pv.param_type, pv.param_value)


def test_param_read_by_name_and_index_with_px4_defaults_bytewise() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    (pv,) = ap.handle(rx(ml.MAVLink_param_request_read_message(1, 1, b"COM_RC_LOSS_T", -1)), 0)
    assert (pv.param_id, pv.param_type, decode(pv)) == ("COM_RC_LOSS_T", 9, 0.5)
    (pv,) = ap.handle(rx(ml.MAVLink_param_request_read_message(1, 1, b"NAV_RCL_ACT", -1)), 0)
    assert pv.param_type == px4_params.MAV_PARAM_TYPE_INT32 and decode(pv) == 2
    # Bytewise: the float's four bytes are the int32's.
    assert struct.pack("<f", pv.param_value) == struct.pack("<i", 2)
    (pv,) = ap.handle(rx(ml.MAVLink_param_request_read_message(1, 1, b"", 0)), 0)
    assert pv.param_id == "COM_RC_IN_MODE" and decode(pv) == 3 and pv.param_index == 0
    assert ap.handle(rx(ml.MAVLink_param_request_read_message(1, 1, b"NO_SUCH", -1)), 0) == []


def test_param_list_has_every_failsafe_param_vehicle_io_checks() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    answers = ap.handle(rx(ml.MAVLink_param_request_list_message(1, 1)), 0)
    values = {pv.param_id: decode(pv) for pv in answers}
    # Types as the 1.18 SITL reports them (COM_DL_LOSS_T is an INT32 there).
    assert {pv.param_id for pv in answers if pv.param_type == px4_params.MAV_PARAM_TYPE_REAL32} \
        == {"COM_RC_LOSS_T", "COM_FAIL_ACT_T", "COM_OF_LOSS_T", "COM_DISARM_LAND", "NAV_ACC_RAD",
            "RO_ACCEL_LIM", "RO_DECEL_LIM", "RO_MAX_THR_SPEED", "RD_YAW_STK_GAIN"}
    assert values == {"COM_RC_IN_MODE": 3, "COM_RC_LOSS_T": 0.5, "NAV_RCL_ACT": 2,
                      "COM_RCL_EXCEPT": 0, "COM_FAIL_ACT_T": 5.0, "NAV_DLL_ACT": 0,
                      "COM_DL_LOSS_T": 10, "COM_OF_LOSS_T": 1.0, "COM_OBL_RC_ACT": 0,
                      "COM_DISARM_LAND": 2.0, "NAV_ACC_RAD": 0.5,
                      "MAV_TYPE": 10, "MAV_SYS_ID": 1, "CA_AIRFRAME": 6, "CA_R_REV": 3,
                      "RO_ACCEL_LIM": -1.0, "RO_DECEL_LIM": -1.0, "RO_MAX_THR_SPEED": -1.0,
                      "GF_ACTION": 2, "GF_SOURCE": 0, "RD_YAW_STK_GAIN": 1.0}


def test_param_set_echoes_the_new_value_and_refuses_bad_ones() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    wire = px4_params.encode_value(px4_params.BY_NAME["NAV_RCL_ACT"], 6)
    (pv,) = ap.handle(rx(ml.MAVLink_param_set_message(1, 1, b"NAV_RCL_ACT", wire, 6)), 0)
    assert decode(pv) == 6 and ap.params.get("NAV_RCL_ACT") == 6
    for bad in (ml.MAVLink_param_set_message(1, 1, b"COM_RC_LOSS_T", math.nan, 9),
                ml.MAVLink_param_set_message(1, 1, b"COM_RC_LOSS_T", 99.0, 9),
                ml.MAVLink_param_set_message(1, 1, b"COM_RC_LOSS_T", 1.0, 6),
                ml.MAVLink_param_set_message(1, 1, b"NOPE", 1.0, 9)):
        assert ap.handle(rx(bad), 0) == []
    assert ap.params.get("COM_RC_LOSS_T") == 0.5


def test_periodic_telemetry_and_battery_drain() -> None:
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    pack = SimPack(NOMINAL_PACK, NOMINAL_PACK.energy_j, hotel_power_w=0.0)
    full = pack.reading(0.0, 0, 0.0)
    kinds = [m.get_type() for m in ap.periodic_telemetry(999 * MS, 1 * S, 0, full, True, 0)]
    assert kinds == ["HEARTBEAT", "SYS_STATUS", "BATTERY_STATUS", "SYSTEM_TIME"]
    assert ap.periodic_telemetry(1 * S, 1090 * MS, 0, full, True, 0) == []
    half = pack.reading(NOMINAL_PACK.energy_j / 2, 0, 148.0)
    full_msg, used = ap.battery_status(full), ap.battery_status(half)
    assert (full_msg.voltages[0], full_msg.battery_remaining) == (16800, 100)
    assert abs(used.voltages[0] - 15000) <= 1 and used.battery_remaining == 50
    assert used.current_battery == int(148.0 / 15.0 * 100)  # cA, truncated as PX4
    assert abs(used.current_consumed - 5000) <= 1  # mAh: half of 10 Ah
    status = ap.sys_status(0, half, False, 7)
    assert (status.battery_remaining, status.errors_comm) == (50, 7)
    assert abs(status.voltage_battery - 15000) <= 1
    assert not status.onboard_control_sensors_health & ml.MAV_SYS_STATUS_SENSOR_GPS


def test_each_fix_goes_out_as_gps_raw_int_then_global_position_int() -> None:
    from seaway.contract.messages import GnssFix

    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    fix = GnssFix(stamp_ns=1_200 * MS, lat_rad=math.radians(47.0), lon_rad=math.radians(8.0),
                  alt_m=3.0, fix_type=3, vel_n_mps=0.3, vel_e_mps=0.4, horizontal_std_m=0.3,
                  satellites=12)
    out = ap.sensor_telemetry([fix, None], [], epoch_ns=200 * MS)
    assert [m.get_type() for m in out] == ["GPS_RAW_INT", "GLOBAL_POSITION_INT"]
    raw, pos = (rx(m) for m in out)
    assert (raw.fix_type, raw.satellites_visible, raw.h_acc) == (3, 12, 300)
    assert raw.time_usec == 1_000_000 and pos.time_boot_ms == 1000  # since boot = stamp - epoch
    assert (raw.lat, raw.lon) == (pos.lat, pos.lon) == (470000000, 80000000)
    assert raw.vel == 50 and raw.cog == round(math.degrees(math.atan2(0.4, 0.3)) * 100)


def test_boot_parameters_from_the_command_line() -> None:
    from seaway_sim.main import parse_params

    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0,
                                param_overrides=parse_params(["NAV_RCL_ACT=1", "COM_RC_LOSS_T=0.3"])))
    assert (ap.params.get("NAV_RCL_ACT"), ap.params.get("COM_RC_LOSS_T")) == (1, 0.3)
    with pytest.raises(ValueError, match="unknown parameter 'BOGUS'"):
        Px4Autopilot(Px4Config(thrust_max_n=10.0, param_overrides=parse_params(["BOGUS=1"])))
    with pytest.raises(ValueError, match=r"NAV_RCL_ACT: 9(\.0)? outside \[1, 6\]"):
        Px4Autopilot(Px4Config(thrust_max_n=10.0, param_overrides=parse_params(["NAV_RCL_ACT=9"])))
    with pytest.raises(ValueError, match="NAME=VALUE"):
        parse_params(["NAV_RCL_ACT"])


def test_set_message_interval_thins_a_stream_as_px4_takes_it() -> None:
    """PX4 ACCEPTs SET_MESSAGE_INTERVAL for its telemetry and FAILs it for HEARTBEAT (1.18 SITL);
    the sim thins its stream to the interval, turns it off at -1 and back to its rate at 0."""
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    interval = ml.MAV_CMD_SET_MESSAGE_INTERVAL
    gpi = ml.MAVLINK_MSG_ID_GLOBAL_POSITION_INT

    def count(kind: str, seconds: int) -> int:
        n = 0
        for k in range(seconds * 10):  # the sim's fixes at 10 Hz
            n += sum(m.get_type() == kind for m in ap.sensor_telemetry(
                [_fix_at(0.0, stamp_ns=k * 100 * MS)], [], epoch_ns=0))
        return n

    assert count("GLOBAL_POSITION_INT", 2) == 20
    (ack,) = ap.handle(command(interval, gpi, 200_000), 0)  # 5 Hz
    assert ack.result == ml.MAV_RESULT_ACCEPTED
    assert count("GLOBAL_POSITION_INT", 2) == 10 and count("GPS_RAW_INT", 2) == 20
    (ack,) = ap.handle(command(interval, gpi, -1), 0)
    assert ack.result == ml.MAV_RESULT_ACCEPTED and count("GLOBAL_POSITION_INT", 1) == 0
    ap.handle(command(interval, gpi, 0), 0)
    assert count("GLOBAL_POSITION_INT", 1) == 10
    (ack,) = ap.handle(command(interval, ml.MAVLINK_MSG_ID_HEARTBEAT, 1e6), 0)
    assert ack.result == ml.MAV_RESULT_FAILED


def test_no_message_carries_an_old_time_after_a_gnss_dropout() -> None:
    """Each message is stamped when its value is made, as PX4's streams are: within a tick of being
    sent. Before, LOCAL_POSITION_NED repeated the last fix with its own stamp once the dropout
    ended and before the next fix came: a message 5 s old, which vehicle_io took for a reboot."""
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    pack = SimPack(NOMINAL_PACK, NOMINAL_PACK.energy_j, hotel_power_w=0.0).reading(0.0, 0, 0.0)
    tick, epoch = 10 * MS, 1_800_000_000 * S
    dropout = (100 * S + 30 * MS, 105 * S + 30 * MS)  # off the fixes' 200 ms grid, as Poisson is
    ages_ms, kinds, system_times = [], set(), []
    for k in range(99 * 100, 107 * 100):
        t = k * tick
        in_dropout = dropout[0] <= t < dropout[1]
        fixes = [_fix_at(0.0, stamp_ns=epoch + t)] if t % (200 * MS) == 0 and not in_dropout else []
        out = ap.sensor_telemetry(fixes, [], epoch, HOME)
        out += ap.periodic_telemetry(t - tick, t, epoch, pack, not in_dropout, 0)
        for m in out:
            m = rx(m)
            if hasattr(m, "time_boot_ms"):
                ages_ms.append(t // MS - m.time_boot_ms)
                kinds.add(m.get_type())
            if m.get_type() == "SYSTEM_TIME":
                system_times.append(m)
    assert {"GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "SYSTEM_TIME"} <= kinds
    assert max(ages_ms) == 0 and min(ages_ms) == 0
    assert len(system_times) == 8  # 1 Hz
    for m in system_times:
        assert m.time_unix_usec == (epoch // 1000) + m.time_boot_ms * 1000
