"""``seaway bench lockstep``'s bookkeeping without the stack: authentication on and off alternate,
and both come out (table and JSON) with their ratio. The real runs are ``seaway bench lockstep``."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import pytest
from seaway_lab.bench import lockstep


def test_lockstep_alternates_auth_and_reports_both(monkeypatch: pytest.MonkeyPatch) -> None:
    order: list[bool] = []

    def fake_run(run_dir: Path, auth: bool = True) -> dict[str, list[int]]:
        order.append(auth)
        period_ns = 5_000_000 if auth else 4_000_000  # on costs 25 % more here
        return {s: [k * period_ns + i * 100_000 for k in range(50)]
                for i, s in enumerate(lockstep.STAGES)}

    monkeypatch.setattr(lockstep, "through_processes", fake_run)
    monkeypatch.setattr(lockstep, "run_closed_loop",
                        lambda *_a, **_k: SimpleNamespace(steps=49, travel_time_s=4.9))
    res = lockstep.run(["--repeat", "2"])

    assert order == [True, False, True, False]
    out = res.to_json()
    names = set(lockstep.AUTH_FIGURES)
    for section in ("auth_on", "auth_off", "auth_overhead_ratio"):
        assert set(out[section]) == names
        assert all(math.isfinite(v) and v > 0 for v in out[section].values())
    assert out["auth_on"]["period_median_ms"] == pytest.approx(5.0)
    assert out["auth_off"]["period_median_ms"] == pytest.approx(4.0)
    assert out["auth_overhead_ratio"]["wall_time_s"] == pytest.approx(1.25)
    ratio = out["targets"]["auth on / off, wall time"]
    assert ratio == {"target": "<= 1.1", "ok": False}
    assert not out["passed"]
    # The comparison with the in-process loop is the stack as it runs: authentication on.
    assert out["figures"]["through the processes, warm [s]"] == pytest.approx(out["auth_on"]["wall_time_s"])
    table = res.table()
    assert "auth on / off, period p99" in table and "through the processes, auth off [s]" in table
