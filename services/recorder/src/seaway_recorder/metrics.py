"""The controller's solve statistics of a recording (the paper's metrics are
``seaway.vessel.metrics.mission_metrics``, shared with the in-process closed loop). Nothing here reads
a clock or a file.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

from seaway.contract.messages import SOLVER_NOT_READY
from seaway.vessel.metrics import median, percentile


@dataclass
class SolveStats:
    count: int
    successes: int
    failures: int
    """Solves that failed; not the periods before the solver was ready (``not_ready``)."""
    not_ready: int
    """Periods with no solver to call yet (``SOLVER_NOT_READY``: being made), flown on a fallback."""
    solve_time_median_ms: float | None
    solve_time_p95_ms: float | None
    solve_time_p99_ms: float | None
    solve_time_max_ms: float | None
    solve_time_mean_ms: float | None
    fallbacks: int
    fallback_levels: dict[str, int]
    max_fallback_count: int
    controllers: list[str]
    statuses: dict[str, int]

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def solve_stats(records: Sequence[Any]) -> SolveStats:
    """Solve-time and fallback statistics of ``ctrl/solve`` SolveRecords."""
    times = [r.solve_time_s * 1e3 for r in records]
    levels: dict[str, int] = {}
    statuses: dict[str, int] = {}
    for r in records:
        if r.fallback_level:
            levels[str(r.fallback_level)] = levels.get(str(r.fallback_level), 0) + 1
        statuses[r.status] = statuses.get(r.status, 0) + 1
    succ = sum(1 for r in records if r.success)
    not_ready = sum(1 for r in records if not r.success and r.status.startswith(SOLVER_NOT_READY))

    def opt(v: float) -> float | None:
        return None if (v is None or math.isnan(v)) else v

    return SolveStats(
        count=len(records),
        successes=succ,
        failures=len(records) - succ - not_ready,
        not_ready=not_ready,
        solve_time_median_ms=opt(median(times)),
        solve_time_p95_ms=opt(percentile(times, 95)),
        solve_time_p99_ms=opt(percentile(times, 99)),
        solve_time_max_ms=max(times) if times else None,
        solve_time_mean_ms=(sum(times) / len(times)) if times else None,
        fallbacks=sum(levels.values()),
        fallback_levels=levels,
        max_fallback_count=max((r.fallback_count for r in records), default=0),
        controllers=sorted({r.controller for r in records}),
        statuses=statuses,
    )
