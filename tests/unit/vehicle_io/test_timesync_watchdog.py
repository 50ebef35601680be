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


def test_a_late_message_gets_its_older_stamp_and_the_ones_after_it_keep_flowing():
    """One message 5 s late (a position stamped with an old fix, a radio that held a packet) is
    neither a reboot nor a reason to refuse what follows: before, it reset the estimate 5 s wrong
    and every later message was refused as "ahead" for good."""
    est = BootTimeOffset(window_s=10.0)
    for k in range(50):  # 5 s of 10 Hz telemetry, 2 ms latency
        est.update(100_000 + 100 * k, EPOCH + (100_000 + 100 * k + 2) * MS)
    late = est.update(100_000, EPOCH + 105_002 * MS)  # boot time 5 s behind the newest
    assert late == EPOCH + 100_002 * MS  # its own (old) time, not its arrival
    for k in range(1, 100):  # the normal ones after it: stamped, each at its own time
        boot = 105_000 + 100 * k
        assert est.update(boot, EPOCH + (boot + 2) * MS) == EPOCH + (boot + 2) * MS
    assert est.resets == 0 and est.rebases == 0


def test_a_reboot_the_link_did_not_show_restarts_the_estimate_after_confirm_s():
    est = BootTimeOffset(window_s=10.0, confirm_s=1.0, confirm_samples=3)
    for k in range(11):  # 1 s of samples: an estimate that stands
        est.update(49_000 + 100 * k, EPOCH + (49_003 + 100 * k) * MS)
    new_epoch = EPOCH + 51 * S  # rebooted 1 s after that: every sample 50 s behind
    stamps = [est.update(100 * k, new_epoch + (100 * k + 6) * MS) for k in range(1, 13)]
    assert (est.resets, est.steps, est.rebases) == (1, 0, 0)
    assert est.offset_ns == new_epoch + 6 * MS
    # Until then (1 s of samples) they were refused: 50 s behind the estimate, more than a window,
    # is no late packet, and an hour-old stamp on the bus would be worse than none.
    assert stamps[:10] == [None] * 10 and est.refused is None
    assert stamps[-1] == new_epoch + 1206 * MS


def test_a_wall_clock_step_is_not_a_reboot():
    """NTP setting the clock of a board without a real-time clock: every sample lands 5 s
    "behind" on the wall clock, but not on the monotonic one. The estimate follows the new wall
    time, and no reboot is counted (a reboot ends the autopilot's latched failsafes)."""
    est = BootTimeOffset(window_s=10.0, confirm_s=1.0, confirm_samples=3)
    step = 5 * S
    stamps = []
    for k in range(40):  # 4 s of 10 Hz telemetry, the wall clock set 5 s ahead at 2 s
        boot, mono = 100_000 + 100 * k, (100_000 + 100 * k + 2) * MS
        wall = EPOCH + mono + (step if k >= 20 else 0)
        stamps.append(est.update(boot, wall, mono))
    assert (est.resets, est.steps, est.rebases) == (0, 1, 0)
    assert stamps[-1] == EPOCH + step + (100_000 + 3900 + 2) * MS  # on the new wall time
    assert None not in stamps  # 5 s behind is within a window: old stamps until confirmed


def test_a_corrupt_first_boot_time_is_a_wrong_estimate_not_a_reboot():
    """The first stamped message after link-up carries time_boot_ms 2^32 - 1: the estimate built
    on it alone is what is wrong when every message after it disagrees."""
    est = BootTimeOffset(window_s=10.0, confirm_s=1.0, confirm_samples=3)
    assert est.update(2**32 - 1, EPOCH + 100_002 * MS) is not None
    stamps = [est.update(100_000 + 100 * k, EPOCH + (100_002 + 100 * k) * MS) for k in range(1, 15)]
    assert (est.resets, est.steps, est.rebases) == (0, 0, 1)
    assert stamps[:10] == [None] * 10  # 49.7 days "behind": refused, never stamped in the past
    assert stamps[-1] == EPOCH + (100_002 + 1400) * MS


def test_system_time_going_back_is_a_reboot_once_the_next_runs_on_from_it():
    est = BootTimeOffset(window_s=10.0)
    est.update(50_000, EPOCH + 50_003 * MS)
    assert not est.system_time(50_010, 50 * S)
    assert not est.system_time(49_500, 50 * S)  # reordered by half a second: not a reboot
    assert not est.system_time(200, 51 * S)  # going back: a reboot, or a stale packet
    assert not est.system_time(51_010, 52 * S)  # the clock runs on where it was: stale
    assert not est.system_time(200, 53 * S)  # the same stale packet, replayed twice
    assert not est.system_time(200, 53 * S + 10 * MS)
    assert not est.system_time(52_510, 53 * S + 500 * MS)  # and the live clock again
    assert est.resets == 0 and est.offset_ns is not None
    assert not est.system_time(1_200, 54 * S)  # going back again, and then running on from it
    assert est.system_time(2_200, 55 * S)
    assert est.resets == 1 and est.offset_ns is None
    new_epoch = EPOCH + 60 * S
    assert est.update(300, new_epoch + 304 * MS) == new_epoch + 304 * MS


def test_a_wrong_estimate_is_rebuilt_from_the_messages_that_contradict_it():
    est = BootTimeOffset(window_s=10.0, confirm_s=1.0, confirm_samples=3)
    # The only sample so far was 5 s late: the estimate is 5 s too large.
    est.update(100_000, EPOCH + 105_002 * MS)
    refused = 0
    for k in range(1, 30):
        boot = 105_000 + 100 * k
        stamp = est.update(boot, EPOCH + (boot + 2) * MS)
        if stamp is None:
            refused += 1
        else:
            assert stamp == EPOCH + (boot + 2) * MS
    assert est.rebases == 1
    assert 1 <= refused <= 10  # refused for about confirm_s, then right again


def test_stamp_does_not_record_until_commit():
    est = BootTimeOffset(window_s=10.0)
    est.update(100, EPOCH + 103 * MS)
    peeked = est.stamp(200, EPOCH + 201 * MS)
    assert est.offset_ns == EPOCH + 3 * MS  # unchanged by stamp
    est.commit(200, EPOCH + 201 * MS)
    assert peeked == EPOCH + 201 * MS and est.offset_ns == EPOCH + 1 * MS


def test_a_forward_jump_is_refused():
    est = BootTimeOffset(window_s=10.0)
    est.update(1000, EPOCH + 1002 * MS)
    assert est.stamp(1100, EPOCH + 1102 * MS) == EPOCH + 1102 * MS
    assert est.stamp(1000 + 3_600_000, EPOCH + 1102 * MS) is None  # an hour ahead: corrupt


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
