"""``seaway bench hold`` runs end to end in its quick form (30 s of holding; the 120 s figures come
from the CLI): the table's figures and targets in ``--json``."""

from __future__ import annotations

import json
import subprocess

import pytest

from tests.conftest import BIN

pytestmark = [pytest.mark.system, pytest.mark.bench]


def test_bench_hold_quick_json() -> None:
    r = subprocess.run([str(BIN / "seaway"), "bench", "hold", "--quick", "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    assert doc["passed"] and doc["bench"] == "hold"
    assert f["hold_s"] == pytest.approx(30.0, abs=0.5)
    assert f["mean_distance_m"] <= 1.0 and f["p95_distance_m"] <= 2.0
    assert doc["targets"]["mean_distance_m"]["ok"] and doc["targets"]["p95_distance_m"]["ok"]
    # It holds against the current and the wind: that takes thrust, so energy.
    assert f["propulsion_energy_j"] > 0 and f["controller_hold_energy_j"] > f["propulsion_energy_j"]
    assert doc["meta"]["current_mps"] == 0.15 and doc["meta"]["wind_force_n"] == 2.0


def test_bench_hold_refuses_a_bad_duration() -> None:
    r = subprocess.run([str(BIN / "seaway"), "bench", "hold", "--seconds", "nan"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "--seconds" in r.stderr
