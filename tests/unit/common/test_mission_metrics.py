"""seaway.vessel.metrics: the paper's metrics over message sequences, cases worked out by hand.

The report (``seaway report``) and the in-process closed loop both compute their figures with this.
"""

from __future__ import annotations

import math
from types import SimpleNamespace as S

import pytest
from seaway.contract.units import NS_PER_S
from seaway.vessel import metrics
from seaway.vessel.metrics import (
    MAX_GRID_SAMPLES,
    energy_used_at,
    median,
    mission_metrics,
    percentile,
    rms,
    truth_energy_used,
)

NS = NS_PER_S
WPS = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]


def pose(t_s: float, x: float, y: float, **kw) -> S:
    return S(stamp_ns=round(t_s * NS), x_m=x, y_m=y, **kw)


def straight_run(speed: float = 1.0, offset: float = 0.5, dt: float = 0.1):
    """North along x at ``offset`` east of leg 1, then east along y at ``offset`` south of x = 10."""
    out = []
    t = 0.0
    x, y = 0.0, offset
    while x < 10.0 - 1e-9:
        out.append(pose(t, x, y))
        x += speed * dt
        t += dt
    x = 10.0 - offset
    while y < 10.5:
        out.append(pose(t, x, y))
        y += speed * dt
        t += dt
    return out


def test_travel_time_legs_and_cross_track_outside_circles() -> None:
    states = straight_run()
    m = mission_metrics(states, WPS, 1.0, 0.0, energy_j=[0.0] * len(states))
    assert m.completed and m.legs_completed == 2
    # Leg 1: from y = 0.5 at x = 0 ... the circle of P1 (r = 1) is entered where (x-10)^2 + 0.25 <= 1,
    # i.e. x >= 10 - sqrt(0.75) = 9.134 -> the first sample at x = 9.2, t = 9.2 s. Leg 2 then runs at
    # x = 9.5 and the circle of P2 is entered at y >= 10 - sqrt(0.75): y = 9.2 (0.5 + 8.7), t = 10 + 8.7.
    ends = [s for s in states if math.hypot(s.x_m - 10, s.y_m - 10) <= 1.0]
    assert m.end_ns == ends[0].stamp_ns
    assert m.travel_time_s == pytest.approx(ends[0].stamp_ns / NS)
    # Every counted sample is 0.5 m from its leg's line, so the average and maximum are 0.5.
    assert m.avg_cross_track_m == pytest.approx(0.5)
    assert m.max_cross_track_m == pytest.approx(0.5)
    # Samples inside a circle are not counted: those at P0 (x < ~0.87) and near P1 are left out.
    inside = sum(1 for s in states if s.stamp_ns <= m.end_ns
                 and any(math.hypot(s.x_m - a, s.y_m - b) <= 1.0 for a, b in WPS))
    assert m.cross_track_samples == m.state_samples - inside


def test_mission_start_and_energy_from_cumulative_energy() -> None:
    states = straight_run()
    # Propulsion energy grows 2 J per second; T^w = 0.5 W.
    energy = [2.0 * s.stamp_ns / NS for s in states]
    m = mission_metrics(states, WPS, 1.0, 0.5, energy_j=energy, mission_start_ns=3 * NS,
                        state_source="sim/truth")
    assert m.start_ns == 3 * NS
    dur = (m.end_ns - 3 * NS) / NS
    assert m.travel_time_s == pytest.approx(dur)
    assert m.propulsion_energy_j == pytest.approx(2.0 * dur)
    assert m.task_energy_j == pytest.approx(0.5 * dur)
    assert m.energy_j == pytest.approx(2.5 * dur)
    assert m.energy_source == "sim/truth energy_j"



def test_the_truth_side_energy_used_is_the_reports() -> None:
    # The energy used that benches and the band's measurement read off the sim's truth is the
    # metrics' energy between the same two stamps; a lookup takes the newest sample at or before.
    states = [pose(s.stamp_ns / NS, s.x_m, s.y_m, energy_j=2.0 * s.stamp_ns / NS) for s in straight_run()]
    m = mission_metrics(states, WPS, 1.0, 0.5, energy_j=[s.energy_j for s in states], mission_start_ns=3 * NS)
    used = truth_energy_used(states, 0.5)
    assert energy_used_at(used, m.end_ns) - energy_used_at(used, m.start_ns) == pytest.approx(m.energy_j)
    assert energy_used_at(used, 3 * NS + NS // 20) == energy_used_at(used, 3 * NS)  # between samples
    assert energy_used_at(used, -1) == used[0][1]  # before the first: the first


def test_energy_from_thrusts_held_until_the_next_one() -> None:
    states = straight_run()
    # Thrust commands every 0.5 s, alternating 1 N / 3 N on both thrusters, from t = 0.
    thrusts = [S(stamp_ns=k * NS // 2, thrust_port_n=1.0 + 2 * (k % 2), thrust_starboard_n=1.0 + 2 * (k % 2))
               for k in range(100)]
    alpha = 0.5
    m = mission_metrics(states, WPS, 1.0, 0.0, alpha_w_per_n2=alpha, thrusts=thrusts, mission_start_ns=0)
    end_s = m.end_ns / NS
    # Power is alpha * 2 * T^2: 1 W for 1 N, 9 W for 3 N, each for half a second.
    expected = 0.0
    for k in range(100):
        a, b = k * 0.5, min((k + 1) * 0.5, end_s)
        if b > a:
            expected += alpha * 2 * (1.0 + 2 * (k % 2)) ** 2 * (b - a)
    assert m.propulsion_energy_j == pytest.approx(expected)
    assert m.energy_check_j is None


def test_truth_energy_checked_against_the_thrust_integral() -> None:
    states = straight_run()
    alpha = 0.4
    # SimTruth-like samples: constant 2 N each, energy integrated forward as a simulator would.
    truth = [pose(s.stamp_ns / NS, s.x_m, s.y_m, thrust_port_n=2.0, thrust_starboard_n=2.0,
                  energy_j=alpha * 8.0 * s.stamp_ns / NS) for s in states]
    m = mission_metrics(truth, WPS, 1.0, 0.49, alpha_w_per_n2=alpha, thrusts=truth,
                        energy_j=[t.energy_j for t in truth])
    assert m.energy_check_j == pytest.approx(m.energy_j)


def test_cross_track_uses_a_point_every_sample_period_at_higher_rates() -> None:
    # 50 Hz states, offset 0.5 m on even 0.1 s ticks and 1.5 m in between: on the 0.1 s grid only the
    # 0.5 m samples count.
    states = []
    for k in range(0, 2000):
        t = k * 0.02
        x = 0.2 * t
        if x > 10.5:
            break
        states.append(pose(t, x, 0.5 if k % 5 == 0 else 1.5))
    m = mission_metrics(states, WPS, 1.0, 0.0, energy_j=[0.0] * len(states))
    assert not m.completed  # never reaches P2
    assert m.travel_time_s is None
    assert m.avg_cross_track_m == pytest.approx(0.5)
    full = mission_metrics(states, WPS, 1.0, 0.0, energy_j=[0.0] * len(states), sample_period_s=0.02)
    assert full.avg_cross_track_m == pytest.approx((0.5 + 4 * 1.5) / 5, rel=0.02)


def test_errors_name_what_is_missing() -> None:
    with pytest.raises(ValueError, match="no state samples"):
        mission_metrics([], WPS, 1.0, 0.0, energy_j=[])
    with pytest.raises(ValueError, match="vessel file"):
        mission_metrics(straight_run(), WPS, 1.0, 0.0)
    with pytest.raises(ValueError, match="after the mission started"):
        mission_metrics(straight_run(), WPS, 1.0, 0.0, energy_j=[0.0] * len(straight_run()),
                        mission_start_ns=10**15)


def test_a_span_beyond_the_grid_s_bound_is_refused_not_walked(monkeypatch) -> None:
    """One state stamped 10^9 s ahead asked for 10^10 grid samples (all the memory there was)."""
    far = [pose(0.0, 0.0, 0.5), pose(0.1, 0.1, 0.5), S(stamp_ns=10**18, x_m=0.2, y_m=0.5)]
    with pytest.raises(ValueError, match=r"\(nav/state\) span 1e\+09 s .* at most 55\.6 h "
                                         r"\(2000000 samples of 0\.1 s\)"):
        mission_metrics(far, WPS, 1.0, 0.0, energy_j=[0.0] * 3, state_source="nav/state")
    assert MAX_GRID_SAMPLES == 2_000_000
    # A wall clock stepped mid-mission (GPS time reaching a computer booted at 1970): the refusal
    # says where the gap is, after how long.
    stepped = [pose(0.0, 0.0, 0.5), pose(0.1, 0.1, 0.5),
               S(stamp_ns=100_000_000 + 1_796_000_000 * 10**9, x_m=0.2, y_m=0.5)]
    with pytest.raises(ValueError, match=r"largest gap between two of them is 1\.796e\+09 s, "
                                         r"after 0\.1 s"):
        mission_metrics(stepped, WPS, 1.0, 0.0, energy_j=[0.0] * 3, state_source="nav/state")
    # At the bound itself the span is walked; one sample over, refused (a smaller bound, to be quick).
    monkeypatch.setattr(metrics, "MAX_GRID_SAMPLES", 100)
    edge = [pose(0.0, 5.0, 0.5), pose(10.0, 5.2, 0.5)]  # outside the circles: every sample counts
    assert mission_metrics(edge, WPS, 1.0, 0.0, energy_j=[0.0] * 2).cross_track_samples == 100
    with pytest.raises(ValueError, match=r"span 10\.1 s"):
        mission_metrics([*edge[:1], pose(10.1, 5.2, 0.5)], WPS, 1.0, 0.0, energy_j=[0.0] * 2)
    with pytest.raises(ValueError, match="sample_period_s must be > 0"):
        mission_metrics(edge, WPS, 1.0, 0.0, energy_j=[0.0] * 2, sample_period_s=0.0)


def test_the_end_instant_is_not_a_cross_track_sample():
    # A run stopped off the line: the samples cover [start, end), so where it stopped does not count.
    states = [pose(0.1 * k, 2.0 + 0.1 * k, 0.5) for k in range(30)]
    states.append(pose(3.0, 5.0, 4.0))  # the last sample, 4 m off the line
    m = mission_metrics(states, WPS, 1.0, 0.0, energy_j=[0.0] * len(states))
    assert not m.completed
    assert m.cross_track_samples == 30 and m.avg_cross_track_m == pytest.approx(0.5)
    assert m.max_cross_track_m == pytest.approx(0.5)


def test_durations_come_from_integer_stamps():
    # 3382 periods of 0.1 s is 338.2 s exactly as a decimal (3382 * 0.1 would be 338.20000000000005).
    states = [S(stamp_ns=k * 100_000_000, x_m=0.01 * k, y_m=0.0) for k in range(3382)]
    states.append(S(stamp_ns=3382 * 100_000_000, x_m=10.0, y_m=10.0))  # in the last circle
    m = mission_metrics(states, WPS, 1.0, 0.5, energy_j=[0.0] * len(states))
    assert m.completed and m.travel_time_s == 338.2
    assert m.task_energy_j == 0.5 * 338.2


def test_statistics():
    assert percentile([5.0, 1.0, 3.0, 2.0, 4.0], 50) == 3.0  # nearest rank on sorted data
    assert percentile([1.0, 2.0, 3.0, 4.0], 99) == 4.0
    assert median([1.0, 2.0, 3.0, 4.0]) == 2.5
    assert rms([3.0, -4.0]) == pytest.approx(math.sqrt(12.5))
    assert all(math.isnan(f([])) for f in (median, rms, lambda v: percentile(v, 50)))
