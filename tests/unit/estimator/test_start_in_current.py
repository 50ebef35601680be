"""A filter started on a boat that drifts in a current: the first fixes are consistent and taken;
what is gated out or re-initialised is noticed and logged (``seaway_estimator.notices``)."""

from __future__ import annotations

import logging
import math

import pytest
from seaway_estimator.core import EstimatorCore
from seaway_estimator.node import EstimatorNode
from seaway_estimator.notices import PERSISTENT_REJECT_RUN

from tests.unit.estimator.test_core import FIXED, MS, S, att, fix

CURRENT_MPS = 0.15
HEADING_RAD = 0.3


def drift(core: EstimatorCore, toward_rad: float, seconds: float, with_sog: bool) -> float:
    """Feed ``seconds`` of noise-free sensors (GNSS 5 Hz reporting 0 m accuracy, as the simulator's
    noise-free GNSS does; heading 20 Hz) of a boat at rest in the water, no thrust, carried by a
    ``CURRENT_MPS`` current toward ``toward_rad``; the largest position error [m] once initialised."""
    cn, ce = CURRENT_MPS * math.cos(toward_rad), CURRENT_MPS * math.sin(toward_rad)
    worst = 0.0
    for k in range(round(seconds * 20) + 1):
        t = k * 50 * MS
        ts = t / S
        if k % 4 == 0:
            vn, ve = (cn, ce) if with_sog else (None, None)
            core.on_gnss(fix(t, cn * ts, ce * ts, vn=vn, ve=ve, std=0.0))
        core.on_attitude(att(t, HEADING_RAD))
        est = core.predict_to(t)
        if est is not None:
            worst = max(worst, math.hypot(est.x_m - cn * ts, est.y_m - ce * ts))
    return worst


@pytest.mark.parametrize("with_sog", [True, False], ids=["sog", "no-sog"])
@pytest.mark.parametrize("toward_deg", [0, 90, 197, 270])
def test_noise_free_fixes_of_a_boat_in_a_015_mps_current_are_all_accepted(
    toward_deg: int, with_sog: bool
) -> None:
    core = EstimatorCore(FIXED)
    worst_m = drift(core, math.radians(toward_deg), 10.0, with_sog)
    assert core.counters["gnss_accepted"] == 50 and core.counters["gnss_rejected"] == 0
    assert core.counters["gnss_reinit"] == 0 and core.counters["degraded_entered"] == 0
    assert worst_m < 0.05


def test_the_initial_force_uncertainty_covers_the_current_it_is_configured_for() -> None:
    # The model has no current: a drift c is a speed through the water held by the force D c.
    core = EstimatorCore(FIXED)
    core.on_gnss(fix(0, 0.0, 0.0))
    core.on_attitude(att(0, 0.0))
    p = core.p
    force_std_n = math.sqrt(core.filter.P[6, 6])
    assert force_std_n >= max(p.xu_kgps, p.yv_kgps) * FIXED.init_current_std_mps
    without = EstimatorCore(FIXED.model_copy(update={"init_current_std_mps": 0.0}))
    without.on_gnss(fix(0, 0.0, 0.0))
    without.on_attitude(att(0, 0.0))
    assert math.sqrt(without.filter.P[6, 6]) == pytest.approx(FIXED.init_force_std_n)


def offset_fixes(core: EstimatorCore, n: int, north_m: float = 50.0) -> None:
    core.on_gnss(fix(0, 0.0, 0.0))
    core.on_attitude(att(0, 0.0))
    for k in range(1, n + 1):
        t = k * 200 * MS
        core.on_attitude(att(t, 0.0))
        core.on_gnss(fix(t, north_m, 0.0, vn=None, ve=None))


def test_rejections_and_the_reinitialisation_are_noticed_once_each() -> None:
    core = EstimatorCore(FIXED)
    n = core.config.gnss_reject_reinit_count
    offset_fixes(core, n)
    notes = core.take_notices()
    rejected = [x for x in notes if x.kind == "gnss_rejected"]
    assert [x.run for x in rejected] == list(range(1, n + 1))
    assert [x.persistent for x in rejected] == [k >= PERSISTENT_REJECT_RUN for k in range(1, n + 1)]
    reinit = [x for x in notes if x.kind == "gnss_reinit"]
    assert len(reinit) == 1 and reinit[0].persistent and reinit[0].stamp_ns == n * 200 * MS
    assert core.take_notices() == []  # taken means taken


def test_the_loop_logs_rejections_rate_limited_and_warns_when_they_persist(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.estimator")
    core = EstimatorCore(FIXED)
    loop = EstimatorNode(core)
    n = core.config.gnss_reject_reinit_count
    offset_fixes(core, n)
    loop.feed("attitude", att((n + 1) * 200 * MS, 0.0))  # any core call logs what it noticed
    lines = [(r.levelno, r.getMessage()) for r in caplog.records if "estimator gnss" in r.getMessage()]
    info = [m for lvl, m in lines if lvl == logging.INFO and "rejected" in m]
    warn_rejected = [m for lvl, m in lines if lvl == logging.WARNING and "rejected" in m]
    warn_reinit = [m for lvl, m in lines if lvl == logging.WARNING and "reinit" in m]
    # 25 rejections and a re-initialisation within a second of wall time: three lines, not 26.
    assert len(info) == 1 and len(warn_rejected) == 1 and len(warn_reinit) == 1, lines
    assert "50.00 m" in warn_reinit[0] and str(n) in warn_reinit[0]
    assert loop.ratelog.held(("gnss_rejected", True)) == n - PERSISTENT_REJECT_RUN
