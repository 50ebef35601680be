"""The pure core, driven with real MAVLink messages (packed and parsed) and time passed in."""

from __future__ import annotations

import struct
from typing import Any

import pytest
from seaway.contract.messages import Attitude, GnssFix, ThrustCommand, VehicleStatus
from seaway.contract.units import NS_PER_S
from seaway_vehicle_io.config import SOURCE_SYSTEM, VehicleIoConfig
from seaway_vehicle_io.core import (
    Now,
    Publish,
    SendCommandLong,
    SendHeartbeat,
    SendManualControl,
    SendParamRequestRead,
    VehicleIoCore,
)
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.profile import ManualControlAxes
from seaway_vehicle_io.thrust import ThrusterLimits

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
LIM = ThrusterLimits(75.0, 75.0, 10.0)
PX4_NEUTRAL = ManualControlAxes(0, 0, 500, 0)


# -- real MAVLink messages (packed to bytes and parsed back) --------------------------------------


def wire(msg: Any, sysid: int = 1, compid: int = 1) -> Any:
    """``msg`` as vehicle_io would receive it from (sysid, compid): packed, then decoded."""
    tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    rx = mavlink.MAVLink(None)
    return rx.decode(bytearray(msg.pack(tx)))


def heartbeat(autopilot: int = 12, armed: bool = False, custom_mode: int = 1 << 16,
              mav_type: int = 10, sysid: int = 1, compid: int = 1) -> Any:
    base = 1 | (128 if armed else 0)
    return wire(mavlink.MAVLink_heartbeat_message(mav_type, autopilot, base, custom_mode, 4, 3),
                sysid, compid)


def global_position_int(time_boot_ms: int = 1000, lat: int = 473977420, lon: int = 85455940,
                        alt: int = 488_000, vx: int = 150, vy: int = -50, sysid: int = 1) -> Any:
    return wire(mavlink.MAVLink_global_position_int_message(
        time_boot_ms, lat, lon, alt, 0, vx, vy, 0, 0), sysid)


def attitude(time_boot_ms: int = 1000, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.5,
             rollspeed: float = 0.0, pitchspeed: float = 0.0, yawspeed: float = 0.1,
             sysid: int = 1) -> Any:
    return wire(mavlink.MAVLink_attitude_message(time_boot_ms, roll, pitch, yaw, rollspeed,
                                                 pitchspeed, yawspeed), sysid)



def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


def make(**cfg) -> VehicleIoCore:
    return VehicleIoCore(VehicleIoConfig(**cfg), LIM, at(0))


def of(outs, kind):
    return [o for o in outs if isinstance(o, kind)]


def published(outs, kind):
    return [o.message for o in outs if isinstance(o, Publish) and isinstance(o.message, kind)]


def thrust(t1: float, t2: float, t_ns: int = 0) -> ThrustCommand:
    """A command stamped with the state of time ``t_ns`` (within vehicle_io's bounds near it)."""
    return ThrustCommand.make(stamp_ns=WALL0 + t_ns, thrust_port_n=t1, thrust_starboard_n=t2)


def connected(armed: bool = True, **cfg) -> VehicleIoCore:
    core = make(check_failsafe_params=False, **cfg)
    core.on_mavlink(heartbeat(armed=armed), at(1 * MS))
    assert core.link.ok
    return core


def test_nothing_but_heartbeats_before_an_autopilot_is_heard():
    core = make()
    outs = core.tick(at(0))
    assert of(outs, SendHeartbeat) and not of(outs, SendManualControl)
    status = published(outs, VehicleStatus)[0]
    assert (status.link_ok, status.autopilot, status.failsafe) == (False, "unknown", "thrust_stale")
    assert not of(core.on_thrust(thrust(30, 30), at(10 * MS)), SendManualControl)


def test_learns_the_autopilot_from_its_heartbeat():
    core = make()
    outs = core.on_mavlink(heartbeat(autopilot=12, sysid=7, compid=1), at(5 * MS))
    assert (core.link.target_system, core.link.target_component) == (7, 1)
    assert core.link.profile.name == "px4" and core.link.mode == "MANUAL"
    mc = of(outs, SendManualControl)
    assert mc and mc[0].target_system == 7 and mc[0].axes == PX4_NEUTRAL  # stream starts neutral
    asked = {o.param_id for o in of(outs, SendParamRequestRead)}
    assert {"COM_RC_IN_MODE", "COM_RC_LOSS_T", "NAV_RCL_ACT"} <= asked
    assert published(outs, VehicleStatus)[0].link_ok


@pytest.mark.parametrize("hb", [
    heartbeat(mav_type=6, autopilot=8),  # a GCS
    heartbeat(mav_type=18, autopilot=12),  # an onboard computer, even if it claims PX4
    heartbeat(autopilot=0),  # generic autopilot: no profile
    heartbeat(sysid=SOURCE_SYSTEM, compid=191),  # ourselves, echoed
])
def test_ignores_heartbeats_that_are_not_a_known_autopilot(hb):
    core = make()
    core.on_mavlink(hb, at(0))
    assert not core.link.ok


def test_configured_autopilot_and_target_are_enforced():
    core = make(autopilot="ardupilot")
    core.on_mavlink(heartbeat(autopilot=12), at(0))
    assert not core.link.ok
    core.on_mavlink(heartbeat(autopilot=3, custom_mode=4), at(0))
    assert core.link.ok and core.link.profile.name == "ardupilot" and core.link.mode == "HOLD"
    core = make(target_system=2)
    core.on_mavlink(heartbeat(sysid=1), at(0))
    assert not core.link.ok
    core.on_mavlink(heartbeat(sysid=2), at(0))
    assert core.link.target_system == 2


def test_thrust_is_mapped_and_sent_at_once_when_armed():
    core = connected(armed=True)
    outs = core.on_thrust(thrust(30.0, -20.0), at(100 * MS))
    (mc,) = of(outs, SendManualControl)
    # L = 0.4, R = -0.2667: y = 500 (L - R) = 333, z = 500 + 250 (L + R) = 533
    assert mc.axes == ManualControlAxes(0, 333, 533, 0) and not mc.neutral
    # and it keeps being streamed at the fixed rate while fresh
    outs = core.tick(at(150 * MS))
    assert of(outs, SendManualControl)[0].axes == ManualControlAxes(0, 333, 533, 0)


def test_thrust_withheld_while_disarmed():
    core = connected(armed=False)
    (mc,) = of(core.on_thrust(thrust(30.0, 30.0), at(100 * MS)), SendManualControl)
    assert mc.axes == PX4_NEUTRAL and mc.neutral
    core = connected(armed=False, forward_thrust_only_when_armed=False)
    (mc,) = of(core.on_thrust(thrust(30.0, 30.0), at(100 * MS)), SendManualControl)
    assert mc.axes != PX4_NEUTRAL


def test_watchdog_sends_neutral_at_the_deadline_and_recovers():
    core = connected()
    core.tick(at(2 * MS))
    core.on_thrust(thrust(40.0, 40.0), at(110 * MS))
    assert core.next_wake_ns() <= 410 * MS  # the loop is told to wake at the deadline
    outs = core.tick(at(400 * MS))  # a stream tick, still fresh
    assert of(outs, SendManualControl) and not of(outs, SendManualControl)[0].neutral
    assert not of(core.tick(at(409 * MS)), SendManualControl)  # nothing due
    outs = core.tick(at(410 * MS))  # exactly 300 ms after receipt, between stream ticks
    mcs = of(outs, SendManualControl)
    assert len(mcs) == 1 and mcs[0].neutral and mcs[0].axes == PX4_NEUTRAL
    status = published(outs, VehicleStatus)
    assert status and status[0].failsafe == "thrust_stale"  # published at once, not at 2 Hz
    # stays neutral on the stream
    assert all(o.neutral for o in of(core.tick(at(460 * MS)), SendManualControl))
    # commands return: failsafe cleared, thrust forwarded immediately
    outs = core.on_thrust(thrust(20.0, 20.0), at(500 * MS))
    assert published(outs, VehicleStatus)[0].failsafe is None
    assert not of(outs, SendManualControl)[0].neutral


def test_link_loss_and_relearn_without_restart():
    core = connected()
    core.on_thrust(thrust(40.0, 40.0), at(100 * MS))
    outs = core.tick(at(1 * MS + 3 * S))  # 3 s without a heartbeat
    status = published(outs, VehicleStatus)
    assert status and status[0].link_ok is False and status[0].mode == "UNKNOWN"
    assert not of(outs, SendManualControl)  # nobody to command
    assert core.arm_command(True, False).startswith("no autopilot link")
    # another autopilot (a restarted one with a new id) comes up: relearnt
    outs = core.on_mavlink(heartbeat(sysid=3, armed=False), at(4 * S))
    assert core.link.ok and core.link.target_system == 3 and core.link.connects == 2
    assert of(outs, SendManualControl)[0].target_system == 3


def test_heartbeats_from_other_vehicles_do_not_keep_the_link():
    core = connected()
    for k in range(1, 5):
        core.on_mavlink(heartbeat(sysid=9), at(k * S))
    assert core.link.target_system == 1
    core.tick(at(3 * S + 2 * MS))
    assert not core.link.ok


def test_telemetry_is_converted_and_stamped_through_the_offset():
    core = connected()
    outs = core.on_mavlink(attitude(time_boot_ms=10_000, yaw=1.0), at(20 * S))
    (att,) = published(outs, Attitude)
    assert att.yaw_rad == pytest.approx(1.0, abs=1e-6)
    assert att.stamp_ns == WALL0 + 20 * S  # first sample: stamp = receipt
    # 100 ms of boot time later, received after 30 ms of extra latency: the stamp keeps the
    # smaller latency (the offset is a minimum), i.e. exactly 100 ms after the first stamp
    (att2,) = published(core.on_mavlink(attitude(time_boot_ms=10_100), at(20 * S + 130 * MS)),
                        Attitude)
    assert att2.stamp_ns == WALL0 + 20 * S + 100 * MS
    (fix,) = published(core.on_mavlink(global_position_int(time_boot_ms=10_200),
                                       at(20 * S + 205 * MS)), GnssFix)
    assert fix.stamp_ns == WALL0 + 20 * S + 200 * MS


def local_position_ned(time_boot_ms: int) -> Any:
    return wire(mavlink.MAVLink_local_position_ned_message(time_boot_ms, 1.0, 2.0, 0.0, 0.1, 0.2,
                                                           0.0))


def test_a_message_seconds_late_does_not_blind_the_telemetry():
    """A LOCAL_POSITION_NED stamped 5 s back (the sim's after a GNSS dropout; a radio holding a
    packet) among on-time ATTITUDE: it is published with its own older stamp, and every on-time
    message after it still is, with its own."""
    core = connected()
    for k in range(50):
        core.on_mavlink(attitude(time_boot_ms=100_000 + 100 * k), at(100 * S + k * 100 * MS))
    outs = core.on_mavlink(local_position_ned(100_000), at(105 * S))
    (late,) = [o.message for o in outs if isinstance(o, Publish)]
    assert late.stamp_ns == WALL0 + 100 * S
    for k in range(1, 30):
        (att,) = published(core.on_mavlink(attitude(time_boot_ms=105_000 + 100 * k),
                                           at(105 * S + k * 100 * MS)), Attitude)
        assert att.stamp_ns == WALL0 + 105 * S + k * 100 * MS
    assert core.dropped == 0


def test_system_time_going_back_restarts_the_time_offset():
    core = connected()
    core.on_mavlink(attitude(time_boot_ms=100_000), at(100 * S))
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 100_010)), at(100 * S))
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 500)), at(102 * S))
    assert core.offset.resets == 0  # one SYSTEM_TIME going back could be a stale packet
    core.on_mavlink(wire(mavlink.MAVLink_system_time_message(0, 1_500)), at(103 * S))
    assert core.offset.resets == 1  # the next runs on from it: the autopilot's clock restarted
    (att,) = published(core.on_mavlink(attitude(time_boot_ms=1_600), at(103 * S + 100 * MS)),
                       Attitude)
    assert att.stamp_ns == WALL0 + 103 * S + 100 * MS


def test_out_of_range_and_garbage_are_counted_and_dropped():
    core = connected()
    core.on_mavlink(attitude(time_boot_ms=1000), at(2 * S))
    cases = [
        attitude(time_boot_ms=1100, yaw=float("nan")),
        attitude(time_boot_ms=1100, rollspeed=1e6),
        global_position_int(time_boot_ms=1100, lat=950_000_000),
        attitude(time_boot_ms=1100 + 3_600_000),  # boot time jumps an hour ahead
    ]
    for k, msg in enumerate(cases, start=1):
        assert core.on_mavlink(msg, at(2 * S + 100 * MS)) == []
        assert core.dropped == k
    offset = core.offset.offset_ns
    # the corrupt boot time did not move the estimate
    core.on_mavlink(attitude(time_boot_ms=1200), at(2 * S + 200 * MS))
    assert core.offset.offset_ns == offset
    # bytes that are not MAVLink
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    for bad in parser.parse_buffer(b"\xfd\x09garbage-not-mavlink" * 3) or []:
        core.on_mavlink(bad, at(3 * S))
    assert core.dropped > 4
    assert published(core.tick(at(3 * S)), VehicleStatus)[0].dropped_messages == core.dropped


def test_messages_from_other_systems_are_not_published():
    core = connected()
    assert core.on_mavlink(attitude(sysid=42), at(2 * S)) == []
    assert core.dropped == 0


def param_value(name: str, value: float, ptype: int) -> object:
    return wire(mavlink.MAVLink_param_value_message(name.encode(), value, ptype, 20, 0))


def bytewise(i: int) -> float:
    return struct.unpack("<f", struct.pack("<i", i))[0]


def test_param_check_reports_the_verdict():
    core = make(param_attempts=2)
    outs = core.on_mavlink(heartbeat(armed=True), at(0))
    wanted = [o.param_id for o in of(outs, SendParamRequestRead)]
    answers = {"COM_RC_IN_MODE": (bytewise(1), 6), "COM_RC_LOSS_T": (0.5, 9),
               "NAV_RCL_ACT": (bytewise(0), 6)}
    for name, (value, ptype) in answers.items():
        core.on_mavlink(param_value(name, value, ptype), at(10 * MS))
    # the rest is unanswered: asked again after the timeout, then given up
    retry = of(core.tick(at(1 * S + 10 * MS)), SendParamRequestRead)
    assert {o.param_id for o in retry} == set(wanted) - set(answers)
    assert core.params.assessment is None
    core.tick(at(2 * S + 20 * MS))
    a = core.params.assessment
    assert a is not None and a.verdict == "none"  # NAV_RCL_ACT 0: the boat would keep going
    core.on_thrust(thrust(20.0, 20.0, 2 * S), at(2 * S + 30 * MS))
    status = core.status(at(2 * S + 40 * MS))
    assert status.failsafe is None  # commands are fresh: no failsafe is acting
    assert status.autopilot_loss_failsafe == "none"
    assert "NAV_RCL_ACT" in status.autopilot_loss_failsafe_summary


def test_ardupilot_config_that_breaks_the_mapping_blocks_thrust():
    core = make()
    core.on_mavlink(heartbeat(autopilot=3, mav_type=11, armed=True, custom_mode=0), at(0))
    for name in core.params.wanted:
        value = 0.0 if name == "PILOT_STEER_TYPE" else 1.0
        core.on_mavlink(param_value(name, value, 9), at(10 * MS))
    assert core.params.assessment is not None and core.params.assessment.blocking
    (mc,) = of(core.on_thrust(thrust(30.0, 30.0), at(20 * MS)), SendManualControl)
    assert mc.neutral and mc.axes == ManualControlAxes(0, 0, 0, 0)
    assert core.status(at(30 * MS)).failsafe == "autopilot_config"


def test_commands_and_acks():
    core = connected()
    cmd = core.arm_command(True, False)
    assert isinstance(cmd, SendCommandLong)
    assert (cmd.command, cmd.target_system, cmd.params[:2]) == (400, 1, (1.0, 0.0))
    mode = core.mode_command("hold")
    assert isinstance(mode, SendCommandLong) and mode.params[:3] == (1.0, 4.0, 3.0)
    assert "no mode" in core.mode_command("WARP")
    core.commands.begin(400, 1)
    # an ACK for another GCS is not ours; ours is recorded
    core.on_mavlink(wire(mavlink.MAVLink_command_ack_message(400, 0, 0, 0, 254, 0)), at(2 * MS))
    assert core.commands.state(400).result is None
    core.on_mavlink(wire(mavlink.MAVLink_command_ack_message(400, 1, 0, 0, SOURCE_SYSTEM, 191)),
                    at(3 * MS))
    assert core.commands.state(400).result == 1


def test_rates_are_counted_per_message_type():
    core = connected()
    for k in range(40):
        core.on_mavlink(attitude(time_boot_ms=1000 + 50 * k), at(k * 50 * MS))
    core.tick(at(2 * S + 1 * MS))
    assert core.rates_hz["ATTITUDE"] == pytest.approx(20.0, rel=0.05)


def test_a_duplicated_packet_is_published_once():
    """A router loop or two radio paths deliver the same packet twice: one measurement, not two
    (the estimator would weigh that fix double); the next message is published."""
    core = connected()
    packet = attitude(time_boot_ms=5000)
    first = published(core.on_mavlink(packet, at(5 * S)), Attitude)
    again = published(core.on_mavlink(packet, at(5 * S + MS)), Attitude)
    nxt = published(core.on_mavlink(attitude(time_boot_ms=5050), at(5 * S + 50 * MS)), Attitude)
    assert (len(first), len(again), len(nxt), core.duplicates) == (1, 0, 1, 1)
