"""``seaway launch``'s mission options through the real processes: ``sim-batch --controller nmpc
--predict-disturbance --task-power-w 1`` flies paper-c1's mission with NMPC predicting with the
estimated tau_d, and the run folder, the recording and the report all say so."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import SolveRecord, ThrustCommand
from seaway_recorder import recording

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent


def test_the_launch_options_choose_the_controller_and_the_prediction(tmp_path, zenoh_env) -> None:
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", "paper-c1",
                          "--controller", "nmpc", "--predict-disturbance", "--task-power-w", "1",
                          "--run-dir", str(run_dir)],
                         env=zenoh_env, capture_output=True, text=True, timeout=400, check=False)
    log = out.stdout[-3000:] + out.stderr[-3000:]
    assert out.returncode == 0, log
    assert "mission paper-c1: accepted (nmpc, predicting the estimated tau_d, T^w 1 W)" in out.stdout, log
    sent = json.loads((run_dir / "mission.json").read_text())
    assert (sent["controller"], sent["predict_disturbance"], sent["task_power_w"]) == ("nmpc", True, 1.0)
    assert "nmpc, predicting the estimated tau_d" in (run_dir / "logs" / "controller.log").read_text()

    # The recording: every solve is NMPC's, and NMPC flew the mission.
    dec = recording.decode_vessel([run_dir / "recording.mcap"], None,
                                  [keys.SOLVE.suffix, keys.THRUST.suffix])
    solves = [m for m in dec.get(keys.SOLVE.suffix) if isinstance(m, SolveRecord)]
    assert solves and {s.controller for s in solves} == {"nmpc"}
    sources = [m.source for m in dec.get(keys.THRUST.suffix) if isinstance(m, ThrustCommand)]
    assert sources.count("nmpc") > 0.9 * len(solves)
    assert not {"cc-empc", "eo-empc"} & set(sources)

    # The report takes the mission the controller accepted and recorded (T^w = 1 W, not the
    # scenario's 0.49 W; nmpc, predicting tau_d).
    report = json.loads((run_dir / "report" / "metrics.json").read_text())
    assert report["mission"]["task_power_w"] == 1.0
    assert report["mission"]["source"] == f"recorded {keys.MISSION_ACCEPTED.suffix}", report["mission"]
    assert (report["mission"]["controller"], report["mission"]["predict_disturbance"]) == ("nmpc", True)
    assert report["metrics"]["completed"] and report["metrics"]["legs_completed"] == 2
