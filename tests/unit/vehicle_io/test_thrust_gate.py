"""ThrustCommands vehicle_io refuses before the autopilot: absurd thrusts and absurd stamps."""

from __future__ import annotations

import logging

import pytest
from seaway.contract.messages import ThrustCommand, VehicleStatus
from seaway.vessel.thrusters import ABSURD_THRUST_FACTOR, absurd_thrust
from seaway_vehicle_io.core import SendManualControl

from tests.unit.vehicle_io.test_core import LIM, MS, PX4_NEUTRAL, WALL0, S, at, connected, of, published

HOUR = 3600 * S


def cmd(t1: float, t2: float, stamp_ns: int) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=t1, thrust_starboard_n=t2, source="t")


def test_absurd_is_beyond_twice_the_bound_of_its_direction():
    assert absurd_thrust(75.0, -75.0, LIM) is None
    assert absurd_thrust(ABSURD_THRUST_FACTOR * 75.0, 0.0, LIM) is None  # saturated, not refused
    assert "thrust_port_n" in absurd_thrust(1e9, 0.0, LIM)
    assert "thrust_starboard_n" in absurd_thrust(0.0, -151.0, LIM)


@pytest.mark.parametrize(
    ("t1", "t2", "stamp_ns", "reason"),
    [
        (1e9, 1e9, WALL0 + 100 * MS, "absurd"),
        (-1e9, 10.0, WALL0 + 100 * MS, "absurd"),
        (10.0, -10.0, WALL0 + 100 * MS + HOUR, "stamp_ahead"),
        (10.0, -10.0, WALL0 + 100 * MS - HOUR, "stamp_behind"),
        (30.0, 30.0, WALL0 + 100 * MS - 1500 * MS, "stamp_behind"),  # older than thrust_max_age_s
        (5.0, 5.0, 2**62, "stamp_ahead"),  # the year 2116
        (5.0, 5.0, 0, "stamp_behind"),  # the epoch
    ],
)
def test_a_refused_command_never_reaches_the_autopilot(t1, t2, stamp_ns, reason, caplog):
    caplog.set_level(logging.WARNING, "seaway.vehicle_io")
    core = connected()
    outs = core.on_thrust(cmd(t1, t2, stamp_ns), at(100 * MS))
    assert outs == []
    # the stream keeps sending what it sent before: neutral, no command having been taken
    (mc,) = of(core.tick(at(200 * MS)), SendManualControl)
    assert mc.axes == PX4_NEUTRAL
    assert core.refused_thrust() == {reason: 1}
    status = core.status(at(200 * MS))
    assert isinstance(status, VehicleStatus) and status.refused_thrust == {reason: 1}
    assert any("ctrl/thrust" in r.getMessage() or "ThrustCommand" in r.getMessage() for r in caplog.records)


def test_a_refused_command_leaves_the_last_good_one_to_the_watchdog():
    core = connected()
    (good,) = of(core.on_thrust(cmd(30.0, 30.0, WALL0 + 100 * MS), at(100 * MS)), SendManualControl)
    assert core.on_thrust(cmd(1e9, 1e9, WALL0 + 150 * MS), at(150 * MS)) == []
    assert core.on_thrust(cmd(-10.0, 10.0, WALL0 + HOUR), at(160 * MS)) == []
    (mc,) = of(core.tick(at(200 * MS)), SendManualControl)
    assert mc.axes == good.axes  # still the good command's, until its deadline
    (mc,) = of(core.tick(at(400 * MS)), SendManualControl)
    assert mc.axes == PX4_NEUTRAL  # watchdog: the refused ones did not keep it alive


def test_a_stop_is_taken_whatever_its_stamp():
    """The controller stamps a stale-state or shutdown stop with the last state's time."""
    core = connected()
    core.on_thrust(cmd(30.0, 30.0, WALL0 + 100 * MS), at(100 * MS))
    (mc,) = of(core.on_thrust(cmd(0.0, 0.0, WALL0 - HOUR), at(150 * MS)), SendManualControl)
    assert mc.axes == PX4_NEUTRAL and mc.neutral
    assert core.refused_thrust() == {}


def test_a_flood_of_refused_commands_is_one_line_a_minute(caplog):
    caplog.set_level(logging.WARNING, "seaway.vehicle_io")
    core = connected()
    for k in range(1000):  # 10 s at 100 Hz, each kind
        core.on_thrust(cmd(1e9, 0.0, WALL0 + k * 10 * MS), at(k * 10 * MS))
        core.on_thrust(cmd(10.0, 10.0, WALL0 + k * 10 * MS + HOUR), at(k * 10 * MS))
    assert core.refused_thrust() == {"absurd": 1000, "stamp_ahead": 1000}
    lines = [
        r for r in caplog.records if "ThrustCommand" in r.getMessage() or "ctrl/thrust" in r.getMessage()
    ]
    assert len(lines) == 2
    assert published(core.tick(at(10 * S)), VehicleStatus)[0].refused_thrust == {
        "absurd": 1000,
        "stamp_ahead": 1000,
    }
