"""The boot-time offset estimator and the thrust watchdog, with time passed in."""

from __future__ import annotations

import pytest
from seaway.contract.messages import ThrustCommand
from seaway.contract.units import NS_PER_S
from seaway_vehicle_io.timesync import BootTimeOffset
from seaway_vehicle_io.watchdog import ThrustWatchdog

S = NS_PER_S
MS = 1_000_000
EPOCH = 1_700_000_000 * S  # wall time at the autopilot's boot


def test_offset_is_the_minimum_latency_sample():
    est = BootTimeOffset(window_s=10.0)
    # (boot ms, latency ms): the 2 ms sample is the best; spikes after it must not move it.
    samples = [(100, 8), (200, 5), (300, 2), (400, 50), (500, 30), (600, 9)]
    for boot_ms, lat_ms in samples:
        stamp = est.update(boot_ms, EPOCH + boot_ms * MS + lat_ms * MS)
    assert est.offset_ns == EPOCH + 2 * MS
    assert stamp == EPOCH + 600 * MS + 2 * MS  # true time + the best latency seen
    # A stamp is never later than its receipt.
    assert stamp <= EPOCH + 600 * MS + 9 * MS


def test_latency_spike_does_not_move_the_estimate():
    est = BootTimeOffset(window_s=10.0)
    est.update(1000, EPOCH + 1000 * MS + 1 * MS)
    before = est.offset_ns
    est.update(1100, EPOCH + 1100 * MS + 400 * MS)  # 400 ms stall on the link
    assert est.offset_ns == before


def test_window_forgets_old_minimum():
    est = BootTimeOffset(window_s=1.0)
    est.update(0, EPOCH + 1 * MS)  # best sample, at t = 0
    est.update(500, EPOCH + 500 * MS + 5 * MS)
    assert est.offset_ns == EPOCH + 1 * MS
    # 1.5 s later the 1 ms sample is out of the window; the estimate follows the newer ones.
    est.update(1500, EPOCH + 1500 * MS + 4 * MS)
    assert est.offset_ns == EPOCH + 4 * MS


def test_reboot_resets():
    est = BootTimeOffset(window_s=10.0)
    est.update(50_000, EPOCH + 50_000 * MS + 3 * MS)
    new_epoch = EPOCH + 60 * S  # rebooted 60 s after the first boot
    stamp = est.update(100, new_epoch + 100 * MS + 6 * MS)
    assert est.resets == 1
    assert est.offset_ns == new_epoch + 6 * MS
    assert stamp == new_epoch + 106 * MS


def test_peek_matches_update_and_does_not_record():
    est = BootTimeOffset(window_s=10.0)
    est.update(100, EPOCH + 103 * MS)
    peeked = est.peek(200, EPOCH + 201 * MS)
    assert est.offset_ns == EPOCH + 3 * MS  # unchanged by peek
    assert peeked == est.update(200, EPOCH + 201 * MS) == EPOCH + 201 * MS


def test_lead_flags_a_forward_jump():
    est = BootTimeOffset(window_s=10.0)
    est.update(1000, EPOCH + 1002 * MS)
    assert est.lead_ns(1100, EPOCH + 1102 * MS) == 0
    assert est.lead_ns(1000 + 3_600_000, EPOCH + 1102 * MS) > S  # an hour ahead: corrupt


def cmd(t1: float = 10.0, t2: float = 10.0) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=0, thrust_port_n=t1, thrust_starboard_n=t2)


def test_watchdog_stale_until_first_command_then_trips_and_recovers():
    wd = ThrustWatchdog(timeout_s=0.3)
    assert wd.stale and wd.active(0) is None and wd.deadline_ns() is None
    event = wd.command(cmd(), 1 * S)
    assert event is not None and not event.stale
    assert wd.active(1 * S + 299 * MS) is not None
    assert wd.check(1 * S + 299 * MS) is None
    # exactly at the timeout the command is no longer applied, and check reports the trip once
    assert wd.active(1 * S + 300 * MS) is None
    event = wd.check(1 * S + 300 * MS)
    assert event is not None and event.stale and event.silent_for_ns == 300 * MS
    assert wd.check(1 * S + 400 * MS) is None and wd.trips == 1
    # commands return: fresh again, with an event saying so
    event = wd.command(cmd(5.0, -5.0), 2 * S)
    assert event is not None and not event.stale
    assert wd.active(2 * S).thrust_port_n == 5.0


def test_watchdog_each_command_restarts_the_timeout():
    wd = ThrustWatchdog(timeout_s=0.3)
    assert wd.command(cmd(), 0) is not None  # stale -> fresh
    for k in range(1, 10):  # every 200 ms: never stale, so no events
        assert wd.check(k * 200 * MS) is None
        assert wd.command(cmd(), k * 200 * MS) is None
    assert wd.deadline_ns() == 9 * 200 * MS + 300 * MS
    assert wd.check(9 * 200 * MS + 299 * MS) is None


def test_watchdog_rejects_bad_timeout():
    with pytest.raises(ValueError):
        ThrustWatchdog(0.0)
