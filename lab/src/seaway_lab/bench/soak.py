"""``seaway bench soak``: a lockstep stack flies missions back to back for a set time; each
service's memory at the start and at the end, the messages recorded and the drops.

The stack is ``seaway launch sim-batch --stay`` (sim, estimator, controller and recorder as separate
processes, on a private Zenoh rendezvous, with the run's own credentials). The bench is its
operator: each time the mission completes it restarts the scenario (a new lockstep episode from
t = 0) and sends the mission again, until ``--duration`` (default 600 s) of wall time has passed; it
then stops the stack with SIGINT, as Ctrl-C would, so the recorder finishes its file.

Memory is each process's resident set (``VmRSS``), read from ``/proc`` at two comparable moments:
when the first mission has completed (warm: solvers loaded, buffers grown) and when the last one
has. Target (issue 14): growth under 5 % for every service. Messages recorded and drops come from
the recorder's own summary (what it wrote, what its queue dropped, what was malformed).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import MissionStatus, ScenarioRequest
from seaway.runtime import stacks
from seaway.runtime.argtypes import positive_float
from seaway.runtime.bus import Bus
from seaway.runtime.credentials import ENV_CREDENTIALS, ENV_IDENTITY
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch.events import EVENTS_FILE

from seaway_lab.bench.common import BenchResult, free_rendezvous

SERVICES = ("sim", "estimator", "controller", "recorder")
TARGET_GROWTH_PCT = 5.0
VESSEL = "vessel1"
MISSION_TIMEOUT_S = 600.0
"""Longest one mission may take (wall) before the soak gives up."""


def rss_bytes(pid: int) -> int:
    """Resident set size of ``pid`` [bytes] (``VmRSS`` in ``/proc/<pid>/status``)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"process {pid} reports no VmRSS")


def service_pids(run_dir: Path) -> dict[str, int]:
    """The current process of each service, from the launcher's events log (its last start)."""
    pids: dict[str, int] = {}
    for line in (run_dir / EVENTS_FILE).read_text().splitlines():
        ev = json.loads(line)
        if ev["event"] == "start" and ev["process"] in SERVICES:
            pids[ev["process"]] = ev["pid"]
    return pids


def restarts(run_dir: Path) -> dict[str, int]:
    starts: dict[str, int] = {}
    for line in (run_dir / EVENTS_FILE).read_text().splitlines():
        ev = json.loads(line)
        if ev["event"] == "start":
            starts[ev["process"]] = starts.get(ev["process"], 0) + 1
    return {p: n - 1 for p, n in starts.items() if n > 1}


def recorder_summary(run_dir: Path) -> dict:
    """The recorder's summary: the last JSON line it printed (its log, through the launcher)."""
    for line in reversed((run_dir / "logs" / "recorder.log").read_text().splitlines()):
        if line.startswith("{") and '"files"' in line:
            return json.loads(line)
    raise RuntimeError(f"no recorder summary in {run_dir / 'logs' / 'recorder.log'}")


class Stack:
    """``seaway launch sim-batch --stay`` in the background, and this bench as its operator."""

    def __init__(self, run_dir: Path, scenario: str, controller: str) -> None:
        self.run_dir = run_dir
        endpoint = free_rendezvous()
        # This process and the launcher: the same private rendezvous and stack registry.
        os.environ[ENV_RENDEZVOUS] = endpoint
        os.environ[ENV_STACKS_DIR] = str(run_dir.parent / "stacks")
        for var in (ENV_CONFIG, ENV_CREDENTIALS, ENV_IDENTITY):
            os.environ.pop(var, None)  # the launcher makes the run's credentials (authentication on)
        self.log = open(run_dir.parent / "launch.log", "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(
            [str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
             scenario, "--controller", controller, "--stay", "--run-dir", str(run_dir)],
            env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=self.log,
            stderr=subprocess.STDOUT, start_new_session=True)
        entry = None
        deadline = time.monotonic() + 120
        while entry is None:
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"the stack did not start:\n{self.tail()}")
            time.sleep(0.2)
            entry = stacks.lookup(endpoint)
        self.bus = Bus.open(VESSEL, identity="operator", credentials=entry.session_credentials())
        self.status = self.bus.subscribe(keys.MISSION_STATUS, mode="latest")

    def tail(self, n: int = 30) -> str:
        self.log.flush()
        return "\n".join((self.run_dir.parent / "launch.log").read_text().splitlines()[-n:])

    def wait_complete(self, mission_id: str) -> None:
        deadline = time.monotonic() + MISSION_TIMEOUT_S
        while True:
            s: MissionStatus | None = self.status.latest()
            if s is not None and s.mission_id == mission_id and s.state == "complete":
                return
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"mission {mission_id} did not complete:\n{self.tail()}")
            time.sleep(0.01)

    def fly_again(self, mission) -> None:
        """A new episode of the scenario, then its mission (each request must be accepted)."""
        reply = self.bus.request(keys.SIM_SCENARIO,
                                 ScenarioRequest(stamp_ns=time.time_ns(), action="restart"), 10.0)
        if not reply.accepted:
            raise RuntimeError(f"scenario restart refused: {reply.reason}")
        reply = self.bus.request(keys.MISSION_SET, mission, 10.0)
        if not reply.accepted:
            raise RuntimeError(f"mission {mission.mission_id} refused: {reply.reason}")

    def stop(self) -> None:
        try:
            self.proc.send_signal(signal.SIGINT)
            self.proc.wait(300)
        finally:
            if self.proc.poll() is None:
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.bus.close()
            self.log.close()


def soak(run_dir: Path, duration_s: float, scenario: str, controller: str) -> dict:
    """Fly back to back for ``duration_s``; the figures as a dict."""
    sc = load_scenario(scenario)
    assert sc.mission is not None, f"scenario {scenario} has no mission"
    stack = Stack(run_dir, scenario, controller)
    try:
        stack.wait_complete(sc.name)  # the launcher's mission: the warm-up
        pids = service_pids(run_dir)
        launcher_pid = stack.proc.pid
        start = {s: rss_bytes(pid) for s, pid in pids.items()}
        start["launcher"] = rss_bytes(launcher_pid)
        t0 = time.monotonic()
        missions = 1
        while time.monotonic() - t0 < duration_s:
            mission = sc.mission.to_request(time.time_ns(), mission_id=f"soak-{missions}",
                                            controller=controller)
            stack.fly_again(mission)
            stack.wait_complete(mission.mission_id)
            missions += 1
        elapsed = time.monotonic() - t0
        now_pids = service_pids(run_dir)
        end = {s: rss_bytes(pid) for s, pid in now_pids.items()}
        end["launcher"] = rss_bytes(launcher_pid)
        replaced = sorted(s for s in pids if now_pids.get(s) != pids[s])
    finally:
        stack.stop()
    summary = recorder_summary(run_dir)
    return {"elapsed_s": elapsed, "missions": missions, "rss_start": start, "rss_end": end,
            "replaced": replaced, "restarts": restarts(run_dir), "recorder": summary,
            "launcher_rc": stack.proc.returncode}


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench soak", description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=positive_float, default=600.0,
                    help="wall seconds of missions back to back after the first (default 600)")
    ap.add_argument("--scenario", default="paper-c1",
                    help="scenario flown again and again (default paper-c1)")
    ap.add_argument("--controller", default="cc-empc", choices=["cc-empc", "eo-empc", "nmpc"],
                    help="controller (default cc-empc)")
    ap.add_argument("--keep", type=Path, default=None,
                    help="run folder to keep (default: a temporary one, removed)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="seaway-bench-soak-") as tmp:
        run_dir = args.keep or Path(tmp) / "run"
        run_dir.parent.mkdir(parents=True, exist_ok=True)
        fig = soak(run_dir, args.duration, args.scenario, args.controller)
    res = BenchResult("soak", f"Soak: {args.scenario} ({args.controller}) back to back in lockstep "
                              f"for {fig['elapsed_s']:.0f} s, {fig['missions']} missions")
    res.add("wall time [s]", round(fig["elapsed_s"], 1), note="after the first (warm-up) mission")
    res.add("missions flown", fig["missions"], note="including the warm-up")
    for name in (*SERVICES, "launcher"):
        a, b = fig["rss_start"].get(name), fig["rss_end"].get(name)
        if a is None or b is None:
            continue
        growth = 100.0 * (b - a) / a
        target = f"< {TARGET_GROWTH_PCT:g}" if name in SERVICES else None
        ok = growth < TARGET_GROWTH_PCT if name in SERVICES else None
        note = "restarted meanwhile: not comparable" if name in fig["replaced"] else ""
        res.add(f"{name} RSS start [MB]", round(a / 1e6, 1))
        res.add(f"{name} RSS end [MB]", round(b / 1e6, 1))
        res.add(f"{name} RSS growth [%]", round(growth, 2), target,
                None if note else ok, note)
    rec = fig["recorder"]
    res.add("messages recorded", int(rec["messages"]))
    res.add("dropped by the recorder", int(rec["dropped"]), "0", int(rec["dropped"]) == 0)
    res.add("malformed", int(rec["malformed"]), "0", int(rec["malformed"]) == 0)
    res.add("process restarts", sum(fig["restarts"].values()), "0", not fig["restarts"],
            ", ".join(f"{p} {n}" for p, n in fig["restarts"].items()))
    res.meta = {"cpus": os.cpu_count(), "scenario": args.scenario, "controller": args.controller,
                "duration_s": args.duration, "recording_files": rec.get("files", []),
                "launcher_exit": fig["launcher_rc"]}
    return res
