"""``seaway bench lockstep`` runs end to end: a short mission composed, through the processes with
authentication on and off, its figures read from the members' marks and the recording (the real
figures, paper condition #1, come from the CLI: docs/results.md)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from tests.conftest import BIN, REPO

pytestmark = [pytest.mark.system, pytest.mark.bench]


def _short_mission(tmp_path: Path) -> Path:
    """Paper condition #1 cut to its first 5 m (about 90 s simulated; the launcher takes a mission
    as over once the vessel arrives at its end from more than 4 m away)."""
    text = (REPO / "deploy" / "scenarios" / "paper-c1.toml").read_text()
    for old, new in (('name = "paper-c1"', 'name = "paper-c1-short"'),
                     ("waypoints_m = [[0.0, 0.0], [8.0, 0.0], [5.13, 8.57]]",
                      "waypoints_m = [[0.0, 0.0], [5.0, 0.0]]")):
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / "paper-c1-short.toml"
    path.write_text(text)
    return path


@pytest.mark.slow  # about 40 s
@pytest.mark.timeout(600)
def test_bench_lockstep_smoke(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    r = subprocess.run([str(BIN / "seaway"), "bench", "lockstep", "--repeat", "1", "--scenario",
                        str(_short_mission(tmp_path)), "--json"],
                       capture_output=True, text=True, timeout=540, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads(r.stdout.strip().splitlines()[-1])
    f = doc["figures"]
    # The mission as the sim's marks delimit it, the same steps composed and through the processes.
    simulated = f["simulated time [s]"]
    assert 20 < simulated < 120
    for way in ("composed", "processes"):
        assert f[f"{way}: wall time [s]"] > 0 and f[f"{way}: period median [ms]"] > 0
        assert f[f"{way}: real-time factor"] == pytest.approx(simulated / f[f"{way}: wall time [s]"])
        # Every member marked its part of a period, composed as through the processes.
        for stage in ("estimator: filter and publish", "controller: solve and publish",
                      "recorder: write and flush", "sim: step and publish after the last answer"):
            assert f[f"{way}: {stage}, median [ms]"] > 0, (way, stage)
    # The solves, from the recordings: one a period, through the processes and composed, where
    # they are a part of the mission's wall time.
    solves = f["MPC solves alone: sum [s]"]
    assert solves > 0 and f["MPC solves"] == round(simulated / 0.1)  # the controller's period
    assert 0 < f["composed: its solves, sum [s]"] < f["composed: wall time [s]"]
    assert f["composed / MPC solves alone"] == pytest.approx(f["composed: wall time [s]"] / solves)
    assert f["MPC solves alone: real-time factor"] == pytest.approx(simulated / solves)
    for section in ("auth_on", "auth_off", "auth_overhead_ratio"):
        assert set(doc[section]) == {"wall_time_s", "period_median_ms", "period_p99_ms"}
    assert set(doc["targets"]) >= {"composed: real-time factor", "composed / MPC solves alone",
                                   "processes: real-time factor"}
    assert doc["meta"]["scenario"].endswith("paper-c1-short.toml")
