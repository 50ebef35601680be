"""Issue 14 in vehicle_io: the status says when the autopilot does not apply the commanded thrust
(item 2), a stop that only ends zero commands is not a warning (item 14), and a flood of bad
telemetry is a line now and then with a count (item 7). Pure core, real MAVLink, time passed in."""

from __future__ import annotations

import logging

import pytest
from seaway.contract.messages import VehicleStatus

from tests.unit.vehicle_io.test_core import (
    MS,
    S,
    at,
    attitude,
    connected,
    heartbeat,
    make,
    published,
    thrust,
)

PX4_MANUAL = 1 << 16
PX4_HOLD = (4 << 16) | (3 << 24)  # AUTO.LOITER, what a PX4 failsafe Hold reports


def test_status_says_why_the_thrust_is_withheld() -> None:
    # Each change comes more than the status pacing's gap (50 ms) after the last one said at once.
    core = make(check_failsafe_params=False)
    assert published(core.tick(at(0)), VehicleStatus)[0].thrust_withheld == "no_link"
    (st,) = published(core.on_mavlink(heartbeat(armed=False), at(1 * MS)), VehicleStatus)
    assert st.link_ok and st.thrust_withheld == "disarmed"
    # Armed (a heartbeat saying so): published at once, not at the next 2 Hz status.
    (st,) = published(core.on_mavlink(heartbeat(armed=True), at(100 * MS)), VehicleStatus)
    assert st.armed and st.thrust_withheld is None
    assert not published(core.on_mavlink(heartbeat(armed=True), at(110 * MS)), VehicleStatus)
    # A failsafe Hold: armed, but manual control does not drive the thrusters.
    (st,) = published(core.on_mavlink(heartbeat(armed=True, custom_mode=PX4_HOLD), at(200 * MS)),
                      VehicleStatus)
    assert st.mode == "HOLD" and st.thrust_withheld == "mode"
    (st,) = published(core.on_mavlink(heartbeat(armed=True, custom_mode=PX4_MANUAL),
                                      at(300 * MS)), VehicleStatus)
    assert st.thrust_withheld is None
    # The link lost: said at once.
    (st,) = published(core.tick(at(300 * MS + 3 * S)), VehicleStatus)
    assert not st.link_ok and st.thrust_withheld == "no_link"


def test_an_old_reader_and_an_old_writer_still_agree() -> None:
    """The new field is optional: an older vehicle_io's status decodes as 'applied'."""
    old = b'{"stamp_ns": 1, "autopilot": "px4", "link_ok": true, "armed": true, "mode": "MANUAL"}'
    assert VehicleStatus.decode(old).thrust_withheld is None


@pytest.mark.parametrize(("last_n", "level"), [(0.0, logging.INFO), (30.0, logging.WARNING)])
def test_stale_commands_warn_only_when_they_cut_thrust(caplog, last_n: float, level: int) -> None:
    """Every stop ended with a ``thrust_stale`` WARNING. Commands that stop after a zero one (a
    mission over, a controller stopped in order) change nothing for the thrusters: INFO. Commands
    that stop while the boat is driven are worth a warning."""
    caplog.set_level(logging.INFO, "seaway.vehicle_io")
    core = connected()
    core.on_thrust(thrust(last_n, last_n), at(100 * MS))
    outs = core.tick(at(400 * MS))
    assert published(outs, VehicleStatus)[0].failsafe == "thrust_stale"
    (rec,) = [r for r in caplog.records if "no ThrustCommand for" in r.getMessage()]
    assert rec.levelno == level


def test_a_flood_of_bad_telemetry_is_a_line_now_and_then(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.vehicle_io")
    core = connected()
    core.on_mavlink(attitude(time_boot_ms=1000), at(10 * MS))
    for i in range(10_000):  # 10 s of corrupt boot times (one or two hours ahead): each dropped
        core.on_mavlink(attitude(time_boot_ms=3_600_000 * (1 + i % 2) + i), at(20 * MS + i * MS))
    lines = [r.getMessage() for r in caplog.records if "dropped ATTITUDE" in r.getMessage()]
    assert core.dropped == 10_000
    assert len(lines) == 2  # the first, then once 5 s later with the count (the shared helper)
    assert lines[1].endswith("(4999 more like it since the last report)")
