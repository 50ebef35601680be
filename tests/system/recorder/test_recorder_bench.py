"""``seaway bench recorder`` runs end to end (short and slow here; the real figures come from the CLI)."""

from __future__ import annotations

import json
import subprocess

import pytest

from tests.conftest import BIN

pytestmark = [pytest.mark.system, pytest.mark.bench]


def test_bench_recorder_smoke(zenoh_env) -> None:
    args = ["--json", "--rate", "4000", "--seconds", "3", "--baseline-messages", "20000"]
    r = subprocess.run([str(BIN / "seaway"), "bench", "recorder", *args], capture_output=True, text=True,
                       timeout=120, env=zenoh_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    assert f["sent"] == f["recorded"] > 10_000
    assert f["drops"] == 0 and doc["targets"]["drops"]["ok"] is True
    assert f["baseline_mcap_writer_msg_per_s"] > 0 and f["core_recording_writer_msg_per_s"] > 0
    assert f["recorder_mcap_writer_msg_per_s"] > 0 and f["recorder_mcap_writer_lockstep_msg_per_s"] > 0
    # What the publisher offered is recorded, second by second, give or take scheduling: 4,000 msg/s
    # asked, less on a loaded machine (3,068 with the other core busy). The 50,000 target is the CLI's.
    assert 0 < f["publisher_rate_msg_per_s"] <= 4000 * 1.05
    assert f["recorded_rate_median_msg_per_s"] == pytest.approx(f["publisher_rate_msg_per_s"], rel=0.1)
    # ... and a run below it says so rather than passing, and that its publisher never offered it.
    assert doc["targets"]["recorded_rate_median_msg_per_s"]["ok"] is False
    assert doc["meta"]["target_rate_offered"] is False
