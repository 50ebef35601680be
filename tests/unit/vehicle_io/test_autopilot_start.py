"""An autopilot that is starting (``autopilot_health.Health.starting``): what it lacks and refuses
until it is first healthy is the expected state of a start, said at INFO and shown in the status;
past ``START_GRACE_S`` without being healthy, or once it has been healthy, the same is a warning.

Measured on ArduPilot Rover SITL before this: a dozen WARNINGs from vehicle_io between its first
HEARTBEAT and its EKF using GPS (40 s), each echoed on the launcher's terminal. Pure core, real
packed MAVLink, time passed in.
"""

from __future__ import annotations

import logging
from typing import Any

from seaway_vehicle_io.autopilot_health import (
    EST_POS_HORIZ_ABS,
    ESTIMATOR_REPORT_WAIT_S,
    READY_SETTLE_S,
    START_GRACE_S,
    Health,
)
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import VehicleIoCore
from seaway_vehicle_io.mav import mavlink

from tests.unit.vehicle_io.test_autopilot_health import AHRS, ALL, ekf, heartbeat, sys_status
from tests.unit.vehicle_io.test_hold_reason import LIM, MS, S, at, wire
from tests.unit.vehicle_io.test_rate_recovery import Autopilot

LOGGER = "seaway.vehicle_io"
GRACE_NS = round(START_GRACE_S * S)
SETTLE_NS = round(READY_SETTLE_S * S)
EKF_GOOD = 0x7 | EST_POS_HORIZ_ABS
EKF_NO_GNSS = 0x7


def said(caplog, level: int) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.levelno == level]


def attitude(time_boot_ms: int) -> Any:
    return wire(mavlink.MAVLink_attitude_message(time_boot_ms, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))


def statustext(text: str, severity: int = 2) -> Any:
    return wire(mavlink.MAVLink_statustext_message(severity, text.encode(), 0, 0))


class Booting:
    """An ArduPilot Rover that came up ``booted_s`` before vehicle_io heard it, its EKF not yet
    using GNSS: HEARTBEAT, SYS_STATUS with AHRS unhealthy, EKF_STATUS_REPORT, ATTITUDE at 1 Hz."""

    def __init__(self, booted_s: float = 2.0) -> None:
        self.core = VehicleIoCore(VehicleIoConfig(autopilot="auto", check_failsafe_params=False,
                                                  message_rates_hz={}), LIM, at(0))
        self.boot_ns = -round(booted_s * S)
        self.healthy = False

    def second(self, t_ns: int) -> None:
        core = self.core
        core.on_mavlink(heartbeat(mavlink.MAV_STATE_STANDBY), at(t_ns))
        core.on_mavlink(attitude((t_ns - self.boot_ns) // MS), at(t_ns))
        core.on_mavlink(sys_status(ALL if self.healthy else ALL & ~AHRS), at(t_ns))
        core.on_mavlink(ekf(EKF_GOOD if self.healthy else EKF_NO_GNSS), at(t_ns))
        core.tick(at(t_ns + 10 * MS))
        core.status(at(t_ns + 20 * MS))

    def run(self, start_s: int, end_s: int) -> None:
        for k in range(start_s, end_s):
            self.second(k * S)


# -- pure logic ------------------------------------------------------------------------------------


def test_a_start_ends_when_first_healthy_and_does_not_come_back():
    h = Health(since_mono_ns=0)
    h.booted_ms(1000)
    h.heartbeat(mavlink.MAV_STATE_STANDBY)
    h.sys_status(ALL, ALL, ALL & ~AHRS)
    assert h.problem() is not None and h.starting(10 * S)
    h.estimator_flags("EKF_STATUS_REPORT", EKF_GOOD)
    h.sys_status(ALL, ALL, ALL)
    assert h.starting(11 * S)  # healthy, not yet for READY_SETTLE_S
    h.sys_status(ALL, ALL, ALL & ~AHRS)  # a flap while it settles (PX4 SITL): still starting
    assert h.starting(12 * S)
    h.sys_status(ALL, ALL, ALL)
    assert h.starting(13 * S) and h.starting(13 * S + SETTLE_NS - 1)
    assert not h.starting(13 * S + SETTLE_NS) and h.ready
    h.sys_status(ALL, ALL, ALL & ~AHRS)  # unhealthy again once started: a fault, not a start
    assert h.problem() is not None and not h.starting(30 * S)


def test_a_start_ends_after_the_grace_by_our_clock_whatever_the_autopilot_says():
    h = Health(since_mono_ns=5 * S)
    h.booted_ms(0)  # an absurd boot time, or one stuck at zero, keeps saying "just booted"
    h.sys_status(ALL, ALL, ALL & ~AHRS)
    assert h.starting(5 * S + GRACE_NS - 1)
    assert not h.starting(5 * S + GRACE_NS)


def test_healthy_sensors_before_the_estimators_first_report_do_not_end_the_start():
    """ArduPilot Rover SITL: its SYS_STATUS says every sensor healthy for seconds before its first
    EKF_STATUS_REPORT, which then says "not initialised"; an autopilot that never sends one is
    judged without it after ``ESTIMATOR_REPORT_WAIT_S``."""
    h = Health(since_mono_ns=0)
    h.booted_ms(2000)
    h.sys_status(ALL, ALL, ALL)
    assert h.problem() is None and h.starting(3 * S)
    h.estimator_flags("EKF_STATUS_REPORT", 0x400)
    assert h.problem() is not None and h.starting(4 * S)
    h.estimator_flags("EKF_STATUS_REPORT", EKF_GOOD)
    assert h.starting(5 * S) and not h.starting(5 * S + SETTLE_NS)
    silent = Health(since_mono_ns=0)
    silent.booted_ms(2000)
    silent.sys_status(ALL, ALL, ALL)
    wait_ns = round(ESTIMATOR_REPORT_WAIT_S * S)
    assert silent.starting(wait_ns - 1) and silent.starting(wait_ns)  # healthy from then on
    assert not silent.starting(wait_ns + SETTLE_NS)


def test_an_autopilot_up_for_longer_than_the_grace_is_not_starting():
    """A restarted vehicle_io meets an autopilot booted ten minutes ago: what it lacks is news."""
    h = Health(since_mono_ns=0)
    assert h.starting(0)  # its boot time not heard yet
    h.booted_ms(600_000)
    assert not h.starting(MS)


# -- the core --------------------------------------------------------------------------------------


def test_what_a_starting_autopilot_lacks_is_said_at_info_then_a_fault_is_a_warning(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = Booting()
    ap.run(0, 40)
    assert ap.core.status(at(40 * S)).thrust_withheld == "autopilot_unhealthy"  # shown, withheld
    assert not said(caplog, logging.WARNING)
    assert any("estimator not using GNSS" in m for m in said(caplog, logging.INFO))
    ap.healthy = True
    ap.run(40, 47)
    assert ap.core.status(at(47 * S)).thrust_withheld is None
    assert not said(caplog, logging.WARNING)
    ap.healthy = False  # its EKF lost GNSS after it had it for seconds: a fault
    ap.run(47, 49)
    (warning,) = said(caplog, logging.WARNING)
    assert "estimator not using GNSS" in warning


def test_an_autopilot_never_healthy_is_warned_once_when_the_grace_ends(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = Booting(booted_s=2.0)  # its own clock ends the start 2 s before ours
    ap.run(0, int(START_GRACE_S) - 3)
    assert not said(caplog, logging.WARNING)
    ap.run(int(START_GRACE_S) - 3, int(START_GRACE_S) + 30)
    (warning,) = said(caplog, logging.WARNING)  # once, not at every status while it stands
    assert "estimator not using GNSS" in warning and "not healthy yet" in warning


def test_a_vehicle_io_restarted_beside_an_old_autopilot_warns_at_once(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = Booting(booted_s=600.0)
    ap.run(0, 3)
    warnings = said(caplog, logging.WARNING)
    assert warnings and all("not healthy" in m for m in warnings)


def test_start_checks_are_info_while_starting_and_warnings_after(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = Booting()
    ap.run(0, 5)
    core = ap.core
    core.on_mavlink(statustext("PreArm: AHRS not healthy"), at(5 * S))
    core.on_mavlink(statustext("EKF3 lane switch 1", 4), at(5 * S + MS))  # no start check: a warning
    (warning,) = said(caplog, logging.WARNING)
    assert "EKF3 lane switch 1" in warning
    assert any("PreArm: AHRS not healthy" in m for m in said(caplog, logging.INFO))
    assert "PreArm: AHRS not healthy" in [t.text for t in core.texts.since(5 * S)]  # kept
    ap.healthy = True
    ap.run(6, 13)
    caplog.clear()
    core.on_mavlink(statustext("PreArm: Battery below minimum arming voltage"), at(13 * S))
    (warning,) = said(caplog, logging.WARNING)
    assert "PreArm: Battery below minimum arming voltage" in warning


def test_a_broken_frame_while_starting_is_info_and_after_it_a_warning(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = Booting()
    ap.run(0, 2)
    bad = mavlink.MAVLink_bad_data(b"\x01\x02", "Bad prefix")
    ap.core.on_mavlink(bad, at(2 * S))
    assert not said(caplog, logging.WARNING) and ap.core.dropped == 1
    ap.healthy = True
    ap.run(2, 10)
    ap.core.on_mavlink(bad, at(10 * S))  # started; past the 5 s the log limits a kind to a line
    (warning,) = said(caplog, logging.WARNING)
    assert "BAD_DATA" in warning and ap.core.dropped == 2


def _streaming(attitude_hz: float, seconds: float, healthy_at_s: float | None) -> Autopilot:
    """``test_rate_recovery``'s autopilot (booted 5 s before, ATTITUDE asked at 10 Hz) sending
    ``attitude_hz``; from ``healthy_at_s`` on, a SYS_STATUS that says it is healthy."""
    core = VehicleIoCore(VehicleIoConfig(autopilot="auto", message_rates_hz={"ATTITUDE": 10.0},
                                         check_failsafe_params=False), LIM, at(0))
    ap = Autopilot(core)
    step_s = 1.0
    t = 0.0
    while t < seconds:
        if healthy_at_s is not None and t >= healthy_at_s:
            core.on_mavlink(sys_status(ALL), at(ap.t_ns))
        ap.run(step_s, attitude_hz=attitude_hz)
        t += step_s
    return ap


def test_telemetry_short_while_starting_is_info_and_a_warning_if_it_outlasts_the_start(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = _streaming(attitude_hz=2.0, seconds=20.0, healthy_at_s=None)
    assert ap.short() and not said(caplog, logging.WARNING)  # shown in the status all along
    assert any("telemetry below the requested rate" in m for m in said(caplog, logging.INFO))
    ap.core.on_mavlink(sys_status(ALL), at(ap.t_ns))  # started: the shortfall is the link's now
    ap.run(14.0, attitude_hz=2.0)  # settled (READY_SETTLE_S), then a drop (DROP_CONFIRM_S)
    warnings = said(caplog, logging.WARNING)
    assert warnings and all("ATTITUDE" in m for m in warnings)


def test_telemetry_short_while_starting_that_recovers_is_never_a_warning(caplog):
    caplog.set_level(logging.INFO, LOGGER)
    ap = _streaming(attitude_hz=2.0, seconds=10.0, healthy_at_s=None)
    ap.run(6.0, attitude_hz=10.0)
    ap.core.on_mavlink(sys_status(ALL), at(ap.t_ns))
    ap.run(20.0, attitude_hz=10.0)
    assert ap.short() == {} and not said(caplog, logging.WARNING)
