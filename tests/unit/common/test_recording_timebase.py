"""The recording's time convention (``seaway.recording.timebase``): in lockstep every log time is the
sim time on the run's epoch (pure: no clock read, times passed in)."""

from __future__ import annotations

import datetime as dt

import pytest
from seaway.contract import keys
from seaway.recording.timebase import RecordingTime, parse_epoch

V = "v1"
E = 1_780_000_000_000_000_000  # the run's epoch [ns]
TRUTH = keys.SIM_TRUTH.key(V)
STATE = keys.NAV_STATE.key(V)


def test_real_time_keeps_receive_times_and_stamps() -> None:
    t = RecordingTime.real_time()
    assert t.bus(TRUTH, 123, 456) == 456
    assert t.wall(789) == 789
    assert t.foxglove_ns(123) == 123
    assert t.metadata()["log_time"] == "receive"


def test_lockstep_logs_sim_time_on_the_epoch_and_places_wall_events_in_sim_time() -> None:
    t = RecordingTime(lockstep=True, epoch_ns=E)
    w0 = 1_790_000_000_000_000_000  # wall time the sim started at
    assert t.wall(w0 - 5_000_000_000) == E  # before the sim's first sample: its start
    # Sim time runs 10x faster than the wall here: 1 s of sim per 0.1 s of wall.
    for k in range(5):
        assert t.bus(TRUTH, k * 1_000_000_000, w0 + k * 100_000_000) == E + k * 1_000_000_000
        assert t.foxglove_ns(k * 1_000_000_000) == E + k * 1_000_000_000
    # Something at a wall time between two samples happened at the sim time reached then.
    assert t.wall(w0 + 250_000_000) == E + 2_000_000_000
    assert t.wall(w0 + 10_000_000_000) == E + 4_000_000_000
    # A wall-clock stamp (a process not on the sim clock) is placed where it arrived.
    assert t.bus(keys.VEHICLE_STATUS.key(V), w0 + 150_000_000, w0 + 150_000_000) == E + 1_000_000_000
    meta = t.metadata()
    assert (meta["log_time"], meta["epoch_ns"]) == ("sim", str(E))


def test_a_new_lockstep_episode_continues_the_timeline() -> None:
    t = RecordingTime(lockstep=True, epoch_ns=E, gap_ns=100_000_000)
    for k in range(31):  # episode 0: 0 .. 3 s
        t.bus(TRUTH, k * 100_000_000, 1000 + k)
    assert t.bus(TRUTH, 0, 2000) == E + 3_100_000_000  # time back to 0: a new episode
    assert t.bus(STATE, 0, 2001) == E + 3_100_000_000
    assert t.new_episodes == [{"episode": "1", "offset_ns": str(E + 3_100_000_000),
                               "offset_utc": dt.datetime.fromtimestamp((E + 3_100_000_000) / 1e9,
                                                                       dt.UTC).isoformat(
                                   timespec="milliseconds")}]
    assert t.bus(TRUTH, 100_000_000, 2002) == E + 3_200_000_000


def test_a_members_absurd_stamp_moves_neither_the_timeline_nor_later_episodes() -> None:
    """A controller's message stamped 10**17 - 1 ns (3.17 years, just under the wall-clock limit)
    was logged 3.17 years on, became the anchor for wall-timed records, and at the next sim restart
    shifted every later message of the run by 3.17 years."""
    t = RecordingTime(lockstep=True, epoch_ns=E, gap_ns=100_000_000)
    w0 = 1_790_000_000_000_000_000
    for k in range(11):  # 0 .. 1 s
        t.bus(TRUTH, k * 100_000_000, w0 + k)
        assert t.bus(STATE, k * 100_000_000, w0 + k) == E + k * 100_000_000  # members: as ever
    ctrl = keys.MISSION_STATUS.key(V)
    assert t.bus(ctrl, 10**17 - 1, w0 + 20) == E + 1_000_000_000  # at the time reached
    assert t.bus(ctrl, 1_200_000_000, w0 + 21) == E + 1_200_000_000  # two periods ahead: its own
    assert t.wall(w0 + 30) == E + 1_000_000_000  # wall-timed records: not 3 years on
    assert t.bus(TRUTH, 0, w0 + 40) == E + 1_100_000_000  # a sim restart: on from the sim's end
    assert t.new_episodes[-1]["offset_ns"] == str(E + 1_100_000_000)


def test_sim_epoch_option() -> None:
    assert parse_epoch("2026-05-01T09:00:00Z") == int(dt.datetime(2026, 5, 1, 9, tzinfo=dt.UTC)
                                                      .timestamp()) * 10**9
    assert parse_epoch("2026-05-01T09:00:00") == parse_epoch("2026-05-01T09:00:00+00:00")
    assert parse_epoch("1780000000.5") == 1_780_000_000_500_000_000
    with pytest.raises(ValueError, match="ISO 8601"):
        parse_epoch("yesterday")
