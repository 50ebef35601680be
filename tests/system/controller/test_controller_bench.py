"""``seaway bench controller`` runs end to end (condition #1, one run; the real figures come from the CLI)."""

from __future__ import annotations

import json
import subprocess

import pytest

from tests.conftest import BIN

pytestmark = [pytest.mark.system, pytest.mark.bench]


def test_bench_controller_quick_json() -> None:
    r = subprocess.run([str(BIN / "seaway"), "bench", "controller", "--quick", "--controllers",
                        "cc-empc", "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    # stderr is a pipe, not a terminal: a progress line per step (the run, IPOPT's instances), each
    # with an estimate of the time left, the last at 100 %.
    progress = [line for line in r.stderr.splitlines() if " ETA " in line]
    assert len(progress) >= 2 and "\r" not in r.stderr, r.stderr
    assert progress[-1].startswith("100% ETA 0 s"), r.stderr
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    assert f["cc-empc/steps"] > 3000 and f["cc-empc/unconverged"] == 0
    assert f["cc-empc/ipopt_unconverged"] == 0 and f["cc-empc/ipopt_sx_unconverged"] == 0
    # The MX and SX graphs are the same NLP: IPOPT must land on the same point from both.
    assert f["cc-empc/ipopt_mx_vs_sx_max_gap"] < 1e-6
    # Both ratios are computed from the same instances; the generated solver is the faster one.
    assert f["cc-empc/speedup_vs_ipopt"] > 1 and f["cc-empc/speedup_vs_ipopt_sx"] > 1
    assert f["cc-empc/ipopt_filtered_median_ms"] / f["cc-empc/ipopt_sx_filtered_median_ms"] == \
        pytest.approx(f["cc-empc/speedup_vs_ipopt"] / f["cc-empc/speedup_vs_ipopt_sx"], rel=1e-9)
    assert "speedup_vs_ipopt" in {k.split("/")[-1] for k in doc["targets"]}
    assert f["c1/cc-empc/energy_j"] == pytest.approx(332.0, rel=0.02)  # Table I, condition #1
