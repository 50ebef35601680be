"""Fault tests on the real `sim` profile: processes SIGKILLed mid-mission, on real Zenoh and MAVLink.

One run of the lake mission (about a minute), three faults:

1. the controller is killed on the mission's second leg: vehicle_io's watchdog zeroes the thrust
   that reaches the (simulated) autopilot within its 300 ms, the launcher restarts the controller,
   and the new controller resumes the same mission at the same leg from its checkpoint;
2. the estimator is killed: restarted; the recording shows the gap in nav/state and its recovery;
3. vehicle_io is killed: restarted; the recording shows the gap in the sensor keys and their
   recovery; the autopilot's own loss failsafe held the boat meanwhile, so the controller paused the
   mission (the thrust did not reach the thrusters), and the launcher, which restarted the link,
   puts the still armed autopilot back in its mode and resumes it.

The mission then completes, and the launcher exits 0.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.recording.reader import iter_messages, open_paths
from seaway.runtime.bus import Bus

from tests.conftest import wait_for

pytestmark = pytest.mark.system
WATCHDOG_S = 0.3
TRUTH_PERIOD_S = 0.1  # the sim publishes sim/truth at the control period
LOAD_SLACK_S = 0.3  # delivery and scheduling between the processes on a busy machine


def starts(run: Path, name: str) -> list[dict]:
    path = run / "events.jsonl"
    if not path.exists():
        return []
    events = [json.loads(line) for line in path.read_text().splitlines()]
    return [e for e in events if e["process"] == name and e["event"] == "start"]


class Watch:
    """What the test sees on the bus, with its own receive times (monotonic)."""

    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.thrust_rx: list[float] = []
        self.truth: list[tuple[float, float, float]] = []
        self.status = None
        self.vehicle = None
        self.failsafes: list[str | None] = []
        bus.subscribe(keys.THRUST, callback=lambda _k, m: self._add(self.thrust_rx, time.monotonic()))
        bus.subscribe(keys.SIM_TRUTH, callback=lambda _k, m: self._add(
            self.truth, (time.monotonic(), m.thrust_port_n, m.thrust_starboard_n)))
        bus.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: setattr(self, "status", m))
        bus.subscribe(keys.VEHICLE_STATUS, callback=self._on_vehicle)

    def _on_vehicle(self, _key: str, msg) -> None:
        self.vehicle = msg
        self._add(self.failsafes, msg.failsafe)

    def _add(self, seq: list, item: object) -> None:
        with self.lock:
            seq.append(item)


def gaps(files: list[Path], suffix: str) -> list[float]:
    """Gaps between consecutive messages on ``suffix`` [s], by recorder receive time."""
    t = [m.log_time_ns for m in iter_messages(files) if m.topic.endswith(suffix)]
    return [(b - a) / 1e9 for a, b in itertools.pairwise(t)]


# A real-time mission with four kills, about 80 s; test_lockstep_restarts kills each member by default.
@pytest.mark.slow
def test_services_killed_mid_mission_are_restarted_and_the_mission_completes(procs, zenoh_env, tmp_path):
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--run-dir", str(run)],
                     zenoh_env, "launcher")
    with Bus.open("vessel1") as bus:
        w = Watch(bus)
        wait_for(lambda: w.status is not None and w.status.state == "active" and w.status.active_leg >= 2,
                 90, what="the mission on its second leg")
        leg_at_kill = w.status.active_leg

        # 1. The controller dies.
        (ctl,) = starts(run, "controller")
        os.kill(ctl["pid"], signal.SIGKILL)
        t_kill = time.monotonic()
        last_cmd = wait_for(lambda: w.thrust_rx[-1] if w.thrust_rx and
                            time.monotonic() - w.thrust_rx[-1] > 0.2 else None, 5, what="commands stop")
        zero = wait_for(lambda: next((t for t, a, b in list(w.truth) if t > last_cmd and a == b == 0.0),
                                     None), 5, what="zero thrust at the vessel")
        # The watchdog's 300 ms, plus the sim applying it and publishing truth at its 0.1 s period,
        # plus what a busy 2-core machine adds between processes (0.39 s seen with the other core
        # busy). Without the watchdog the last thrust stays on until the new controller commands,
        # seconds later: this still bites.
        assert zero - last_cmd <= WATCHDOG_S + TRUTH_PERIOD_S + LOAD_SLACK_S, zero - last_cmd
        print(f"controller killed: zero thrust at the vessel {zero - last_cmd:.3f} s after its last command")
        wait_for(lambda: "thrust_stale" in w.failsafes, 3, what="vehicle_io reporting thrust_stale")
        wait_for(lambda: len(starts(run, "controller")) == 2, 15, what="the controller restarted")
        wait_for(lambda: w.thrust_rx[-1] > t_kill + 0.5, 30, what="commands from the new controller")
        assert w.status.state == "active" and w.status.active_leg >= leg_at_kill  # resumed, not restarted
        assert "resumed mission 'lake'" in (run / "logs" / "controller.log").read_text()
        wait_for(lambda: w.failsafes[-1] is None, 5, what="the failsafe cleared")

        # 2. The estimator dies.
        (est,) = starts(run, "estimator")
        os.kill(est["pid"], signal.SIGKILL)
        wait_for(lambda: len(starts(run, "estimator")) == 2, 15, what="the estimator restarted")

        # 3. vehicle_io dies (the autopilot's own loss failsafe holds the boat meanwhile).
        time.sleep(2.0)
        (vio,) = starts(run, "vehicle_io")
        os.kill(vio["pid"], signal.SIGKILL)
        wait_for(lambda: len(starts(run, "vehicle_io")) == 2, 15, what="vehicle_io restarted")
        # Meanwhile the thrust did not reach the thrusters (no link, then the failsafe's HOLD): the
        # controller paused the mission, saying why (issue 14, item 2). The launcher restarted the
        # link and the autopilot stayed armed: it puts it back in its mode and resumes the mission
        # (issue 56, item 19; seaway.tools.launch.resume).
        wait_for(lambda: w.status.state == "paused" and "paused by the controller" in w.status.reason,
                 15, what="the mission paused by the controller")
        wait_for(lambda: w.status.state == "active", 30, what="the launcher resuming the mission")
        assert "mission resumed after the link restart" in procs.log(la)

        la.wait(120)
    out = procs.log(la)
    assert la.returncode == 0, out
    assert "mission complete" in out

    files = open_paths([run])
    # Each kill shows in the recording as exactly one gap (back-off + start: about a second) in what
    # that process produces, and then the stream recovers; there is no other hole. The estimator
    # keeps publishing (predicting) while vehicle_io is down, so only its own death shows in nav/state.
    for suffix in ("/nav/state", "/sensors/gnss"):
        g = gaps(files, suffix)
        holes = [i for i, x in enumerate(g) if x > 0.5]
        assert len(holes) == 1, (suffix, [round(g[i], 2) for i in holes])
        assert 0.5 < g[holes[0]] < 10.0
        assert len(g) - holes[0] > 50, f"{suffix} did not recover after its gap"
        print(f"{suffix}: one gap of {g[holes[0]]:.2f} s, then {len(g) - holes[0]} messages")


STOP_BUDGET_S = 5.0
"""From the Ctrl-C to every process of the stack gone (the stop takes 1-2 s on an idle machine)."""


def _gone(pid: int) -> bool:
    """The process has exited (reaped, or a zombie its parent has yet to reap)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    except OSError:
        return True


def test_ctrl_c_stops_the_real_sim_profile_within_5_s_without_orphans(procs, zenoh_env, tmp_path):
    """Timed: the stop (Ctrl-C to the last process gone, the recorder's file finished), not the
    report the launcher makes after it, which has a timeout of its own (REPORT_TIMEOUT_S)."""
    from seaway.tools.launch.final_report import REPORT_TIMEOUT_S

    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--run-dir", str(run)],
                     zenoh_env, "launcher")
    wait_for(lambda: "mission lake: accepted" in procs.log(la), 60, what="the mission under way")
    time.sleep(3.0)
    pids = [e["pid"] for name in ("recorder", "sim", "vehicle_io", "estimator", "controller")
            for e in starts(run, name)]
    assert len(pids) == 5
    t0 = time.monotonic()
    la.send_signal(signal.SIGINT)
    wait_for(lambda: all(map(_gone, pids)), 4 * STOP_BUDGET_S, what="every process stopped")
    took = time.monotonic() - t0
    assert took < STOP_BUDGET_S, procs.log(la)
    la.wait(REPORT_TIMEOUT_S + 30.0)  # then the report; the launcher still exits cleanly
    assert la.returncode == 0, procs.log(la)
    print(f"stopped in {took:.2f} s; launcher exited after {time.monotonic() - t0:.2f} s")
    # The recording was finished properly (indexed), not cut: it reads back with a summary.
    from mcap.reader import make_reader

    with open(run / "recording.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics.message_count > 100
