"""The ``fleet`` profile as shipped (two simulated vessels, each with its own simulated PX4 behind
MAVLink, vehicle_io, estimator, controller and recorder; one ground station), in real time.

Every request goes to one vessel, by the ground station's API or by ``seaway vehicle``: disarm,
mode HOLD and back, arm, then a different mission to each. The test listens to both vessels' vehicle
and mission statuses all along, on its own session: what is asked of one vessel never shows on the
other. Both missions complete; then each vessel's recording holds that vessel's keys only and its
report names that vessel's mission only.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import threading
from collections import defaultdict
from typing import Any

import pytest
from seaway.contract import keys
from seaway.runtime.bus import Bus
from seaway.runtime.credentials import ENV_IDENTITY

from tests.conftest import BIN, wait_for
from tests.system.groundstation.helpers import http

pytestmark = pytest.mark.system
A, B = "vessel1", "vessel2"
MISSIONS = {
    A: {"mission_id": "fleet-a", "waypoints": [{"x_m": 0.0, "y_m": 0.0}, {"x_m": 14.0, "y_m": 0.0},
                                               {"x_m": 14.0, "y_m": 8.0}]},
    B: {"mission_id": "fleet-b", "waypoints": [{"x_m": 0.0, "y_m": 0.0}, {"x_m": 0.0, "y_m": -14.0},
                                               {"x_m": 8.0, "y_m": -14.0}]},
}
PARAMS = {"coa_radius_m": 2.0, "task_power_w": 250.0, "controller": "cc-empc"}
PAGE_LINE = re.compile(r"^ground station: (http://127\.0\.0\.1:\d+/)#token=(\S+)$", re.MULTILINE)




class Heard:
    """Every vehicle and mission status of every vessel, as (vessel, message), from the bus."""

    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.vehicle: dict[str, list] = defaultdict(list)
        self.mission: dict[str, list] = defaultdict(list)
        for spec, into in ((keys.VEHICLE_STATUS, self.vehicle), (keys.MISSION_STATUS, self.mission)):
            bus.subscribe(spec, mode="fifo", vessel="*",
                          callback=lambda key, msg, into=into: self._add(into, key, msg))

    def _add(self, into: dict[str, list], key: str, msg: Any) -> None:
        with self.lock:
            into[key.split("/")[1]].append(msg)

    def since(self, kind: str, vessel: str, n: int = 0) -> list:
        with self.lock:
            return list(getattr(self, kind)[vessel][n:])

    def count(self, kind: str, vessel: str) -> int:
        with self.lock:
            return len(getattr(self, kind)[vessel])

    def latest(self, kind: str, vessel: str) -> Any:
        got = self.since(kind, vessel)
        return got[-1] if got else None


@pytest.mark.slow  # two real-time missions, about 36 s; test_fleet_launch runs by default
def test_two_vessels_fly_different_missions_and_a_command_to_one_never_reaches_the_other(
        procs, zenoh_env, tmp_path) -> None:
    from seaway.recording.reader import read_info

    run = tmp_path / "run"
    launcher = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "fleet", "--run-dir",
                            str(run)], zenoh_env, "launcher")

    def launched(text: str):
        def check() -> bool:
            if launcher.poll() is not None:
                pytest.fail(f"the launcher exited ({launcher.returncode}):\n"
                            f"{procs.log(launcher)[-3000:]}")
            return text in procs.log(launcher)
        return check

    wait_for(launched(f"{B}: arm: accepted"), 300, interval_s=0.5, what="both vessels ready and armed")
    out = procs.log(launcher)
    assert f"{A}: mode MANUAL: accepted" in out and f"{A}: arm: accepted" in out
    line = PAGE_LINE.search(out)
    assert line, out
    base, token = line.group(1), line.group(2)

    with Bus.open(A) as bus:
        heard = Heard(bus)
        for v in (A, B):
            wait_for(lambda v=v: (s := heard.latest("vehicle", v)) is not None and s.armed
                     and s.mode == "MANUAL", 60, what=f"{v} armed in MANUAL")
            wait_for(lambda v=v: heard.latest("mission", v) is not None, 60, what=f"{v}'s mission status")
        status, body = http("GET", base + "api/vessels")
        assert status == 200 and {A, B} <= {v["vessel"] for v in body["vessels"]}, body
        idle_b = heard.latest("mission", B)
        assert idle_b.mission_id == "" or idle_b.state != "active", idle_b
        b_vehicle, b_mission = heard.count("vehicle", B), heard.count("mission", B)

        # Vehicle commands to A: by the API (with the token the launcher printed) and by the CLI.
        status, body = http("POST", base + f"api/vessels/{A}/disarm", {"force": False}, token=token)
        assert status == 200 and body["accepted"], body
        wait_for(lambda: not heard.latest("vehicle", A).armed, 30, what=f"{A} disarmed")
        operator = {k: v for k, v in zenoh_env.items() if k != ENV_IDENTITY}  # as an operator
        cli = subprocess.run([str(BIN / "seaway"), "vehicle", "mode", "HOLD", "--vessel", A,
                              "--timeout", "60"], env=operator, capture_output=True, text=True,
                             timeout=120, check=False)
        assert cli.returncode == 0 and "mode HOLD: accepted" in cli.stdout, cli.stdout + cli.stderr
        wait_for(lambda: heard.latest("vehicle", A).mode == "HOLD", 30, what=f"{A} in HOLD")
        for ask, body_in in (("mode", {"mode": "MANUAL"}), ("arm", {"force": False})):
            status, body = http("POST", base + f"api/vessels/{A}/{ask}", body_in, token=token)
            assert status == 200 and body["accepted"], body
        wait_for(lambda: (s := heard.latest("vehicle", A)).armed and s.mode == "MANUAL", 30,
                 what=f"{A} armed in MANUAL again")
        # B heard all along (its statuses kept coming), and none of it changed.
        wait_for(lambda: heard.count("vehicle", B) > b_vehicle + 2, 30, what=f"{B}'s status going on")
        for s in heard.since("vehicle", B, b_vehicle):
            assert s.armed and s.mode == "MANUAL" and s.link_ok, s
        for m in heard.since("mission", B, b_mission):
            assert (m.mission_id, m.state) == (idle_b.mission_id, idle_b.state), m

        # A mission to A only; B goes on idle while A flies.
        status, body = http("POST", base + f"api/vessels/{A}/mission", {**MISSIONS[A], **PARAMS},
                            token=token)
        assert status == 200 and body["accepted"], body
        wait_for(lambda: (m := heard.latest("mission", A)).mission_id == "fleet-a"
                 and m.state == "active" and m.active_leg >= 1, 120, what=f"{A} flying fleet-a")
        for m in heard.since("mission", B, b_mission):
            assert (m.mission_id, m.state) == (idle_b.mission_id, idle_b.state), m
        for s in heard.since("vehicle", B, b_vehicle):
            assert s.armed and s.mode == "MANUAL", s

        # B's own mission; both complete.
        status, body = http("POST", base + f"api/vessels/{B}/mission", {**MISSIONS[B], **PARAMS},
                            token=token)
        assert status == 200 and body["accepted"], body
        for v in (A, B):
            mid = MISSIONS[v]["mission_id"]
            wait_for(lambda v=v, mid=mid: (m := heard.latest("mission", v)).mission_id == mid
                     and m.state == "complete", 300, interval_s=0.5, what=f"{v} completing {mid}")
        # What each vessel's controller ever said: its own mission only.
        assert {m.mission_id for m in heard.since("mission", A)} <= {"", idle_b.mission_id, "fleet-a"}
        assert "fleet-a" not in {m.mission_id for m in heard.since("mission", B)}
        assert "fleet-b" not in {m.mission_id for m in heard.since("mission", A)}

    assert procs.stop(launcher, signal.SIGINT, timeout_s=400) < 400
    assert launcher.returncode == 0, procs.log(launcher)[-3000:]
    assert not list(run.glob("*.mcap"))  # nothing recorded for the fleet as a whole
    for v, other in ((A, B), (B, A)):
        folder = run / v
        assert json.loads((folder / "run.json").read_text())["vessel"] == v
        info = read_info([folder / "recording.mcap"])
        bus_topics = [t for t in info.topics if t.startswith(f"{keys.ROOT}/")]
        assert bus_topics and all(t.startswith(f"{keys.ROOT}/{v}/") for t in bus_topics), info.topics
        assert f"{keys.ROOT}/{v}/{keys.SIM_TRUTH.suffix}" in bus_topics
        report = json.loads((folder / "report" / "metrics.json").read_text())
        assert report["vessel"] == v
        flown = [m for m in report["missions"] if m["mission_id"]]
        assert [m["mission_id"] for m in flown] == [MISSIONS[v]["mission_id"]], report["missions"]
        assert flown[0]["controller_reported"]["state"] == "complete"
        events = (folder / "events.jsonl").read_text()
        assert f'"sim-{v}"' in events and f'"sim-{other}"' not in events
