"""Valid messages that say what no receiver or vessel does, and stale copies of used ones: refused
or ignored with a counted, logged reason; the rest of the message and every good sample kept; never
a dropped state or a missing, non-finite or absurd estimate (pure core, and the real-time loop)."""

from __future__ import annotations

import logging
import math

import pytest
from seaway.contract.messages import StateEstimate
from seaway.vessel.frames import MAX_RANGE_M
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_estimator.node import EstimatorNode

from tests.unit.estimator.test_core import FIXED, MS, S, att, fix, started

WALL = 1_800_000_000 * S


def _sane(est: StateEstimate | None) -> StateEstimate:
    """A published estimate: there, finite, within the local frame and a vessel's speeds."""
    assert est is not None
    values = [est.u_mps, est.v_mps, est.r_radps, est.x_m, est.y_m, *est.covariance]
    assert all(math.isfinite(v) for v in values)
    assert abs(est.x_m) <= MAX_RANGE_M and abs(est.y_m) <= MAX_RANGE_M
    assert math.hypot(est.u_mps, est.v_mps) < 25.0 and abs(est.r_radps) < 2 * math.pi
    return est


def _kinds(core: EstimatorCore) -> set[str]:
    return {n.kind for n in core.take_notices()}


@pytest.mark.parametrize("std_m", [1e6, 1e200])
def test_a_fix_too_uncertain_to_be_a_position_is_refused_and_the_state_kept(std_m: float) -> None:
    """Before: a run of 25 fixes reporting a std of 1e200 m was gated out, then taken (variance
    inf): 7 periods without an estimate and the state dropped."""
    core = started()
    for k in range(1, 41):
        t = k * 100 * MS
        core.on_gnss(fix(t, 0.0, 0.0, std=std_m if k <= 30 else 0.3))
        core.on_attitude(att(t, 0.0))
        est = _sane(core.predict_to(t))
        if k == 30:  # no position for 3 s: the receiver said so, the estimate must say it too
            assert est.degraded
    assert not est.degraded
    c = core.counters
    assert c["gnss_refused"] == 30 and c["gnss_accepted"] == 10
    assert c["divergence_resets"] == 0 and c["gnss_reinit"] == 0 and c["publish_refused"] == 0
    assert "gnss_refused" in _kinds(core)


def test_a_fix_too_uncertain_never_becomes_the_origin() -> None:
    core = EstimatorCore()  # no configured origin: the first good fix is it
    core.on_gnss(fix(0, 5_000.0, 0.0, std=1e6))
    assert core.origin is None and core.counters["gnss_refused"] == 1
    core.on_gnss(fix(100 * MS, 0.0, 0.0))
    core.on_attitude(att(100 * MS, 0.0))
    est = _sane(core.predict_to(100 * MS))
    assert abs(est.x_m) < 1e-6  # the origin is the good fix, not the refused one 5 km north


def test_a_fix_beyond_the_local_frame_is_refused_not_taken_after_a_run() -> None:
    """Before: fixes 5000 km from the origin were gated out 25 times, then the position was moved
    there and published (x = 3.9e6 m)."""
    core = started()
    for k in range(1, 41):
        t = k * 100 * MS
        core.on_gnss(fix(t, 5e6, 0.0))
        core.on_attitude(att(t, 0.0))
        est = _sane(core.predict_to(t))
        assert abs(est.x_m) < 1.0
    assert core.counters["gnss_refused"] == 40 and core.counters["gnss_reinit"] == 0
    assert "gnss_refused" in _kinds(core)


@pytest.mark.parametrize("vel_n_mps", [1e5, 100.0])
def test_an_absurd_velocity_over_ground_is_refused_and_its_position_kept(vel_n_mps: float) -> None:
    """Before: after 5 rejections the disturbance was re-opened, the velocity taken, and the state
    dropped as past the envelope: at 100 m/s, 26 periods of 30 without an estimate."""
    core = started()
    for k in range(1, 31):
        t = k * 100 * MS
        core.on_gnss(fix(t, 0.0, 0.0, vn=vel_n_mps if k <= 20 else 0.0))
        core.on_attitude(att(t, 0.0))
        est = _sane(core.predict_to(t))
        assert abs(est.u_mps) < 0.5
    c = core.counters
    assert c["sog_refused"] == 20 and c["sog_accepted"] == 10
    assert c["gnss_accepted"] == 30  # the positions of those fixes were used
    assert c["divergence_resets"] == 0 and c["disturbance_reopened"] == 0
    assert "sog_refused" in _kinds(core)


def test_an_absurd_velocity_over_ground_does_not_initialise_the_speeds() -> None:
    """Before: the first fix's 1e5 m/s became u, and the filter was dropped at once, three times."""
    core = EstimatorCore(FIXED)
    core.on_gnss(fix(0, 0.0, 0.0, vn=1e5))
    core.on_attitude(att(0, 0.0))
    est = _sane(core.predict_to(0))
    assert est.u_mps == 0.0 and est.covariance[0] == pytest.approx(FIXED.init_speed_std_mps ** 2)
    assert core.counters["sog_refused"] == 1 and core.counters["divergence_resets"] == 0


def test_an_absurd_yaw_rate_is_refused_and_its_heading_kept() -> None:
    core = started()
    for k in range(1, 31):
        t = k * 100 * MS
        core.on_gnss(fix(t, 0.0, 0.0))
        core.on_attitude(att(t, 0.03 if k > 5 else 0.0, 1e5 if k <= 20 else 0.0))
        _sane(core.predict_to(t))
    c = core.counters
    assert c["yaw_rate_refused"] == 20 and c["yaw_rate_accepted"] == 10
    assert c["heading_accepted"] == 30  # the headings of those samples were used
    assert c["divergence_resets"] == 0 and c["disturbance_reopened"] == 0
    assert core.filter.z[5] == pytest.approx(0.03, abs=0.01)
    assert "yaw_rate_refused" in _kinds(core)


def test_an_absurd_yaw_rate_does_not_initialise_the_yaw_rate() -> None:
    config = EstimatorConfig(origin=FIXED.origin, init_yaw_rate_std_radps=0.1)
    core = EstimatorCore(config)
    core.on_gnss(fix(0, 0.0, 0.0))
    core.on_attitude(att(0, 0.0, -1e5))
    est = _sane(core.predict_to(0))
    assert est.r_radps == 0.0 and est.covariance[2 * 9 + 2] == pytest.approx(0.1 ** 2)
    assert core.counters["yaw_rate_refused"] == 1 and core.counters["divergence_resets"] == 0


def _fed(copies: int) -> EstimatorCore:
    """A core fed fixes and attitudes at 10 Hz, each followed by ``copies`` stale copies of the
    previous one (re-sent, or repeated in a bundle)."""
    core = started()
    for k in range(1, 31):
        t = k * 100 * MS
        core.on_gnss(fix(t, 0.0, 0.0))
        core.on_attitude(att(t, 0.0))
        for _ in range(copies):
            core.on_gnss(fix(t - 100 * MS, 0.0, 0.0))
            core.on_attitude(att(t - 100 * MS, 0.0))
        core.predict_to(t)
    return core


def test_a_stale_copy_of_a_used_measurement_is_not_used_again() -> None:
    """Before: each copy was applied again as a late measurement; with 20 copies of each fix the
    position std fell from 0.05 m to 0.013 m (the filter four times too sure)."""
    clean, flooded = _fed(0), _fed(20)
    assert flooded.counters["duplicates"] == 30 * 20 * 2 and flooded.counters["late_applied"] == 0
    assert flooded.counters["gnss_accepted"] == clean.counters["gnss_accepted"]
    assert (flooded.filter.P == clean.filter.P).all() and (flooded.filter.z == clean.filter.z).all()


def test_a_measurement_arriving_late_once_is_still_used() -> None:
    """Not a copy: a fix that comes after a later one, within the late tolerance, is used once."""
    core = started()
    core.on_gnss(fix(200 * MS, 0.0, 0.0))
    core.on_gnss(fix(100 * MS, 0.0, 0.0))
    assert core.counters["late_applied"] == 1 and core.counters["gnss_accepted"] == 2
    assert core.counters["duplicates"] == 0


class _Out:
    def __init__(self) -> None:
        self.msgs: list = []

    def put_all(self, msgs: list) -> None:
        self.msgs.extend(msgs)


def test_in_real_time_an_input_stamped_ahead_of_the_clock_waits_for_its_time() -> None:
    """A fix stamped 0.9 s ahead of the wall clock (within the stamp gate's second). Before: fed at
    once, it moved the filter 0.9 s ahead: 8 ticks without nav/state, and 16 good measurements
    refused as too old."""
    loop = EstimatorNode(EstimatorCore(FIXED))
    out = _Out()
    for k in range(40):
        now = WALL + k * 50 * MS
        if k % 2 == 0:
            loop.take("seaway/v/sensors/gnss", fix(now - 10 * MS, 0.0, 0.0), now)
            loop.take("seaway/v/sensors/attitude", att(now - 10 * MS, 0.0), now)
        if k == 10:
            loop.take("seaway/v/sensors/gnss", fix(now + 900 * MS, 0.0, 0.0), now)
        out.msgs.clear()
        loop.tick(now, out)
        states = [m for spec, m in out.msgs if spec.suffix == "nav/state"]
        if k > 0:
            assert len(states) == 1 and states[0].stamp_ns == now
    c = loop.core.counters
    assert c["too_old"] == 0 and c["late_applied"] == 0
    assert c["gnss_accepted"] == 20 - 1 + 1  # the first initialised; the one ahead came in its time


def test_the_loop_logs_a_refusal_with_a_warning_and_goes_on(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.estimator")
    loop = EstimatorNode(EstimatorCore(FIXED))
    loop.feed("gnss", fix(0, 0.0, 0.0))
    loop.feed("attitude", att(0, 0.0, 1e5))
    loop.feed("gnss", fix(100 * MS, 0.0, 0.0, std=1e9))
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 2 and loop.refused == 0
    assert _sane(loop.core.predict_to(100 * MS)).stamp_ns == 100 * MS


def _position_std_m(core: EstimatorCore) -> float:
    return math.sqrt(core.filter.P[3, 3])


def test_a_flood_of_fixes_is_no_more_information_than_the_fastest_receiver() -> None:
    """Each fix is taken as an independent measurement, so a sender repeating distinct fixes at
    10 kHz made the filter sure of its position to millimetres (2 s: std 0.004 m). Samples closer
    than a sensor's fastest rate (MAX_GNSS_RATE_HZ, MAX_ATTITUDE_RATE_HZ) allows are refused,
    counted: a flood tells the filter about what the fastest real sensor would."""
    from seaway.contract.messages import MAX_ATTITUDE_RATE_HZ, MAX_GNSS_RATE_HZ

    def fed(gnss_hz: float, attitude_hz: float) -> EstimatorCore:
        core = started()
        samples = [(round(k * 1e9 / gnss_hz), "gnss") for k in range(1, round(2 * gnss_hz) + 1)]
        samples += [(round(k * 1e9 / attitude_hz), "att") for k in range(1, round(2 * attitude_hz) + 1)]
        for t, kind in sorted(samples):
            if kind == "gnss":
                core.on_gnss(fix(100 * MS + t, 0.0, 0.0))
            else:
                core.on_attitude(att(100 * MS + t, 0.0))
        core.predict_to(100 * MS + 2 * S)
        return core

    fastest, flood = fed(MAX_GNSS_RATE_HZ, MAX_ATTITUDE_RATE_HZ), fed(10_000.0, 10_000.0)
    assert fastest.counters["too_frequent"] == 0  # real sensors at their fastest: all taken
    assert flood.counters["too_frequent"] > 30_000
    for i in (3, 5):  # the north position's and the heading's std
        assert math.sqrt(flood.filter.P[i, i]) > 0.8 * math.sqrt(fastest.filter.P[i, i]), i
    assert "too_frequent" in _kinds(flood)
