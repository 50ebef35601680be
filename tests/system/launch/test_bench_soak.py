"""``seaway bench soak`` runs end to end (a few seconds of NMPC missions here; the real figures,
600 s of the paper's CC-EMPC mission, come from the CLI: services/recorder/README.md)."""

from __future__ import annotations

import json
import subprocess

import pytest

from tests.conftest import BIN

pytestmark = [pytest.mark.system, pytest.mark.bench]


@pytest.mark.slow  # about 17 s
def test_bench_soak_smoke(zenoh_env) -> None:
    r = subprocess.run([str(BIN / "seaway"), "bench", "soak", "--duration", "3", "--controller",
                        "nmpc", "--json"], capture_output=True, text=True, timeout=600,
                       env=zenoh_env)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    assert f["missions flown"] >= 2 and f["messages recorded"] > 1000
    for service in ("sim", "estimator", "controller", "recorder"):
        assert f[f"{service} RSS start [MB]"] > 10 and f[f"{service} RSS end [MB]"] > 10
        assert f"{service} RSS growth [%]" in doc["targets"]
    assert f["dropped by the recorder"] == 0 and f["process restarts"] == 0
    assert doc["meta"]["launcher_exit"] == 0
