"""seaway.simkit.sensors: noise statistics, SOG, dropouts, schedule and bit-exact reproducibility."""

from __future__ import annotations

import itertools
import math
import statistics

import pytest
from seaway.contract.config import Origin
from seaway.simkit.scenario import SensorNoise
from seaway.simkit.sensors import GnssDropouts, SensorSuite, instants_in, origin_of

ORIGIN = Origin(lat_deg=28.18, lon_deg=112.94, alt_m=30.0)
STATE = [1.0, 0.2, 0.05, 12.0, -7.0, math.pi / 2]  # u, v, r, x north, y east, psi (heading east)


def suite(seed: int = 3, **noise) -> SensorSuite:
    return SensorSuite(SensorNoise(**noise), ORIGIN, seed)


def test_noise_free_gnss_is_the_true_position_and_velocity_over_ground() -> None:
    fix = suite().gnss(1_000, STATE, (0.02, -0.03), epoch_ns=5)
    assert fix is not None and fix.stamp_ns == 1_005
    north, east, _ = origin_of(ORIGIN).to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m)
    assert (north, east) == pytest.approx((12.0, -7.0), abs=1e-6)
    # Heading east: surge goes east, sway (to starboard) goes south; plus the current.
    assert fix.vel_n_mps == pytest.approx(-0.2 + 0.02, abs=1e-12)
    assert fix.vel_e_mps == pytest.approx(1.0 - 0.03, abs=1e-12)
    assert fix.alt_m == 30.0 and fix.fix_type == 3


def test_gnss_noise_has_the_scenario_std() -> None:
    s = suite(gnss_std_m=0.3, sog_std_mps=0.05)
    o = origin_of(ORIGIN)
    errs_n, errs_vn = [], []
    for k in range(4000):
        fix = s.gnss(k, STATE, (0.0, 0.0))
        errs_n.append(o.to_ned(fix.lat_rad, fix.lon_rad)[0] - 12.0)
        errs_vn.append(fix.vel_n_mps + 0.2)
    # 4000 samples: the sample std is within ~5 % of sigma with > 99.9 % probability.
    assert statistics.pstdev(errs_n) == pytest.approx(0.3, rel=0.06)
    assert abs(statistics.fmean(errs_n)) < 0.03
    assert statistics.pstdev(errs_vn) == pytest.approx(0.05, rel=0.06)


def test_heading_noise_and_wrapping() -> None:
    s = suite(heading_std_rad=0.02, yaw_rate_std_radps=0.005)
    near_pi = [0, 0, 0.01, 0, 0, math.pi - 1e-4]
    yaws = [s.attitude(k, near_pi).yaw_rad for k in range(2000)]
    assert all(-math.pi < y <= math.pi for y in yaws)
    assert any(y < 0 for y in yaws)  # noise pushed some past pi: wrapped to near -pi
    unwrapped = [y if y > 0 else y + 2 * math.pi for y in yaws]
    assert statistics.pstdev(unwrapped) == pytest.approx(0.02, rel=0.08)
    rates = [s.attitude(k, STATE).yaw_rate_radps for k in range(2000)]
    assert statistics.pstdev(rates) == pytest.approx(0.005, rel=0.08)


def test_same_seed_same_samples_bit_for_bit_and_streams_are_independent() -> None:
    noise = {"gnss_std_m": 0.3, "heading_std_rad": 0.02, "sog_std_mps": 0.1}
    a, b = suite(**noise), suite(**noise)
    for k in range(50):
        assert a.gnss(k, STATE, (0, 0)) == b.gnss(k, STATE, (0, 0))
        assert a.attitude(k, STATE) == b.attitude(k, STATE)
    # Changing the heading noise does not shift the GNSS draws (separate streams).
    c, d = suite(gnss_std_m=0.3), suite(gnss_std_m=0.3, heading_std_rad=0.5)
    for k in range(20):
        d.attitude(k, STATE)
        assert c.gnss(k, STATE, (0, 0)) == d.gnss(k, STATE, (0, 0))
    assert suite(seed=4, **noise).gnss(0, STATE, (0, 0)) != suite(**noise).gnss(0, STATE, (0, 0))


def test_dropouts_follow_a_poisson_process_of_the_given_rate_and_duration() -> None:
    drop = GnssDropouts(seed=11, rate_per_s=0.05, duration_s=2.0)
    step = 100_000_000
    states = [drop.active(k * step) for k in range(100_000)]  # 10,000 s at 10 Hz
    starts = sum(1 for a, b in itertools.pairwise(states) if b and not a)
    # Expected starts ~ 10,000 s / (20 s mean gap + 2 s outage) = 455; Poisson sd ~ 21.
    assert 370 < starts < 540
    # Each outage lasts 2 s: 20 consecutive 0.1 s samples; two outages merge when the exponential
    # gap between them is shorter than a sample (rare at this rate).
    runs, n = [], 0
    for s in states:
        if s:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    assert min(runs) == 20
    assert sum(r == 20 for r in runs) / len(runs) > 0.97


def test_a_fix_due_inside_a_dropout_is_not_produced() -> None:
    s = suite(gnss_dropout_rate_per_s=0.5, gnss_dropout_duration_s=1.0)
    fixes = [s.gnss(k * 200_000_000, STATE, (0, 0)) for k in range(500)]
    assert 0 < sum(f is None for f in fixes) < 500


def test_no_dropouts_when_the_rate_is_zero() -> None:
    drop = GnssDropouts(seed=1, rate_per_s=0.0, duration_s=5.0)
    assert not any(drop.active(k * 10**9) for k in range(1000))


def test_instants_are_multiples_of_the_period_in_the_half_open_interval() -> None:
    assert instants_in(200, 0, 1000) == [200, 400, 600, 800, 1000]
    assert instants_in(200, 200, 399) == []
    assert instants_in(200, 199, 200) == [200]
