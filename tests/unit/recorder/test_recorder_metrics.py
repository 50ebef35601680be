"""The recorder's figures: solve statistics (the paper's metrics are ``seaway.vessel.metrics``'s,
tested in tests/unit/common/test_mission_metrics.py)."""

from __future__ import annotations

import pytest
from seaway.contract.messages import SolveRecord
from seaway.vessel import metrics as shared
from seaway_recorder import report
from seaway_recorder.metrics import solve_stats


def test_the_report_uses_the_shared_mission_metrics():
    assert report.mission_metrics is shared.mission_metrics


def test_solve_stats() -> None:
    recs = [SolveRecord.make(stamp_ns=i, controller="cc-empc", status="ok" if i % 10 else "fail",
                             success=bool(i % 10), iterations=3, solve_time_s=(i + 1) / 1000,
                             fallback_level=0 if i % 10 else 2, fallback_count=i // 10 + 1)
            for i in range(100)]
    s = solve_stats(recs)
    assert (s.count, s.successes, s.failures) == (100, 90, 10)
    assert s.solve_time_max_ms == pytest.approx(100.0)
    assert s.solve_time_median_ms == pytest.approx(50.5)
    assert s.solve_time_p95_ms == pytest.approx(95.0)
    assert s.fallback_levels == {"2": 10} and s.fallbacks == 10
    assert s.max_fallback_count == 10
    assert s.controllers == ["cc-empc"]
    assert solve_stats([]).solve_time_median_ms is None


def test_periods_before_the_solver_was_ready_are_not_failed_solves() -> None:
    """A warm-cache run's first period could come while its solver was being loaded: flown on a
    fallback, with no solve, and the report counted it as a failed solve."""
    from seaway.contract.messages import SOLVER_NOT_READY

    def rec(i: int, status: str, success: bool) -> SolveRecord:
        return SolveRecord.make(stamp_ns=i, controller="cc-empc", status=status, success=success,
                                iterations=0, solve_time_s=0.0, fallback_level=0 if success else 2)

    recs = [rec(0, f"{SOLVER_NOT_READY} (the generated solver is being made)", False),
            rec(1, "convexify_failed", False)] + [rec(i, "Solve_Succeeded", True) for i in range(2, 9)]
    s = solve_stats(recs)
    assert (s.count, s.successes, s.failures, s.not_ready) == (9, 7, 1, 1)
