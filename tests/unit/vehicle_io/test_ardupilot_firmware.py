"""What running against the real ArduPilot firmware needed, as pure logic: the telemetry-rate request
and its check, both names of the GCS system-id parameter, the RC dead-zone compensation and the
STATUSTEXT behind a refused arm. The core is driven with real packed MAVLink messages and time
passed in (the system tests in tests/system/vehicle_io/test_ardupilot_sitl.py run the firmware)."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pytest
from seaway.contract.units import NS_PER_S
from seaway_vehicle_io import rates
from seaway_vehicle_io.ardupilot import PROFILE as AP
from seaway_vehicle_io.ardupilot import RcChannel
from seaway_vehicle_io.autopilot_events import EventCatalog
from seaway_vehicle_io.config import SOURCE_SYSTEM, VehicleIoConfig
from seaway_vehicle_io.core import (
    Now,
    SendCommandLong,
    SendManualControl,
    SendParamRequestRead,
    SendRequestDataStream,
    VehicleIoCore,
)
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.statustext import ID0_HOLD_NS, StatusTexts, matching
from seaway_vehicle_io.thrust import ThrusterLimits, normalise

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
LIM = ThrusterLimits(75.0, 75.0, 0.0)
SITL_RC = {f"RC{ch}_{f}": v for ch in (1, 3)
           for f, v in {"MIN": 1000.0, "TRIM": 1500.0, "MAX": 2000.0, "DZ": 30.0,
                        "REVERSED": 0.0}.items()}
# What Rover 4.7.0-dev SITL answers (motorboat defaults + PILOT_STEER_TYPE 1): no SYSID_MYGCS.
SITL_PARAMS = {"FS_THR_ENABLE": 1.0, "FS_ACTION": 2.0, "FS_TIMEOUT": 1.5, "FS_GCS_ENABLE": 0.0,
               "RC_OVERRIDE_TIME": 3.0, "RC_OPTIONS": 32.0, "PILOT_STEER_TYPE": 1.0,
               "MAV_GCS_SYSID": float(SOURCE_SYSTEM), "FRAME_CLASS": 2.0, "MOT_SLEWRATE": 0.0,
               "MOT_THST_ASYM": 1.0, "RCMAP_ROLL": 1.0, "RCMAP_THROTTLE": 3.0, **SITL_RC}


def wire(msg: Any, sysid: int = 1, compid: int = 1) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


def ardupilot_heartbeat(armed: bool = True) -> Any:
    base = 1 | (128 if armed else 0)
    return wire(mavlink.MAVLink_heartbeat_message(11, 3, base, 0, 4, 3))


def px4_heartbeat() -> Any:
    return wire(mavlink.MAVLink_heartbeat_message(10, 12, 1, 1 << 16, 4, 3))


def ack(command: int, result: int) -> Any:
    return wire(mavlink.MAVLink_command_ack_message(command, result, 0, 0, SOURCE_SYSTEM, 191))


def param_value(name: str, value: float) -> Any:
    return wire(mavlink.MAVLink_param_value_message(name.encode(), value, 9, 1219, 0))


def statustext(text: str, severity: int = 2, text_id: int = 0, seq: int = 0) -> Any:
    return wire(mavlink.MAVLink_statustext_message(severity, text.encode(), text_id, seq))


def attitude(t_ms: int) -> Any:
    return wire(mavlink.MAVLink_attitude_message(t_ms, 0.0, 0.0, 0.5, 0.0, 0.0, 0.1))


def make(**cfg: Any) -> VehicleIoCore:
    return VehicleIoCore(VehicleIoConfig(autopilot="auto", **cfg), LIM, at(0))


def of(outs: list, kind: type) -> list:
    return [o for o in outs if isinstance(o, kind)]


def answer_params(core: VehicleIoCore, params: dict[str, float], t_ns: int) -> None:
    for name, value in params.items():
        core.on_mavlink(param_value(name, value), at(t_ns))


# -- rate planning ----------------------------------------------------------------------------------


def test_rate_plan_asks_each_message_by_id_and_interval():
    plan = rates.plan({"ATTITUDE": 10.0, "GLOBAL_POSITION_INT": 5.0})
    assert [(r.message, r.msg_id) for r in plan] == [("ATTITUDE", 30), ("GLOBAL_POSITION_INT", 33)]
    assert [r.interval_us for r in plan] == pytest.approx([100_000.0, 200_000.0])


@pytest.mark.parametrize(("rates_hz", "named"), [
    ({"HEARTBEAT": 1.0}, "HEARTBEAT"),  # not telemetry vehicle_io uses
    ({"NOT_A_MESSAGE": 1.0}, "NOT_A_MESSAGE"),
    ({"ATTITUDE": 0.0}, "ATTITUDE"),
    ({"ATTITUDE": 500.0}, "ATTITUDE"),
    ({"ATTITUDE": float("nan")}, "ATTITUDE"),
])
def test_rate_plan_refuses_what_it_cannot_ask_for(rates_hz, named):
    with pytest.raises(ValueError, match=named):
        rates.plan(rates_hz)
    with pytest.raises(ValueError, match=named):
        VehicleIoConfig(message_rates_hz=rates_hz)


def test_the_telemetry_that_may_be_asked_for_is_what_the_core_handles():
    assert set(VehicleIoCore._HANDLERS) >= rates.TELEMETRY
    assert set(rates.DEFAULT_RATES_HZ) == rates.TELEMETRY


def test_fallback_streams_take_the_fastest_rate_per_group_rounded_up():
    plan = rates.plan({"GLOBAL_POSITION_INT": 5.0, "LOCAL_POSITION_NED": 2.5, "ATTITUDE": 9.5,
                       "SYS_STATUS": 1.0, "GPS_RAW_INT": 5.0})
    assert rates.fallback_streams(plan, AP.data_streams) == {6: 5, 10: 10, 2: 5}


def test_shortfalls_name_the_slow_messages_with_their_measured_rate():
    plan = rates.plan({"ATTITUDE": 10.0, "GLOBAL_POSITION_INT": 5.0, "SYS_STATUS": 1.0})
    counts = {"ATTITUDE": 25, "GLOBAL_POSITION_INT": 3, "SYS_STATUS": 2}  # over 2.5 s
    assert rates.shortfalls(plan, counts, 2.5) == {"GLOBAL_POSITION_INT": 1.2}
    assert rates.shortfalls(plan, {"ATTITUDE": 20, "GLOBAL_POSITION_INT": 10, "SYS_STATUS": 2},
                            2.5) == {}  # 80 % of the rate is at the rate
    assert rates.shortfalls(plan, {"ATTITUDE": 19, "GLOBAL_POSITION_INT": 10, "SYS_STATUS": 1},
                            2.5) == {"ATTITUDE": 7.6, "SYS_STATUS": 0.4}


# -- the rate request and check in the core -------------------------------------------------------


def rate_commands(outs: list) -> list[SendCommandLong]:
    return [o for o in of(outs, SendCommandLong) if o.command == rates.MAV_CMD_SET_MESSAGE_INTERVAL]


def feed(core: VehicleIoCore, start_ns: int, end_ns: int, hz: dict[str, float]) -> None:
    """ATTITUDE and SYS_STATUS as the autopilot would stream them at ``hz``."""
    for name, rate in hz.items():
        step = round(S / rate)
        for t in range(start_ns, end_ns, step):
            msg = attitude(t // MS) if name == "ATTITUDE" else wire(
                mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 12000, 0, 100, 0, 0, 0, 0, 0, 0))
            core.on_mavlink(msg, at(t))


def test_ardupilot_connection_requests_rates_and_the_check_reports_the_slow_ones():
    core = make(message_rates_hz={"ATTITUDE": 10.0, "SYS_STATUS": 2.0})
    outs = core.on_mavlink(ardupilot_heartbeat(), at(0))
    asked = rate_commands(outs)
    assert sorted((c.params[0], c.params[1]) for c in asked) == [(1.0, 500_000.0), (30.0, 100_000.0)]
    for _ in asked:
        core.on_mavlink(ack(rates.MAV_CMD_SET_MESSAGE_INTERVAL, 0), at(20 * MS))
    core.tick(at(30 * MS))
    assert core.rate_check.phase == "measuring" and not core.rate_check.fallback_used
    feed(core, 0, 3500 * MS, {"ATTITUDE": 10.0, "SYS_STATUS": 1.0})  # SYS_STATUS stayed at 1 Hz
    for t in (1 * S, 2 * S, 3 * S):
        core.on_mavlink(ardupilot_heartbeat(), at(t))
    assert core.status(at(2 * S)).telemetry_rates_short is None  # not decided yet
    assert core.next_wake_ns() <= core.rate_check.window_end_ns()
    core.tick(at(3100 * MS))
    assert core.rate_check.phase == "done"
    assert core.status(at(3100 * MS)).telemetry_rates_short == {"SYS_STATUS": 1.2}


def test_refused_interval_falls_back_to_stream_rates():
    core = make(message_rates_hz={"ATTITUDE": 10.0, "GLOBAL_POSITION_INT": 5.0})
    core.on_mavlink(ardupilot_heartbeat(), at(0))
    core.on_mavlink(ack(rates.MAV_CMD_SET_MESSAGE_INTERVAL, 3), at(10 * MS))  # UNSUPPORTED
    streams = of(core.tick(at(20 * MS)), SendRequestDataStream)
    assert sorted((s.stream_id, s.rate_hz) for s in streams) == [(6, 5), (10, 10)]
    assert core.rate_check.fallback_used


def test_unanswered_interval_falls_back_after_the_ack_timeout():
    core = make(message_rates_hz={"ATTITUDE": 10.0})
    core.on_mavlink(ardupilot_heartbeat(), at(0))
    assert not of(core.tick(at(900 * MS)), SendRequestDataStream)
    assert core.next_wake_ns() <= round(rates.ACK_TIMEOUT_S * S)
    assert [s.stream_id for s in of(core.tick(at(1 * S)), SendRequestDataStream)] == [10]


def test_px4_is_asked_for_rates_and_has_no_stream_fallback():
    """PX4's links stream at their mode's rates (a radio's "Normal" mode sends GPS_RAW_INT at
    1 Hz), so PX4 is asked too; it takes SET_MESSAGE_INTERVAL and has no REQUEST_DATA_STREAM."""
    core = make()
    asked = rate_commands(core.on_mavlink(px4_heartbeat(), at(0)))
    assert {round(c.params[0]) for c in asked} == {
        getattr(mavlink, f"MAVLINK_MSG_ID_{m}") for m in rates.DEFAULT_RATES_HZ}
    out = core.tick(at(int(rates.ACK_TIMEOUT_S * S) + MS))  # no ACK at all: no fallback to send
    assert not [o for o in out if type(o).__name__ == "SendRequestDataStream"]


# -- both names of the GCS system id, verdict without waiting ---------------------------------------


def test_gcs_sysid_is_asked_under_both_names_and_the_check_ends_on_the_first_answers():
    core = make(message_rates_hz={})
    outs = core.on_mavlink(ardupilot_heartbeat(), at(0))
    asked = [o.param_id for o in of(outs, SendParamRequestRead)]
    assert "MAV_GCS_SYSID" in asked and "SYSID_MYGCS" in asked
    answer_params(core, SITL_PARAMS, 50 * MS)  # 4.7 answers MAV_GCS_SYSID only
    assert core.params.done  # at once: nothing left waiting for SYSID_MYGCS
    assert core.params.values["SYSID_MYGCS"] == SOURCE_SYSTEM
    assert core.params.answered_as["SYSID_MYGCS"] == "MAV_GCS_SYSID"
    assert core.status(at(60 * MS)).autopilot_loss_failsafe is not None
    assert not of(core.tick(at(1100 * MS)), SendParamRequestRead)  # nothing asked again


def test_a_wrong_gcs_sysid_under_the_new_name_is_warned():
    params = {**SITL_PARAMS, "SYSID_MYGCS": 254.0}
    del params["MAV_GCS_SYSID"]
    a = AP.assess_failsafe(params, 255, "present")
    assert any("254" in w for w in a.warnings)


# -- RC dead zone ---------------------------------------------------------------------------------------


FORCES_N = [-75.0, -40.0, -12.0, -5.0, 5.0, 8.0, 12.0, 20.0, 40.0, 60.0, 75.0]


@pytest.mark.parametrize("force_n", FORCES_N)
def test_dead_zone_compensated_force_within_3_percent(force_n):
    """The force ArduPilot reconstructs from our axis value, with the SITL's 30 us dead zone."""
    mapper = AP.mapper(SITL_RC)
    u = normalise(force_n, LIM, AP.quantisation_guard)
    axes = mapper(u, u)
    for cal, value in ((RcChannel.from_params(SITL_RC, 1), axes.y),
                       (RcChannel.from_params(SITL_RC, 3), axes.z)):
        out_n = cal.norm_input_dz(value) * 75.0
        assert out_n == pytest.approx(force_n, rel=0.03, abs=0.0)


def test_without_compensation_small_forces_came_out_a_third_low():
    """The fault seen on the firmware (issue #19): the plain mapping through a 30 us dead zone."""
    cal = RcChannel.from_params(SITL_RC, 3)
    plain = AP.manual_control(12.0 / 75.0, 12.0 / 75.0).z
    assert cal.norm_input_dz(plain) * 75.0 == pytest.approx(12.0 * 0.66, rel=0.02)


@pytest.mark.parametrize("cal", [
    RcChannel(1000, 1500, 2000, 30),
    RcChannel(1100, 1500, 1900, 30),  # ArduPilot's defaults
    RcChannel(982, 1494, 2006, 45),  # a real transmitter: trim off-centre
    RcChannel(1000, 1500, 2000, 30, reversed=True),
    RcChannel(1000, 1500, 2000, 0),
], ids=["sitl", "defaults", "off-centre", "reversed", "no-dz"])
def test_override_inverts_the_firmware_arithmetic_everywhere(cal):
    span_us = min(cal.max_us - cal.trim_us, cal.trim_us - cal.min_us) - cal.dead_zone_us
    for n in np.linspace(-1.0, 1.0, 401):
        got = cal.norm_input_dz(cal.override_value(float(n)))
        assert got == pytest.approx(n, abs=1.01 / span_us), n  # to 1 us of PWM
        assert (got == 0.0) == (n == 0.0)  # never lost in the dead zone, neutral exact


def test_plain_calibration_gives_the_plain_mapping():
    cal = RcChannel(1000, 1500, 2000, 0)
    assert [cal.override_value(n) for n in (-1.0, -0.123, 0.0, 0.5, 1.0)] == [-1000, -123, 0, 500,
                                                                              1000]


def test_an_impossible_calibration_is_refused_naming_it():
    with pytest.raises(ValueError, match="dead zone 600"):
        RcChannel(1000, 1500, 2000, 600)


def test_thrust_waits_for_the_calibration_then_is_compensated():
    from seaway.contract.messages import ThrustCommand

    core = make(message_rates_hz={})
    core.on_mavlink(ardupilot_heartbeat(armed=True), at(0))
    cmd = ThrustCommand.make(stamp_ns=WALL0, thrust_port_n=12.0, thrust_starboard_n=12.0)
    (mc,) = of(core.on_thrust(cmd, at(10 * MS)), SendManualControl)
    assert mc.neutral  # the RC calibration is not known yet
    answer_params(core, SITL_PARAMS, 20 * MS)
    (mc,) = of(core.on_thrust(cmd, at(30 * MS)), SendManualControl)
    cal = RcChannel.from_params(SITL_RC, 3)
    assert cal.norm_input_dz(mc.axes.z) * 75.0 == pytest.approx(12.0, rel=0.03)
    assert mc.axes.z > AP.manual_control(0.16, 0.16).z  # pushed past the dead zone


# -- STATUSTEXT ---------------------------------------------------------------------------------------


def test_statustext_matching_and_chunks():
    texts = StatusTexts()
    texts.add(6, "EKF3 IMU0 origin set", 0)
    texts.add(2, b"PreArm: EKF3 waiting for GPS config data\x00\x00", 10)
    first = "PreArm: a reason long enough to need two chunks of"
    assert texts.add(2, first[:50], 20, text_id=7, chunk_seq=0) == []
    (joined,) = texts.add(2, " text", 21, text_id=7, chunk_seq=1)
    assert joined.text == first[:50] + " text"
    texts.add(2, "Arm: Gyros inconsistent", 30)
    texts.add(2, "Arm: Gyros inconsistent", 31)
    assert matching(texts.since(10), ("PreArm:", "Arm:")) == [
        "PreArm: EKF3 waiting for GPS config data", first[:50] + " text",
        "Arm: Gyros inconsistent"]
    assert matching(texts.since(25), ("PreArm:", "Arm:")) == ["Arm: Gyros inconsistent"]
    assert matching(texts.since(0), ("Disarm:",)) == []


PX4_DENIAL = "Arming denied: Resolve system health failures first"  # 51 characters
TAGGED = PX4_DENIAL + "\t"  # as PX4 sends it: the tab says an EVENT says it too


def test_px4s_first_long_text_in_chunks_of_id_0_is_joined():
    """PX4 numbers its texts from 0 on each link, so its first text, when longer than a field,
    comes as chunks of id 0 (the specification's "the only chunk"): it was said in two pieces,
    "... failures firs" and "t" (PX4 1.18 SITL). Held, then joined with its continuation."""
    texts = StatusTexts()
    assert texts.add(2, PX4_DENIAL[:50], 10) == []
    assert [t.text for t in texts.since(0)] == [PX4_DENIAL[:50]]  # a refusal names it at once
    (joined,) = texts.add(2, PX4_DENIAL[50:], 11, chunk_seq=1)
    assert joined.text == PX4_DENIAL and joined.mono_ns == 10
    # PX4's next text has id 1: chunks as the specification has them.
    assert texts.add(2, PX4_DENIAL[:50], 12, text_id=1) == []
    (nxt,) = texts.add(2, PX4_DENIAL[50:], 12, text_id=1, chunk_seq=1)
    assert nxt.text == PX4_DENIAL and [t.text for t in texts.since(0)] == [PX4_DENIAL] * 2


def test_a_full_length_text_of_id_0_alone_is_kept_whole():
    fifty = "x" * 50
    texts = StatusTexts()
    assert texts.add(4, fifty, 10) == []
    # Another text comes: the held one is complete, said first.
    assert [t.text for t in texts.add(6, "next", 20)] == [fifty, "next"]
    # Nothing comes: said once its hold is over, not before.
    assert texts.add(4, fifty, 30) == []
    assert texts.due(30 + ID0_HOLD_NS - 1) == []
    assert [t.text for t in texts.due(30 + ID0_HOLD_NS)] == [fifty]
    assert texts.due(30 + 2 * ID0_HOLD_NS) == []
    # A continuation that does not follow on (a chunk lost) is a text of its own.
    texts.add(4, fifty, 40)
    assert [t.text for t in texts.add(4, "tail", 41, chunk_seq=2)] == [fifty, "tail"]


def test_core_says_px4s_first_long_text_whole_and_its_event_tag_apart(caplog):
    """PX4's first text on a link, in chunks of id 0 ("...failures firs", then "t" and the tab):
    said whole, without the tab. Without PX4's events decoded it is an arming denial, said at INFO
    while the autopilot starts (``test_autopilot_start``); with them it is what the EVENT says
    too, and a debug line (a ground station that decodes events hides it)."""
    core = make(message_rates_hz={})
    core.on_mavlink(px4_heartbeat(), at(0))
    with caplog.at_level(logging.DEBUG, logger="seaway.vehicle_io"):
        core.on_mavlink(statustext(TAGGED[:50], severity=4), at(10 * MS))
        core.on_mavlink(statustext(TAGGED[50:], severity=4, seq=1), at(11 * MS))
    (kept,) = core.texts.since(0)
    assert (kept.text, kept.also_an_event) == (PX4_DENIAL, True)
    said = [r for r in caplog.records if "autopilot says" in r.getMessage()]
    assert [(r.levelno, r.getMessage().endswith(PX4_DENIAL)) for r in said] == [(logging.INFO, True)]
    caplog.clear()
    core.events.tracker.catalog = EVENTS_CATALOG  # its events are decoded from now on
    with caplog.at_level(logging.DEBUG, logger="seaway.vehicle_io"):
        core.on_mavlink(statustext("Armed by external command\t", severity=6, text_id=3), at(S))
        core.on_mavlink(statustext("Navigation error: no valid position", severity=4,
                                   text_id=4), at(S))
    said = [(r.levelno, r.getMessage()) for r in caplog.records if "autopilot says" in r.getMessage()]
    assert said == [(logging.DEBUG, "autopilot says: Armed by external command"),
                    (logging.WARNING, "autopilot says: Navigation error: no valid position")]
    core.on_mavlink(statustext("x" * 50, severity=4), at(2 * S))
    core.tick(at(2 * S + ID0_HOLD_NS))
    assert [t.text for t in core.texts.since(2 * S)] == ["x" * 50]


EVENTS_CATALOG = EventCatalog.from_json({"version": 2, "components": {"1": {
    "namespace": "px4", "event_groups": {"default": {"events": {"133277": {
        "name": "commander_arm_denied_resolve_failures", "message": PX4_DENIAL}}}}}}})


def test_core_keeps_the_refusal_texts_sent_since_the_request():
    core = make(message_rates_hz={})
    core.on_mavlink(ardupilot_heartbeat(armed=False), at(0))
    core.on_mavlink(statustext("PreArm: old news"), at(10 * MS))
    core.on_mavlink(statustext("Arm: Gyros inconsistent"), at(30 * MS))
    core.on_mavlink(statustext("Field Elevation Set: 30m", severity=6), at(31 * MS))
    assert core.explains_refusals()
    assert core.refusal_texts(20 * MS) == (["Arm: Gyros inconsistent"], True)
    assert core.refusal_texts(40 * MS) == ([], False)  # nothing said yet: worth waiting for
    px4 = make()
    px4.on_mavlink(px4_heartbeat(), at(0))
    assert not px4.explains_refusals()  # PX4 says it in EVENTs: not before their catalog arrives


def test_parameters_read_while_the_autopilot_starts_are_read_again_after():
    """Measured on SITL: read during INITIALISING, RC1_DZ came back 0 (before Rover set its 30 us
    default), so the steering paddle went uncompensated (12 N -> 8 N at the servo)."""
    core = make(message_rates_hz={})
    booting = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 16, 3, 3))  # INITIALISING
    core.on_mavlink(booting, at(0))
    answer_params(core, {**SITL_PARAMS, "RC1_DZ": 0.0}, 10 * MS)
    assert core.params.done and core.mapper(0.16, 0.16).y == 160  # plain: RC1 had no dead zone
    core.on_mavlink(wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 0, 3, 3)), at(1 * S))  # MANUAL
    asked = [o.param_id for o in of(core.tick(at(1 * S + MS)), SendParamRequestRead)]
    assert "RC1_DZ" in asked and not core.params.done
    answer_params(core, SITL_PARAMS, 1100 * MS)
    assert core.params.done and core.mapper(0.16, 0.16).y == 211  # now compensated


def test_an_autopilot_flapping_its_start_up_mode_does_not_flood_the_link_with_requests():
    """INITIALISING and MANUAL alternating at 10 kHz, for 2 s: each flap restarted the read, and
    each tick (every 2 ms here) sent the whole set again, 24 requests: 480 a second at vehicle_io's
    tick. A read restarted in progress keeps its pace: about one set per ``param_timeout_s``; once
    the flapping stops, the last read finishes as ever."""
    core = make(message_rates_hz={})
    booting = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 16, 3, 3))  # INITIALISING
    manual = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1, 0, 3, 3))
    per_set = len(of(core.on_mavlink(booting, at(0)), SendParamRequestRead))  # at link-up
    assert per_set > 0
    asked = 0
    for i in range(20_000):  # 2 s
        t = 2 * MS + i * 100_000
        asked += len(of(core.on_mavlink(manual if i % 2 == 0 else booting, at(t)),
                        SendParamRequestRead))
        if i % 20 == 0:
            asked += len(of(core.tick(at(t)), SendParamRequestRead))
    assert asked <= 3 * per_set  # at most one set a second (param_timeout_s 1 s), not 1,000
    answer_params(core, SITL_PARAMS, 3 * S)
    assert core.params.done and core.mapper(0.16, 0.16).y == 211


def test_the_mapping_parameters_are_read_again_when_the_vessel_arms():
    """Measured on SITL: even after INITIALISING, RC1_DZ could still read 0 (its default came with
    the first RC input); the port paddle lost 30 us and the boat turned steadily to port. Arming
    reads them again, and the mapping in use stays until the new one is made."""
    core = make(message_rates_hz={})
    core.on_mavlink(ardupilot_heartbeat(armed=False), at(0))
    answer_params(core, {**SITL_PARAMS, "RC1_DZ": 0.0}, 10 * MS)
    assert core.params.done and core.mapper(0.16, 0.16).y == 160
    core.on_mavlink(ardupilot_heartbeat(armed=False), at(1 * S))  # no change: nothing read
    assert not of(core.tick(at(1 * S + MS)), SendParamRequestRead)
    core.on_mavlink(ardupilot_heartbeat(armed=True), at(2 * S))
    asked = [o.param_id for o in of(core.tick(at(2 * S + MS)), SendParamRequestRead)]
    assert "RC1_DZ" in asked and "RC3_DZ" in asked
    assert core.mapper(0.16, 0.16).y == 160  # the old mapping until the answers are in
    answer_params(core, SITL_PARAMS, 2100 * MS)
    assert core.params.done and core.mapper(0.16, 0.16).y == 211
    core.on_mavlink(ardupilot_heartbeat(armed=True), at(3 * S))  # still armed: not again
    assert not of(core.tick(at(3 * S + MS)), SendParamRequestRead)


def test_an_accepted_arm_request_reads_the_mapping_parameters_again_before_the_heartbeat_says_so():
    core = make(message_rates_hz={})
    core.on_mavlink(ardupilot_heartbeat(armed=False), at(0))
    answer_params(core, {**SITL_PARAMS, "RC1_DZ": 0.0}, 10 * MS)
    core.command_accepted(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1.0, 0, 0, 0, 0, 0, 0), None)
    asked = [o.param_id for o in of(core.tick(at(1 * S)), SendParamRequestRead)]
    assert "RC1_DZ" in asked
    answer_params(core, SITL_PARAMS, 1100 * MS)
    core.on_mavlink(ardupilot_heartbeat(armed=True), at(2 * S))  # the HEARTBEAT after: not again
    assert not of(core.tick(at(2 * S + MS)), SendParamRequestRead)
    assert core.mapper(0.16, 0.16).y == 211
