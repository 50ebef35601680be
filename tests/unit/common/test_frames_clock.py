"""Frames (geodetic <-> NED, wrapping) and clocks (drift-free loop, simulated time)."""

from __future__ import annotations

import math
import threading

import pytest
from seaway.runtime.clock import RateLoop, SimClock
from seaway.vessel.frames import GeoOrigin, wrap_2pi, wrap_pi


@pytest.mark.parametrize(("a", "w"), [(0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi),
                                      (3 * math.pi / 2, -math.pi / 2), (7.0, 7.0 - 2 * math.pi),
                                      (-7.0, -7.0 + 2 * math.pi)])
def test_wrap_pi(a: float, w: float) -> None:
    assert wrap_pi(a) == pytest.approx(w)
    assert -math.pi < wrap_pi(a) <= math.pi


def test_wrap_2pi() -> None:
    assert wrap_2pi(-0.5) == pytest.approx(2 * math.pi - 0.5)
    assert wrap_2pi(2 * math.pi) == pytest.approx(0.0)


def test_ned_round_trip_and_scale() -> None:
    o = GeoOrigin(math.radians(47.0), math.radians(8.0), 400.0)
    for n, e, d in [(0, 0, 0), (100.0, -250.0, 0.0), (-3000.0, 4000.0, -5.0), (0.01, 0.02, 0.0)]:
        lat, lon, alt = o.to_geodetic(n, e, d)
        back = o.to_ned(lat, lon, alt)
        assert back == pytest.approx((n, e, d), abs=1e-6)
    # One arc-second of latitude is about 30.9 m at 47 deg; of longitude, 30.9 * cos(47 deg).
    n, e, _ = o.to_ned(math.radians(47.0 + 1 / 3600), math.radians(8.0 + 1 / 3600), 400.0)
    assert n == pytest.approx(30.88, abs=0.05)
    assert e == pytest.approx(21.13, abs=0.05)


class FakeMonotonic:
    """A clock whose time moves only when the loop sleeps, plus injected work."""

    def __init__(self) -> None:
        self.t = 1_000

    def now_ns(self) -> int:
        return self.t

    monotonic_ns = now_ns

    def sleep_until(self, t: int, stop: threading.Event) -> bool:
        self.t = max(self.t, t)
        return not stop.is_set()


def test_rate_loop_is_drift_free_and_counts_overruns() -> None:
    clk, stop = FakeMonotonic(), threading.Event()
    loop = RateLoop(0.1, clk, stop)
    ticks = []
    for k in range(50):
        assert loop.wait()
        ticks.append(clk.t)
        clk.t += 3_000_000 if k != 20 else 350_000_000  # work: 3 ms, once 350 ms
    period = 100_000_000
    off_grid = [k for k, t in enumerate(ticks) if (t - ticks[0]) % period]
    # After the 350 ms overrun at tick 20, ticks 21 and 22 are skipped, 23 runs late (at once),
    # and from 24 on the loop is back on the grid t0 + k * period: no drift accumulates.
    assert off_grid == [21]
    assert loop.skipped == 2
    assert ticks[-1] == ticks[0] + (50 - 1 + 2) * period


def test_rate_loop_stops() -> None:
    stop = threading.Event()
    loop = RateLoop(0.1, FakeMonotonic(), stop)
    assert loop.wait()
    stop.set()
    assert not loop.wait()


def test_sim_clock_wakes_waiters_and_refuses_going_back() -> None:
    clk, stop = SimClock(), threading.Event()
    done = []
    th = threading.Thread(target=lambda: done.append(clk.sleep_until(500, stop)))
    th.start()
    clk.set(200)
    assert not done
    clk.set(600)
    th.join(2)
    assert done == [True]
    with pytest.raises(ValueError, match="cannot go back"):
        clk.set(100)


def test_a_step_of_the_wall_clock_is_seen_and_a_slew_is_not() -> None:
    """NTP slews by at most 0.5 ms a second; NTP or GPS time setting a computer with no real-time
    clock steps it: by an hour, or by 56 years after a boot at 1970."""
    from seaway.runtime.clock import WALL_STEP_MIN_NS, WallStepWatch

    s = 1_000_000_000
    w = WallStepWatch()
    assert w.look(86_400 * s, 5 * s) is None  # the first look: nothing to compare
    assert [w.look(86_400 * s + k * s // 20 + k * 25_000, 5 * s + k * s // 20)  # 0.5 ms/s slew
            for k in range(1, 200)] == [None] * 199
    mono = 20 * s
    assert w.look(1_796_000_000 * s, mono) == 1_796_000_000 * s - 86_400 * s - 15 * s - 199 * 25_000
    assert w.look(1_796_000_000 * s + s // 20, mono + s // 20) is None  # on the new clock now
    assert w.look(1_796_000_000 * s - 3600 * s, mono + s // 10) == -3600 * s - s // 10
    # Just under the least step: none.
    w2 = WallStepWatch()
    w2.look(0, 0)
    assert w2.look(WALL_STEP_MIN_NS - 1, 0) is None and w2.look(2 * WALL_STEP_MIN_NS, 0) is not None
