"""``seaway bench sim`` smoke run: the figures come out, consistent with each other."""

from __future__ import annotations

import pytest
from seaway_lab.bench.sim import run

pytestmark = [pytest.mark.system, pytest.mark.bench]


def test_bench_sim_smoke(zenoh_env) -> None:
    res = run(["--scenario", "paper-c1", "--periods", "60", "--warmup", "5"])
    figures = {f.name: f.value for f in res.figures}
    assert res.meta["periods_timed"] == 60 and res.meta["stale_commands"] == 0
    assert 0 < figures["period_wall_median_ms"] <= figures["period_wall_p99_ms"]
    assert figures["real_time_factor_at_median"] == pytest.approx(
        100.0 / figures["period_wall_median_ms"])
    # The protocol round trip costs something on top of the plant alone.
    assert figures["plant_only_real_time_factor"] > figures["real_time_factor"] > 0
    assert res.to_json()["targets"]["real_time_factor"]["target"] == ">= 200"
