"""Stamp bounds (``seaway.runtime.stamps``) and the lockstep ledger's use of them: a stamp far ahead
(10 s, 10^4000 ns) or far behind is judged, counted, dropped and logged once; nothing it can make a
receiver do is unbounded."""

from __future__ import annotations

import logging

import pytest
from seaway.contract.messages import PeriodDone
from seaway.runtime.lockstep import Ledger
from seaway.runtime.stamps import (
    LOCKSTEP_AHEAD_PERIODS,
    MAX_AHEAD_LIVE_S,
    StampBounds,
    StampGate,
    describe_ns,
)

S = 1_000_000_000
NOW = 1_800_000_000 * S
HUGE = 10**4000
LOGGER = "test.stamps"


def test_live_bounds() -> None:
    b = StampBounds.live(behind_s=30.0)
    assert b.judge(NOW, NOW) is None
    assert b.judge(NOW + round(MAX_AHEAD_LIVE_S * S), NOW) is None  # the bound itself is allowed
    assert b.judge(NOW + round(MAX_AHEAD_LIVE_S * S) + 1, NOW) == "ahead"
    assert b.judge(NOW + 10 * S, NOW) == "ahead"
    assert b.judge(HUGE, NOW) == "ahead"
    assert b.judge(NOW - 30 * S, NOW) is None
    assert b.judge(NOW - 30 * S - 1, NOW) == "behind"
    assert b.judge(1, NOW) == "behind"  # the epoch
    assert StampBounds.live().judge(0, NOW) is None  # no behind bound: any age


def test_lockstep_bounds() -> None:
    period = S // 10
    b = StampBounds.lockstep(period)
    assert b.judge(5 * S + LOCKSTEP_AHEAD_PERIODS * period, 5 * S) is None
    assert b.judge(5 * S + LOCKSTEP_AHEAD_PERIODS * period + 1, 5 * S) == "ahead"
    assert b.judge(0, 5 * S) is None  # a new episode starts again at 0: never "behind"
    with pytest.raises(ValueError, match="must be >= 0"):
        StampBounds(-1)


def test_durations_for_people_even_absurd_ones() -> None:
    assert describe_ns(10 * S) == "10.000 s"
    assert describe_ns(HUGE) == "about 10^3991 s"  # a float could not hold it


def test_gate_counts_drops_and_logs_once_per_key_and_direction(caplog) -> None:
    caplog.set_level(logging.INFO, LOGGER)
    gate = StampGate("estimator", logging.getLogger(LOGGER), StampBounds.live(behind_s=30.0))
    assert gate.admit("ctrl/thrust", NOW, NOW)
    for i in range(100):
        assert not gate.admit("ctrl/thrust", NOW + 10 * S, NOW, now_ns=i)
    assert not gate.admit("ctrl/thrust", HUGE, NOW, now_ns=200)
    assert not gate.admit("sensors/gnss", 1, NOW, now_ns=300)
    assert gate.dropped == {("ctrl/thrust", "ahead"): 101, ("sensors/gnss", "behind"): 1}
    assert gate.total == 102
    assert gate.summary() == "ctrl/thrust ahead 101, sensors/gnss behind 1"
    msgs = [r.getMessage() for r in caplog.records if r.name == LOGGER]
    assert len(msgs) == 2 and all(r.levelno == logging.WARNING for r in caplog.records)
    assert "estimator: dropped a message on ctrl/thrust stamped 10.000 s ahead" in msgs[0]
    assert "allowed: up to 1.000 s ahead, 30.000 s behind" in msgs[0]
    assert "on sensors/gnss" in msgs[1] and "behind" in msgs[1]
    # Unknown reference time (a lockstep member before its first period): nothing to judge by.
    assert gate.admit("ctrl/thrust", HUGE, None)


def test_gate_counting_is_bounded_in_keys() -> None:
    gate = StampGate("x", logging.getLogger(LOGGER), StampBounds(0))
    for i in range(500):
        gate.admit(f"key/{i}", 10, 0)
    assert len(gate.dropped) <= 65 and gate.total == 500


def _tick(t_ns: int, period_ns: int = S // 10) -> PeriodDone:
    return PeriodDone(stamp_ns=t_ns, service="sim", episode=0, seq=t_ns, period_ns=period_ns)


def test_the_ledger_does_not_keep_stamps_no_period_can_list() -> None:
    """While the sim holds (no mission), a flood of future-stamped messages must not grow what a
    member keeps: only stamps up to the next periods are noted."""
    ledger = Ledger(watched=None)
    assert ledger.see("ctrl/thrust", HUGE)  # no period yet: nothing to judge by
    ledger.on_answer(_tick(5 * S))
    assert ledger.see("sensors/gnss", 5 * S + S // 10)  # the next period's sample, early
    for i in range(1000):
        assert not ledger.see("ctrl/thrust", 5 * S + 10 * S + i)
    assert not ledger.seen.get("ctrl/thrust")  # (HUGE went at the first period: after t_k)
    assert ledger.seen["sensors/gnss"] == {5 * S + S // 10}
