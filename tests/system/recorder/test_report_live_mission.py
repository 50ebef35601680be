"""A mission sent to a running stack by ``seaway mission FILE`` (not the scenario's) is reported
with full metrics, measured against the path sent (issue 14, item 5).

The real lockstep stack (``seaway launch sim-batch --no-mission``: recorder, sim, estimator,
controller) on paper-c1, a mission of its own from a file, flown to completion; then ``seaway report``
on the run. Requests are queries, which the recorder does not record: the report knows the path
only from the controller's ``mission/accepted``. Before it, the report fell back to the scenario's
mission, which does not fit what was flown, and gave no metrics.
"""

from __future__ import annotations

import itertools
import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from seaway.contract import keys
from seaway.runtime.bus import Bus
from seaway.simkit.scenario import load_scenario

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
SENT = [(0.0, 0.0), (6.0, 0.0), (6.0, -6.0)]
"""The mission sent: as many waypoints as paper-c1's, a different path (north 6 m, then west)."""
COA_M, TASK_POWER_W = 1.0, 5.0


def cross_track(x: np.ndarray, y: np.ndarray, wps: list[tuple[float, float]], coa_m: float
                ) -> np.ndarray:
    """|cross-track error| [m] of each sample to its leg, legs switched on entering the circle of
    acceptance, samples inside any circle left out (the paper's definition, written here again)."""
    wp = np.array(wps)
    active, out = 1, []
    for xi, yi in zip(x, y, strict=True):
        while active < len(wp) and np.hypot(xi - wp[active, 0], yi - wp[active, 1]) <= coa_m:
            active += 1
        if active == len(wp):
            break
        if (np.hypot(xi - wp[:, 0], yi - wp[:, 1]) <= coa_m).any():
            continue
        a, b = wp[active - 1], wp[active]
        d = b - a
        out.append(abs(d[0] * (yi - a[1]) - d[1] * (xi - a[0])) / np.hypot(*d))
    return np.array(out)


def test_a_mission_sent_live_is_reported_against_the_path_sent(procs, zenoh_env, tmp_path) -> None:
    from seaway.recording.reader import decode_vessel

    run = tmp_path / "run"
    mission_file = tmp_path / "probe.toml"
    mission_file.write_text(f'mission_id = "probe-live"\nwaypoints_m = {[list(p) for p in SENT]}\n'
                            f"coa_radius_m = {COA_M}\ntask_power_w = {TASK_POWER_W}\n"
                            'controller = "cc-empc"\n')
    launcher = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch",
                            "--run-dir", str(run), "--no-mission", "--stay"], zenoh_env, "launcher")

    def ready() -> bool:
        if launcher.poll() is not None:
            pytest.fail(f"the launcher exited ({launcher.returncode}):\n{procs.log(launcher)[-3000:]}")
        return "all ready in" in procs.log(launcher)

    wait_for(ready, 240, interval_s=0.2, what="the sim-batch stack to be ready")
    statuses = []
    with Bus.open("vessel1") as bus:
        bus.subscribe(keys.MISSION_STATUS, mode="fifo", callback=lambda _k, m: statuses.append(m))
        sent = subprocess.run([str(BIN / "seaway"), "mission", str(mission_file), "--timeout", "120"],
                              env=zenoh_env, capture_output=True, text=True, timeout=300)
        assert sent.returncode == 0 and "accepted" in sent.stdout, sent.stdout + sent.stderr
        wait_for(lambda: any(s.mission_id == "probe-live" and s.state == "complete" for s in statuses),
                 400, interval_s=0.2, what="the mission sent to complete")
    assert procs.stop(launcher, signal.SIGINT, timeout_s=300) < 300
    assert launcher.returncode == 0, procs.log(launcher)[-3000:]
    assert not (run / "mission.json").exists()  # the launcher sent nothing: no document to go by
    # ... but it heard the controller take the operator's mission (in lockstep, in its bundle):
    # the vessel flew one, so it gets its report.
    assert "no report: vessel" not in procs.log(launcher), procs.log(launcher)[-3000:]

    rep = subprocess.run([str(BIN / "seaway"), "report", str(run), "--out", str(tmp_path / "rep"),
                          "--json", "--no-plots"], capture_output=True, text=True, timeout=300,
                         env=zenoh_env)
    assert rep.returncode == 0, rep.stderr
    doc = json.loads(rep.stdout)
    flown = [m for m in doc["missions"] if m["mission_id"] == "probe-live"]
    assert len(flown) == 1, doc["missions"]
    assert flown[0]["source"] == f"recorded {keys.MISSION_ACCEPTED.suffix}", flown[0]
    assert doc["mission"]["waypoints_m"] == [list(p) for p in SENT]
    assert (doc["mission"]["coa_radius_m"], doc["mission"]["task_power_w"]) == (COA_M, TASK_POWER_W)
    m = doc["metrics"]
    assert m is not None and m["completed"] and m["legs_completed"] == len(SENT) - 1

    # Travel time and energy: what the controller reported live for the mission sent.
    mine = [s for s in statuses if s.mission_id == "probe-live"]
    active = min(s.stamp_ns for s in mine if s.state == "active")
    done = next(s for s in mine if s.state == "complete")
    assert m["travel_time_s"] == pytest.approx((done.stamp_ns - active) / 1e9, abs=0.1 + 1e-9)
    assert m["energy_j"] == pytest.approx(done.energy_used_j, rel=1e-3)

    # Cross-track error: against the path sent, computed here from the recorded truth; the
    # scenario's path gives something else entirely.
    dec = decode_vessel(sorted(Path(run).glob("*.mcap")), "vessel1", [keys.SIM_TRUTH.suffix])
    truth = [t for t in dec.get(keys.SIM_TRUTH.suffix) if active <= t.stamp_ns <= done.stamp_ns]
    x, y = np.array([t.x_m for t in truth]), np.array([t.y_m for t in truth])
    along_sent = cross_track(x, y, SENT, COA_M)
    assert m["cross_track_samples"] == pytest.approx(len(along_sent), abs=2)
    assert m["avg_cross_track_m"] == pytest.approx(float(along_sent.mean()), abs=0.01)
    assert m["max_cross_track_m"] == pytest.approx(float(along_sent.max()), abs=0.02)
    scenario = load_scenario("paper-c1").mission
    assert scenario is not None and [tuple(p) for p in scenario.waypoints_m] != SENT
    off_scenario = distance_to_path(x, y, [tuple(p) for p in scenario.waypoints_m])
    # (The first legs overlap: both go north from the origin; the second ones part by metres.)
    assert m["avg_cross_track_m"] < 0.5 and off_scenario.max() > 4.0
    assert float(off_scenario.mean()) > max(1.0, 5 * m["avg_cross_track_m"])


def distance_to_path(x: np.ndarray, y: np.ndarray, wps: list[tuple[float, float]]) -> np.ndarray:
    """Each sample's distance to the nearest point of the polyline ``wps`` [m]."""
    best = np.full(len(x), np.inf)
    for p, q in itertools.pairwise(wps):
        a, b = np.array(p), np.array(q)
        d = b - a
        s = np.clip(((x - a[0]) * d[0] + (y - a[1]) * d[1]) / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.hypot(x - (a[0] + s * d[0]), y - (a[1] + s * d[1])))
    return best
