"""The launcher with real processes that hang, and an impatient operator (issue 14, items 3 and 10).

* A process that stops publishing what it must (its loop stuck, or the whole process SIGSTOPped),
  or whose restart never becomes ready,
  is restarted like a dead one, with its back-off; so is one whose health token disappears while it
  still runs. Each time the launcher logs why, writes a ``hung`` event, and the recorder puts the
  event into the recording (``launcher/events``).
* A second Ctrl-C shortens the stop's grace, but the processes still stop in order, the recorder
  last, its file finished, and the launcher still prints its status table.

The processes are ``dummy_service.py`` stand-ins (and the real recorder), so each test takes seconds.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest
from seaway.recording.reader import finished, iter_messages

from tests.conftest import BIN, wait_for
from tests.system.launch.test_launcher import DUMMY, launch, write_profile

pytestmark = pytest.mark.system


def events(run: Path) -> list[dict]:
    path = run / "events.jsonl"
    return [json.loads(x) for x in path.read_text().splitlines()] if path.exists() else []


def of(run: Path, process: str, event: str) -> list[dict]:
    return [e for e in events(run) if e["process"] == process and e["event"] == event]


RECORDER = ('[[processes]]\nname = "recorder"\nservice = "recorder"\n'
            f'command = ["{BIN / "seaway-recorder"}", "--vessel", "{{vessel}}", "--out", "{{run_dir}}", '
            '"--events", "{run_dir}/events.jsonl"]\n')


def controller(args: str, within_s: float = 1.0) -> str:
    """A stand-in controller that publishes ctrl/thrust at 20 Hz, which it must keep doing."""
    return ('[[processes]]\nname = "ctl"\nservice = "controller"\nafter = ["recorder"]\n'
            f'command = ["{sys.executable}", "{DUMMY}", "--service", "controller", '
            f'"--publish-thrust", "20"{args}]\n'
            f'must_publish = [{{ key = "ctrl/thrust", within_s = {within_s} }}]\n')


def recorded_events(run: Path) -> list[dict]:
    files = sorted(p for p in run.glob("*.mcap") if not p.name.endswith(".recovered.mcap"))
    return [json.loads(m.data) for m in iter_messages(files, ["launcher/events"])]


@pytest.mark.parametrize("how", ["quiet", "sigstop"])
def test_a_process_that_stops_publishing_is_restarted(how, procs, zenoh_env, tmp_path) -> None:
    run = tmp_path / "run"
    quiet = ', "--quiet-after", "2"' if how == "quiet" else ""
    la = launch(procs, zenoh_env, write_profile(tmp_path, RECORDER + controller(quiet)), tmp_path)
    wait_for(lambda: "all ready" in procs.log(la), 60, what="all ready")
    (first,) = of(run, "ctl", "start")
    if how == "sigstop":
        time.sleep(1.0)  # it has published (its duty is armed by its first command)
        os.kill(first["pid"], signal.SIGSTOP)
    hung = wait_for(lambda: of(run, "ctl", "hung"), 30, what="the stand-in found hung")[0]
    assert "published no ctrl/thrust for" in hung["reason"], hung
    wait_for(lambda: len(of(run, "ctl", "start")) == 2, 30, what="the stand-in restarted")
    (exit_,) = of(run, "ctl", "exit")[:1]
    assert exit_["code"] == -signal.SIGKILL
    # Restarted like a dead one: after its back-off (0.2 s in this profile), counted as a restart.
    second = of(run, "ctl", "start")[1]
    assert second["t_unix_s"] - exit_["t_unix_s"] >= 0.2
    log = procs.log(la)
    assert "launcher: ctl is hung: published no ctrl/thrust" in log
    assert "ctl exited with code -9; restarting in 0.2 s (restart 1 of at most 3)" in log

    assert procs.stop(la, signal.SIGINT, timeout_s=20) < 20
    assert la.returncode == 0, procs.log(la)
    # The recording tells the story too, from the launcher's events log.
    story = [(e["process"], e["event"]) for e in recorded_events(run)]
    assert ("ctl", "hung") in story and story.count(("ctl", "start")) == 2, story


def test_a_process_whose_health_token_disappears_is_restarted(procs, zenoh_env, tmp_path) -> None:
    run = tmp_path / "run"
    est = ('[[processes]]\nname = "est"\nservice = "estimator"\n'
           f'command = ["{sys.executable}", "{DUMMY}", "--service", "estimator", '
           '"--drop-token-after", "1"]\n')
    la = launch(procs, zenoh_env, write_profile(tmp_path, est), tmp_path)
    hung = wait_for(lambda: of(run, "est", "hung"), 40, what="the stand-in found hung")[0]
    assert "its health token has been gone for" in hung["reason"], hung
    wait_for(lambda: len(of(run, "est", "start")) == 2, 30, what="the stand-in restarted")
    assert procs.stop(la, signal.SIGINT, timeout_s=20) < 20
    assert la.returncode == 0, procs.log(la)


def test_a_restarted_process_that_never_becomes_ready_is_restarted_again(procs, zenoh_env,
                                                                        tmp_path) -> None:
    """A service that crashed and whose restart hangs before its health token (stuck in start-up,
    or unable to link) was left "starting" for good: the run went on without it, nothing said.
    Now, past its ``ready_timeout_s`` from the restart, it is hung: SIGKILL, then a restart."""
    run, once = tmp_path / "run", tmp_path / "ready-once"
    est = ('[[processes]]\nname = "est"\nservice = "estimator"\nready_timeout_s = 3.0\n'
           f'command = ["{sys.executable}", "{DUMMY}", "--service", "estimator", '
           f'"--exit-after", "1", "--code", "1", "--ready-once", "{once}"]\n')
    la = launch(procs, zenoh_env, write_profile(tmp_path, est), tmp_path)
    hung = wait_for(lambda: of(run, "est", "hung"), 40, what="the restart found hung")[0]
    assert "not ready" in hung["reason"], hung
    starts = of(run, "est", "start")
    assert len(starts) == 2 and hung["t_unix_s"] - starts[1]["t_unix_s"] >= 3.0
    wait_for(lambda: len(of(run, "est", "start")) == 3, 30, what="restarted again")
    assert procs.stop(la, signal.SIGINT, timeout_s=20) < 20


def test_a_second_ctrl_c_stops_faster_in_order_and_keeps_the_recording_whole(procs, zenoh_env,
                                                                             tmp_path) -> None:
    run = tmp_path / "run"
    stubborn = ('[[processes]]\nname = "sim"\nservice = "sim"\nafter = ["recorder"]\n'
                f'command = ["{sys.executable}", "{DUMMY}", "--service", "sim", "--ignore-sigint"]\n'
                "stop_timeout_s = 60.0\n")
    la = launch(procs, zenoh_env, write_profile(tmp_path, RECORDER + stubborn), tmp_path)
    wait_for(lambda: "all ready" in procs.log(la), 60, what="all ready")
    t0 = time.monotonic()
    la.send_signal(signal.SIGINT)
    wait_for(lambda: "stopping..." in procs.log(la), 10, what="the stop under way")
    time.sleep(0.5)  # the stand-in ignores SIGINT: the launcher would wait for it for 60 s
    la.send_signal(signal.SIGINT)
    la.wait(30)
    took = time.monotonic() - t0
    out = procs.log(la)
    assert la.returncode == 0, out
    assert took < 15, out
    assert "Ctrl-C again: stopping faster" in out
    assert "sim ignored SIGINT for 0.5 s; SIGKILL" in out
    assert "process   state" in out and "stopped in" in out  # the status table, as on one Ctrl-C
    stopped = [e["process"] for e in events(run) if e["event"] == "stopped"]
    assert stopped == ["sim", "recorder"]  # in order, the recorder last
    recording = run / "recording.mcap"
    assert finished(recording), "the recorder did not finish its file"
