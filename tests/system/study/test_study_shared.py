"""`seaway study` on a shared stack: one `seaway launch sim-batch --stay` flies run after run (a
scenario load and a mission each, sent as the operator), and each run's numbers are those of a stack
of its own (``execute.SharedStack``).

Real processes, real Zenoh sessions and recordings: NMPC on paper conditions #1 and #5 (#5 loads a
scenario whose disturbance grid is a file beside it), one worker, once on one stack and once on a
stack per run (``--fresh-stacks``).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from seaway_recorder import recording
from seaway_recorder.report import episodes, read_for_report

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system

KEYS = ("paper-c1-nmpc", "paper-c5-nmpc")


def study(out: Path, env: dict[str, str], *extra: str) -> dict:
    p = subprocess.run([str(BIN / "seaway"), "study", "table1", "--rows", "#1", "#5", "--columns",
                        "nmpc", "--workers", "1", "--no-figures", "--out", str(out), "--json", *extra],
                       env=env, cwd=REPO, capture_output=True, text=True, timeout=400)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert json.loads(p.stdout)["failures"] == {}
    return json.loads((out / "results.json").read_text())


@pytest.mark.timeout(600)
def test_runs_flown_one_after_another_on_one_stack_equal_fresh_stacks(tmp_path: Path,
                                                                      zenoh_env: dict[str, str]) -> None:
    shared = study(tmp_path / "shared", zenoh_env)
    fresh = study(tmp_path / "fresh", zenoh_env, "--fresh-stacks")
    assert shared["executor"]["stacks"] == "shared" and fresh["executor"]["stacks"] == "one per run"
    runs = {r["key"]: r for r in shared["runs"]}
    assert set(runs) == set(KEYS)
    # One stack, one folder, one recording: each run its own episode of it.
    folders = {r["run_dir"] for r in runs.values()}
    assert folders == {str(tmp_path / "shared" / "runs" / "stack-1")}
    assert sorted(r["episode"] for r in runs.values()) == [0, 1]
    assert len({r["port"] for r in runs.values()}) == 1
    files = recording.open_paths(folders)
    assert len(episodes(read_for_report(files)[1])) == 2
    first, second = sorted(runs.values(), key=lambda r: r["episode"])
    assert "startup_s" in first["timing"] and "switch_s" not in first["timing"]
    assert "switch_s" in second["timing"] and "startup_s" not in second["timing"]
    assert "stop_s" in second["timing"]  # the last run of its stack
    for r in (first, second):  # the stack's CPU, split between its runs
        assert r["cpu_s"]["controller"] > 0 and r["cpu_s"]["recorder"] > 0
    assert first["cpu_s"]["launch"] > second["cpu_s"]["launch"]  # the start-up is the first's
    # The numbers of a stack of its own, each (the same code on the same machine: to rounding).
    for row, key in (("#1", "paper-c1-nmpc"), ("#5", "paper-c5-nmpc")):
        a, b = shared["results"][row]["nmpc"], fresh["results"][row]["nmpc"]
        assert a["completed"] and b["completed"]
        for m in ("energy_j", "avg_cross_track_m", "travel_time_s"):
            assert a[m] == pytest.approx(b[m], rel=1e-9), (key, m, a[m], b[m])
    # The two conditions differ (the grid of #5 was loaded, not #1's calm water flown twice).
    c1, c5 = (shared["results"][r]["nmpc"] for r in ("#1", "#5"))
    assert abs(c1["energy_j"] - c5["energy_j"]) > 1.0, (c1, c5)
