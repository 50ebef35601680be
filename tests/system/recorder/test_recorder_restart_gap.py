"""A recorder killed in real time and restarted by the launcher (#56 item 20): what was published
while it was away is in the recording (the publishers' caches, asked by the restarted recorder),
once, and the restart is said in the file."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from seaway.recording.recover import recover

from tests.conftest import wait_for
from tests.system.recorder.test_foxglove_recording import SCENARIO
from tests.unit.recorder.foxglove_check import invalid_messages

pytestmark = [pytest.mark.system, pytest.mark.slow]
BIN = Path(sys.executable).parent
V = "vessel1"
GOAL_S = 0.1


def recorder_pids(run_dir: Path) -> list[int]:
    path = run_dir / "events.jsonl"
    if not path.is_file():
        return []
    return [
        e["pid"]
        for e in map(json.loads, path.read_text().splitlines())
        if e["process"] == "recorder" and e["event"] == "start"
    ]


def messages(path: Path) -> list[tuple[str, bytes, int]]:
    """(topic, bytes, log time) of every message of a recording (a killed one read as far as whole)."""
    out: list[tuple[str, bytes, int]] = []
    if not path.is_file():
        return out
    with open(path, "rb") as fh:
        try:
            for _, ch, m in make_reader(fh).iter_messages(log_time_order=False):
                out.append((ch.topic, bytes(m.data), m.log_time))
        except Exception:
            pass
    return out


@pytest.mark.timeout(400)
def test_a_recorder_killed_in_real_time_loses_at_most_100_ms(tmp_path, zenoh_env) -> None:
    scenario = tmp_path / "short.toml"
    scenario.write_text(SCENARIO)
    run_dir = tmp_path / "run"
    launcher = subprocess.Popen(
        [str(BIN / "seaway"), "launch", "sim", "--scenario", str(scenario), "--run-dir", str(run_dir)],
        env=zenoh_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        first = wait_for(lambda: recorder_pids(run_dir), 120, what="the recorder started")[0]
        log = run_dir / "logs" / "controller.log"
        wait_for(
            lambda: log.is_file() and "mission" in log.read_text() and "accepted" in log.read_text(),
            120,
            interval_s=0.2,
            what="the mission accepted",
        )
        time.sleep(8.0)  # well under way (the leg takes about 30 s)
        t_kill = time.time_ns()
        os.kill(first, signal.SIGKILL)
        out, _ = launcher.communicate(timeout=300)
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGKILL)
            launcher.wait(10)
    assert launcher.returncode == 0, out[-3000:]
    assert len(recorder_pids(run_dir)) == 2, out[-3000:]  # restarted once

    # The killed file, repaired here (seaway record recover): readers repair into a cache of their
    # own, never into the run folder.
    repaired = tmp_path / "killed.recovered.mcap"
    recover(run_dir / "recording.mcap", repaired)
    killed = messages(repaired)
    restarted = messages(run_dir / "recording.restart-001.mcap")
    # The restart is said in the file, with the time it asked the publishers for.
    (marker,) = [json.loads(d) for t, d, _ in restarted if t == "recorder/restart"]
    assert marker["previous_file"] == "recording.mcap" and marker["gap_unrecovered_s"] == 0
    assert marker["previous_last_ns"] <= t_kill <= marker["stamp_ns"]

    # Both files validate against their channels' schemas, the recalled samples and the marker too
    # (a real-time run: vehicle_io's status, with its unknown fields, among them).
    for path in (repaired, run_dir / "recording.restart-001.mcap"):
        checked, invalid = invalid_messages(path)
        assert checked > 500 and invalid == {}, (path.name, {t: e[0] for t, e in invalid.items()})

    # Each steady topic's samples, by their own stamps, across the kill: no gap beyond its period
    # plus the goal, and no sample in both files.
    worst = {}
    for suffix in ("sensors/attitude", "sensors/gnss", "nav/state", "ctrl/thrust", "sim/truth"):
        key = f"seaway/{V}/{suffix}"
        a = [d for t, d, _ in killed if t == key]
        b = [d for t, d, _ in restarted if t == key]
        assert a and b, suffix
        assert not set(a) & set(b), f"{suffix}: {len(set(a) & set(b))} samples written twice"
        stamps = sorted(json.loads(d)["stamp_ns"] for d in a + b)
        steps = [(y - x) / 1e9 for x, y in itertools.pairwise(stamps)]
        period = sorted(steps)[len(steps) // 2]
        near = [s for s, x in zip(steps, stamps, strict=False) if abs(x - t_kill) < 15e9]
        worst[suffix] = (max(near), period)
    print("largest step near the kill, median step [s]:", worst)
    for suffix, (step, period) in worst.items():
        assert step <= period + GOAL_S, (suffix, step, period)
