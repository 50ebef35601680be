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
    r = subprocess.run(
        [
            str(BIN / "seaway"),
            "bench",
            "soak",
            "--duration",
            "3",
            "--controller",
            "nmpc",
            "--sample-interval",
            "0.25",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=zenoh_env,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    assert f["missions flown"] >= 2 and f["messages recorded"] > 1000
    for process in ("sim", "estimator", "controller", "recorder", "launcher"):
        assert f[f"{process} RSS start [MB]"] > 10 and f[f"{process} RSS end [MB]"] > 10
        assert isinstance(f[f"{process} RSS growth [%]"], float)
        # the target is on the steady part (after the warm-up), the launcher's as every service's
        assert f"{process} RSS steady growth [%]" in doc["targets"]
        assert isinstance(f[f"{process} RSS steady slope [MB/h]"], float)
        assert len(doc["rss_samples_mb"][process]) >= 3  # sampled through the run
    assert f["dropped by the recorder"] == 0 and f["process restarts"] == 0
    assert doc["meta"]["launcher_exit"] == 0
