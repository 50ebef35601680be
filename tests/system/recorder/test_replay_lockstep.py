"""``seaway launch replay`` of a lockstep recording: live services, paced by their own answers.

A lake mission flown by the real lockstep stack (``seaway launch sim-batch``) is replayed into a
live estimator, controller and recorder (``seaway launch replay``, whose replay process is
``seaway replay --lockstep``). Before, the replay kept the recording's log-time pace, which for a
lockstep recording is simulated time: a 333 s mission took 333 s to replay. Now each recorded period
waits for the members' answers, so:

* every recorded period reaches the members (none skipped, none outrun), and the live controller,
  fed the same states, gives the recorded commands again, the estimator the recorded states (the
  same code on the same inputs; tolerances as in ``tests/replay``, for another CPU's last bit);
* the replay ends at the recording's last period, where the controller holds (its mission over),
  instead of waiting for ever;
* it runs faster than the recorded simulated time (lockstep through the processes is ~20x here; the
  assertion leaves a 10x margin for a loaded machine).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract.messages import StateEstimate, ThrustCommand
from seaway.recording.reader import iter_messages

pytestmark = pytest.mark.system

SCENARIO = "lake"
THRUST_TOLERANCE_N = 1e-6
STATE_RTOL, STATE_ATOL = 1e-9, 1e-12


def launch(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "seaway.tools.cli", "launch", *args], env=env,
                          capture_output=True, text=True, timeout=600)


def flown(run: Path) -> tuple[dict[int, ThrustCommand], dict[int, StateEstimate], int]:
    """(commands by stamp, states by stamp, number of sim answers) recorded in ``run``."""
    commands: dict[int, ThrustCommand] = {}
    states: dict[int, StateEstimate] = {}
    answers = 0
    for m in iter_messages([run / "recording.mcap"]):
        if m.topic.endswith("/ctrl/thrust"):
            c = ThrustCommand.decode(m.data)
            commands[c.stamp_ns] = c
        elif m.topic.endswith("/nav/state"):
            s = StateEstimate.decode(m.data)
            states[s.stamp_ns] = s
        elif m.topic.endswith("/lockstep/sim"):
            answers += 1
    return commands, states, answers


def test_a_lockstep_recording_replays_into_live_services_paced_by_their_answers(
        zenoh_env, tmp_path: Path) -> None:
    original, again = tmp_path / "original", tmp_path / "replayed"
    done = launch(["sim-batch", "--scenario", SCENARIO, "--run-dir", str(original)], zenoh_env)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    # No --scenario: the replay takes the recorded run's (its run.json beside the recording).
    done = launch(["replay", "--recording", str(original), "--run-dir", str(again)], zenoh_env)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "completed                                           yes" in done.stdout, done.stdout

    log_lines = (again / "logs" / "replay.log").read_text().splitlines()
    stats = json.loads(next(line for line in reversed(log_lines) if line.startswith("{")))
    commands, states, answers = flown(original)
    assert answers > 500  # the lake mission: ~60 s of 0.1 s periods
    assert stats["by_topic"]["seaway/vessel1/lockstep/sim"] == answers
    assert stats["periods"] == answers  # every recorded period answered by every live member
    assert stats["elapsed_s"] < stats["recorded_span_s"] / 2, stats

    replayed_commands, replayed_states, _ = flown(again)
    assert replayed_commands.keys() == commands.keys()
    worst_n = max(max(abs(a.thrust_port_n - b.thrust_port_n),
                      abs(a.thrust_starboard_n - b.thrust_starboard_n))
                  for a, b in ((commands[k], replayed_commands[k]) for k in commands))
    assert worst_n <= THRUST_TOLERANCE_N
    assert states.keys() <= replayed_states.keys()
    for stamp, s in states.items():
        r = replayed_states[stamp].model_dump()
        for name, value in s.model_dump().items():
            if isinstance(value, float):
                assert math.isclose(value, r[name], rel_tol=STATE_RTOL, abs_tol=STATE_ATOL), (
                    stamp, name, value, r[name])
