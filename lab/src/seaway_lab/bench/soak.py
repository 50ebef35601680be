"""``seaway bench soak``: a lockstep stack flies missions back to back for a set time; each
service's memory at the start and at the end, the messages recorded and the drops.

The stack is ``seaway launch sim-batch --stay`` (sim, estimator, controller and recorder as separate
processes, on a private Zenoh rendezvous, with the run's own credentials). The bench is its
operator: each time the mission completes it restarts the scenario (a new lockstep episode from
t = 0) and sends the mission again, until ``--duration`` (default 600 s) of wall time has passed; it
then stops the stack with SIGINT, as Ctrl-C would, so the recorder finishes its file.

Memory is each process's resident set (``VmRSS``, read from ``/proc``) for every service and for
the launcher, sampled every ``--sample-interval`` (default 5 s) from the moment the first mission
has completed (warm: solvers loaded, buffers grown) until the last one has. Two figures per process:

- growth start -> end [%]: the last sample against the first, as a plain comparison;
- steady growth [%] and slope [MB/h]: a least-squares line through the samples after a warm-up
  span (the first third of the run, ``STEADY_FROM``); the growth is that line's rise over the
  steady span as a percentage of its value where the span begins.

Target (issue 14): steady growth under 5 % for every process, the launcher included. The target
applies to the steady figure, not to start -> end, because a process's RSS also rises once while
it warms up after the first mission (glibc's per-thread malloc arenas filling, caches growing)
and then stays flat: start -> end counts that step, which is not a leak and whose size varies from
run to run, while a leak keeps rising after it and shows in the steady line. Messages recorded and
drops come from the recorder's own summary (what it wrote, what its queue dropped, what was
malformed).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
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
STEADY_FROM = 1.0 / 3.0
"""Where the steady part of the run begins, as a fraction of its length: the warm-up before it."""


def steady_trend(
    samples: list[tuple[float, int]], steady_from: float = STEADY_FROM
) -> tuple[float, float] | None:
    """Growth over the steady part of a run: ``(growth_pct, slope_mb_per_h)``, or None if the
    steady part holds fewer than three samples.

    ``samples``: ``(t_s, rss_bytes)`` in time order, ``t_s`` seconds from the run's start. The
    steady part is the samples at ``t_s >= steady_from * t_last``; through them a least-squares
    line; ``slope_mb_per_h`` is its slope [MB/h, 1 MB = 1e6 bytes] and ``growth_pct`` its rise over
    the steady span as a percentage of its value where the span begins."""
    if not samples:
        return None
    t_begin = steady_from * samples[-1][0]
    steady = [(t, float(b)) for t, b in samples if t >= t_begin]
    if len(steady) < 3:
        return None
    n = len(steady)
    t_mean = sum(t for t, _ in steady) / n
    b_mean = sum(b for _, b in steady) / n
    stt = sum((t - t_mean) ** 2 for t, _ in steady)
    if stt <= 0.0:
        return None
    slope_bps = sum((t - t_mean) * (b - b_mean) for t, b in steady) / stt
    t0, t1 = steady[0][0], steady[-1][0]
    at_t0 = b_mean + slope_bps * (t0 - t_mean)
    growth_pct = 100.0 * slope_bps * (t1 - t0) / at_t0
    return growth_pct, slope_bps * 3600.0 / 1e6


def rss_bytes(pid: int) -> int:
    """Resident set size of ``pid`` [bytes] (``VmRSS`` in ``/proc/<pid>/status``)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"process {pid} reports no VmRSS")


class RssSampler:
    """Samples the RSS of fixed processes every ``interval_s`` in a thread: ``(t_s, rss_bytes)``
    per name, ``t_s`` from ``start()``. A process that has gone is skipped (its series stops)."""

    def __init__(self, pids: dict[str, int], interval_s: float) -> None:
        self.pids = dict(pids)
        self.interval_s = interval_s
        self.samples: dict[str, list[tuple[float, int]]] = {name: [] for name in pids}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="rss-sampler", daemon=True)
        self._t0 = 0.0

    def sample(self) -> None:
        t = time.monotonic() - self._t0
        for name, pid in self.pids.items():
            # A process that has gone (a restart) stops its series: the bench reports it replaced.
            with contextlib.suppress(FileNotFoundError, ProcessLookupError, RuntimeError):
                self.samples[name].append((t, rss_bytes(pid)))

    def start(self) -> None:
        self._t0 = time.monotonic()
        self.sample()
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            self.sample()

    def stop(self) -> None:
        """Stop sampling and take one last sample (the end of the run)."""
        self._stop.set()
        self._thread.join()
        self.sample()


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
            [
                str(Path(sys.executable).parent / "seaway"),
                "launch",
                "sim-batch",
                "--scenario",
                scenario,
                "--controller",
                controller,
                "--stay",
                "--run-dir",
                str(run_dir),
            ],
            env=dict(os.environ, PYTHONUNBUFFERED="1"),
            stdout=self.log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
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
        reply = self.bus.request(
            keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=time.time_ns(), action="restart"), 10.0
        )
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


def soak(
    run_dir: Path, duration_s: float, scenario: str, controller: str, sample_interval_s: float = 5.0
) -> dict:
    """Fly back to back for ``duration_s``, sampling RSS every ``sample_interval_s``; the figures
    as a dict (``rss_samples``: name -> ``[(t_s, rss_bytes), ...]``)."""
    sc = load_scenario(scenario)
    assert sc.mission is not None, f"scenario {scenario} has no mission"
    stack = Stack(run_dir, scenario, controller)
    try:
        stack.wait_complete(sc.name)  # the launcher's mission: the warm-up
        pids = service_pids(run_dir)
        sampler = RssSampler({**pids, "launcher": stack.proc.pid}, sample_interval_s)
        sampler.start()
        t0 = time.monotonic()
        missions = 1
        while time.monotonic() - t0 < duration_s:
            mission = sc.mission.to_request(
                time.time_ns(), mission_id=f"soak-{missions}", controller=controller
            )
            stack.fly_again(mission)
            stack.wait_complete(mission.mission_id)
            missions += 1
        elapsed = time.monotonic() - t0
        sampler.stop()
        now_pids = service_pids(run_dir)
        replaced = sorted(s for s in pids if now_pids.get(s) != pids[s])
    finally:
        stack.stop()
    summary = recorder_summary(run_dir)
    series = sampler.samples
    return {
        "elapsed_s": elapsed,
        "missions": missions,
        "rss_samples": series,
        "rss_start": {n: v[0][1] for n, v in series.items() if v},
        "rss_end": {n: v[-1][1] for n, v in series.items() if v},
        "replaced": replaced,
        "restarts": restarts(run_dir),
        "recorder": summary,
        "launcher_rc": stack.proc.returncode,
    }


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench soak", description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--duration",
        type=positive_float,
        default=600.0,
        help="wall seconds of missions back to back after the first (default 600)",
    )
    ap.add_argument(
        "--scenario", default="paper-c1", help="scenario flown again and again (default paper-c1)"
    )
    ap.add_argument(
        "--controller",
        default="cc-empc",
        choices=["cc-empc", "eo-empc", "nmpc"],
        help="controller (default cc-empc)",
    )
    ap.add_argument(
        "--sample-interval",
        type=positive_float,
        default=5.0,
        help="seconds between RSS samples of each process (default 5)",
    )
    ap.add_argument(
        "--keep", type=Path, default=None, help="run folder to keep (default: a temporary one, removed)"
    )
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="seaway-bench-soak-") as tmp:
        run_dir = args.keep or Path(tmp) / "run"
        run_dir.parent.mkdir(parents=True, exist_ok=True)
        fig = soak(run_dir, args.duration, args.scenario, args.controller, args.sample_interval)
    res = BenchResult(
        "soak",
        f"Soak: {args.scenario} ({args.controller}) back to back in lockstep "
        f"for {fig['elapsed_s']:.0f} s, {fig['missions']} missions",
    )
    res.add("wall time [s]", round(fig["elapsed_s"], 1), note="after the first (warm-up) mission")
    res.add("missions flown", fig["missions"], note="including the warm-up")
    steady_begin_s = STEADY_FROM * fig["elapsed_s"]
    for name in (*SERVICES, "launcher"):
        a, b = fig["rss_start"].get(name), fig["rss_end"].get(name)
        if a is None or b is None:
            continue
        note = "restarted meanwhile: not comparable" if name in fig["replaced"] else ""
        res.add(f"{name} RSS start [MB]", round(a / 1e6, 1))
        res.add(f"{name} RSS end [MB]", round(b / 1e6, 1))
        res.add(
            f"{name} RSS growth [%]",
            round(100.0 * (b - a) / a, 2),
            note=note or "start -> end, warm-up included (no target)",
        )
        trend = None if note else steady_trend(fig["rss_samples"][name])
        if trend is None:
            res.add(
                f"{name} RSS steady growth [%]",
                "n/a",
                f"< {TARGET_GROWTH_PCT:g}",
                None,
                note or "too few samples in the steady part",
            )
            continue
        growth_pct, slope = trend
        res.add(
            f"{name} RSS steady growth [%]",
            round(growth_pct, 2),
            f"< {TARGET_GROWTH_PCT:g}",
            growth_pct < TARGET_GROWTH_PCT,
            f"least-squares line from {steady_begin_s:.0f} s to the end",
        )
        res.add(f"{name} RSS steady slope [MB/h]", round(slope, 2))
    rec = fig["recorder"]
    res.add("messages recorded", int(rec["messages"]))
    res.add("dropped by the recorder", int(rec["dropped"]), "0", int(rec["dropped"]) == 0)
    res.add("malformed", int(rec["malformed"]), "0", int(rec["malformed"]) == 0)
    res.add(
        "process restarts",
        sum(fig["restarts"].values()),
        "0",
        not fig["restarts"],
        ", ".join(f"{p} {n}" for p, n in fig["restarts"].items()),
    )
    res.meta = {
        "cpus": os.cpu_count(),
        "scenario": args.scenario,
        "controller": args.controller,
        "duration_s": args.duration,
        "recording_files": rec.get("files", []),
        "launcher_exit": fig["launcher_rc"],
        "sample_interval_s": args.sample_interval,
        "steady_from_s": round(steady_begin_s, 1),
    }
    res.sections["rss_samples_mb"] = {
        name: [[round(t, 1), round(b / 1e6, 2)] for t, b in series]
        for name, series in fig["rss_samples"].items()
    }
    return res
