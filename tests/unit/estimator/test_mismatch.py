"""The motion fault detector (``seaway_estimator.mismatch``), pure: synthetic GNSS fix sequences in,
the fault's onsets and clearings out. A vessel that does not follow its thrust is named after the
persistence time, once; noise, one outlier, a dropout, a faster plant are not faults; it clears with
hysteresis."""

from __future__ import annotations

import math
import random
from fractions import Fraction

from seaway_estimator.mismatch import FixSample, MismatchConfig, MotionMismatch

S = 1_000_000_000
GNSS_NS = S // 5  # 5 Hz
SOG_NOISE_MPS = 0.05  # per axis, as the paper-boat's receiver


def feed(det: MotionMismatch, t0_s: float, t1_s: float, commanded_mps: float, measured_mps: float,
         reject_every: int = 0, nis: float = 2.0, rng: random.Random | None = None) -> list:
    """Fixes at 5 Hz over [t0, t1): events seen. The vessel runs north at ``measured_mps``."""
    events = []
    for k in range(round(t0_s * 5), round(t1_s * 5)):
        t = k * GNSS_NS
        noise = rng.gauss(0.0, SOG_NOISE_MPS) if rng else 0.0
        rejected = reject_every > 0 and k % reject_every == 0
        ev = det.on_fix(FixSample(t, measured_mps * t / S, 0.0, rejected, 18.42 if rejected else nis,
                                  measured_mps + noise, commanded_mps))
        if ev is not None:
            events.append(ev)
    return events


def onset_s(events) -> float:
    return next(e.t_ns / S for e in events if e.kind is not None)


def test_commanded_but_still_is_not_moving_after_the_persistence_time_once() -> None:
    det = MotionMismatch(MismatchConfig())
    assert feed(det, 0, 20, 0.9, 0.9) == [] and det.kind is None
    events = feed(det, 20, 60, 0.9, 0.0)
    assert [e.kind for e in events] == ["not_moving"]  # once per onset, not per sample
    # The window's mean falls under 30 % of the command after 3.5 s of 5; then 3 s of persistence.
    assert 20 + 3.0 <= onset_s(events) <= 20 + 5.0 + 3.0 + 0.2
    assert det.kind == "not_moving" and "commanded 0.900 m/s, measured 0.000 m/s" in det.detail


def test_it_clears_after_moving_as_commanded_for_clear_s_not_before() -> None:
    det = MotionMismatch(MismatchConfig())
    feed(det, 0, 30, 0.9, 0.0)
    assert det.kind == "not_moving"
    events = feed(det, 30, 60, 0.9, 0.9)
    cleared = [e for e in events if e.kind is None]
    assert len(cleared) == 1 and "moves as commanded again" in cleared[0].detail
    # The window must first hold agreement (mean above 30 %), then 5 s of it.
    assert 30 + 5.0 <= cleared[0].t_ns / S <= 30 + 5.0 + 5.0 + 0.2


def test_with_nothing_commanded_it_clears_only_after_idle_clear_s() -> None:
    det = MotionMismatch(MismatchConfig())
    feed(det, 0, 30, 0.9, 0.0)
    events = feed(det, 30, 100, 0.0, 0.0)
    t_clear = [e.t_ns / S for e in events if e.kind is None]
    # The slow window still holds the commanded seconds that did not move the vessel (up to 30 s),
    # then 15 s without suspicion.
    assert len(t_clear) == 1 and 30 + 15.0 <= t_clear[0] <= 30 + 30.0 + 15.0 + 0.2


def test_noise_an_outlier_and_a_dropout_are_not_faults() -> None:
    det = MotionMismatch(MismatchConfig())
    rng = random.Random(3)
    assert feed(det, 0, 600, 0.3, 0.3, rng=rng) == []
    assert feed(det, 600, 700, 0.3, 0.3, reject_every=40, nis=2.0, rng=rng) == []  # lone outliers
    # A dropout: no fixes for 20 s, then the vessel as before: no verdict on a short window.
    assert feed(det, 720, 760, 0.3, 0.3, rng=rng) == []
    assert det.onsets == 0


def test_a_stuck_suspicion_shorter_than_the_persistence_time_is_not_a_fault() -> None:
    det = MotionMismatch(MismatchConfig(onset_s=3.0))
    feed(det, 0, 20, 0.9, 0.9)
    assert feed(det, 20, 24, 0.9, 0.0) == []  # the window's mean crosses at ~23.5 s: 0.5 s suspicious
    assert feed(det, 24, 60, 0.9, 0.9) == []


def test_rejections_while_slower_than_commanded_are_not_as_modelled() -> None:
    det = MotionMismatch(MismatchConfig())
    events = feed(det, 0, 30, 0.9, 0.6, reject_every=2)  # half the fixes gated out, 2/3 the speed
    assert [e.kind for e in events] == ["not_as_modelled"]
    assert "50% of the fixes gated out" in det.detail


def test_rejections_on_a_plant_faster_than_its_model_are_not_a_fault() -> None:
    det = MotionMismatch(MismatchConfig())
    assert feed(det, 0, 60, 0.6, 0.75, reject_every=2) == []


def test_a_slow_economic_cruise_that_stops_is_seen_over_the_slow_window() -> None:
    det = MotionMismatch(MismatchConfig())
    rng = random.Random(5)
    assert feed(det, 0, 400, 0.045, 0.045, rng=rng) == []  # the paper vessel's cruise, with noise
    events = feed(det, 400, 460, 0.045, 0.0, rng=rng)
    assert [e.kind for e in events] == ["not_moving"]
    assert 400 + 20.0 <= onset_s(events) <= 400 + 30.0 + 3.0 + 0.2


def test_disabled_detects_nothing() -> None:
    det = MotionMismatch(MismatchConfig(enabled=False))
    assert feed(det, 0, 60, 0.9, 0.0) == [] and det.kind is None


def test_positions_alone_give_the_speed_when_fixes_have_no_velocity() -> None:
    det = MotionMismatch(MismatchConfig())
    for moving, want in ((0.9, None), (0.0, "not_moving")):
        det = MotionMismatch(MismatchConfig())
        for k in range(150):
            t = k * GNSS_NS
            det.on_fix(FixSample(t, moving * t / S, 0.0, False, 2.0, None, 0.9))
        assert det.kind == want
    assert math.isfinite(det.last.measured_mps)


def _window_verdict(fixes: list[FixSample], c: MismatchConfig) -> tuple[float, float, float, float]:
    """(commanded, measured, reject rate, mean NIS) of the fast window, summed afresh, exactly."""
    w = [s for s in fixes if s.t_ns >= fixes[-1].t_ns - round(c.window_s * 1e9)]

    def mean(xs: list[float]) -> float:
        return float(sum(map(Fraction, xs)) / len(xs))  # the exact mean, rounded once
    return (mean([s.commanded_mps for s in w]), mean([s.surge_over_ground_mps or 0.0 for s in w]),
            sum(s.rejected for s in w) / len(w), mean([s.nis for s in w]))


def test_the_window_sums_kept_over_a_long_run_are_the_window_summed_afresh() -> None:
    # The sums are kept as fixes come and go (a verdict is O(1)); a float sum kept that way drifts
    # (a large value added then taken out leaves its rounding behind), so after ten thousand fixes
    # of wildly mixed sizes the kept sums must still be those of the window summed afresh.
    c = MismatchConfig()
    det = MotionMismatch(c)
    rng = random.Random(7)
    fixes: list[FixSample] = []
    for k in range(10_000):
        big = k % 97 == 0
        s = FixSample(k * 200_000_000, 0.0, 0.0, rng.random() < 0.1,
                      rng.uniform(0.0, 9.0) * (1e12 if big else 1.0),
                      rng.uniform(0.0, 0.5) * (1e15 if big else 1.0),
                      rng.uniform(0.0, 0.5) + (1e16 if big else 0.0))
        fixes.append(s)
        det.on_fix(s)
    v = det.last
    assert v is not None
    assert (v.commanded_mps, v.measured_mps, v.reject_rate, v.mean_nis) == _window_verdict(fixes, c)
