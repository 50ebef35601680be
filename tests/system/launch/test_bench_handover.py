"""``seaway bench handover`` smoke run: every process hears every message (the run raises
otherwise), and the figures come out consistent with each other, with authentication on and off."""

from __future__ import annotations

import math
import os

import pytest
from seaway.runtime import zenoh_bus
from seaway_lab.bench.handover import LABELS, run

pytestmark = [pytest.mark.system, pytest.mark.bench]


# About 20 s (six processes spawned per case, authentication on and off), and the bench is a floor
# beside `bench lockstep`, not a target: with --slow (CI runs it), so the default run stays near 15 min.
@pytest.mark.slow
def test_bench_handover_smoke(zenoh_env) -> None:
    before = {k: os.environ.get(k) for k in ("SEAWAY_CREDENTIALS", zenoh_bus.ENV_RUNTIME)}
    level = zenoh_bus.log.level
    res = run(["--messages", "100", "--repeat", "1", "--interval-ms", "1"])
    data = res.to_json()
    on = {k: data["figures"][k] for k in LABELS}
    assert set(data["auth_on"]) == set(data["auth_off"]) == set(LABELS)
    assert all(math.isfinite(v) for v in on.values())
    # Receives cost something; the sums are what they say.
    assert on["receive_ring_us"] > 0 and on["receive_callback_us"] > 0
    assert on["handover_least_us"] == pytest.approx(on["put_from_zenoh_thread_us"]
                                                    + on["receive_callback_us"])
    assert on["three_handovers_least_ms"] == pytest.approx(3 * on["handover_least_us"] / 1e3)
    assert data["auth_on"] == pytest.approx(on)
    assert data["figures"]["auth_on_off_handover_least"] == pytest.approx(
        on["handover_least_us"] / data["auth_off"]["handover_least_us"])
    assert res.meta["messages_per_case"] == 100 and res.meta["rounds_each"] == 1
    # The environment and the logging the bench changed are the caller's again.
    assert {k: os.environ.get(k) for k in before} == before
    assert zenoh_bus.log.level == level
