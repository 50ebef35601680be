"""``seaway bench groundstation``: the live stream to many WebSocket clients, and one slow client.

A real ``seaway-groundstation`` process (its own identity, the run's credentials, a private
rendezvous port) serves the stream; this process plays one vessel on the bus (a health token, the
state estimate at ``--state-hz`` and a solve record with a 20-point predicted trajectory at
``--solve-hz``, as the estimator and the controller publish them) and opens ``--clients`` WebSocket
clients on ``/api/stream`` in one asyncio loop.

Each state carries its sequence number in ``stamp_ns``; this process keeps the monotonic time of
each ``put``, and each client the monotonic time at which a frame carrying that state arrived, so
the latency is *bus to client*: publication, Zenoh, the ground station's fleet, its stream hub, the
WebSocket and the client's parsing (the client's own share is small: ``json.loads`` of one frame).
Only the state is timed; the solve records are there for the frame sizes and rates.

Two phases in the same run, each ``--seconds`` long, on the same server:

* ``steady``: ``--clients`` clients that read as fast as frames come;
* ``slow``: the same plus one client that stops reading (its socket fills up, the
  server's send to it blocks), so the others' figures show whether it holds them up.

Figures, per phase (``steady_*``, ``slow_*``): frames per second per client (the stream sends each
vessel's kinds at up to 20 Hz each), the median and p99 latency of the timely clients (target p99 <
20 ms), the server's CPU [% of one core]; then the ratio of the timely clients' p99 with and without
the slow client (target <= 1.5: the slow one must not raise the others') and the server's resident
memory.

Then the replay (``groundstation_replay``): a recording of ``--replay-mb`` (40 MB) opened through
the API the page's replay view uses; the time to its first frame (target <= 3 s) and to its whole
timeline (target <= 10 s).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import SolveRecord, StateEstimate
from seaway.runtime import credentials
from seaway.runtime.argtypes import non_negative_float, positive_float, positive_int
from seaway.runtime.bus import Bus
from seaway.runtime.zenoh_bus import ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile

from seaway_lab.bench.common import BenchResult, free_rendezvous

TARGET_P99_MS = 20.0
TARGET_SLOW_RATIO = 1.5
VESSEL = "bench-gs"
HORIZON = 20
"""Points of the predicted trajectory in each solve record (the controller's horizon is of this order)."""


@dataclass
class ClientStats:
    """One client's frames and latencies [ms]."""

    frames: int = 0
    latencies_ms: list[float] = field(default_factory=list)


def _server_cpu_s(pid: int) -> float:
    """User + system CPU time of ``pid`` so far [s] (``/proc/<pid>/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _server_rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class Vessel:
    """This process as the vessel: publishes states and solves, remembers when each state left."""

    def __init__(self, bus: Bus, state_hz: float, solve_hz: float) -> None:
        self.bus, self.state_hz, self.solve_hz = bus, state_hz, solve_hz
        self.sent_ns: dict[int, int] = {}
        self.stop = threading.Event()
        self._state = bus.publisher(keys.NAV_STATE)
        self._solve = bus.publisher(keys.SOLVE)
        self._thread = threading.Thread(target=self._run, name="bench-vessel", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        seq, next_state, next_solve = 0, time.monotonic(), time.monotonic()
        xs = [float(i) for i in range(HORIZON)]
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= next_state:
                seq += 1
                msg = StateEstimate(stamp_ns=seq, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=seq * 0.1,
                                    y_m=0.0, psi_rad=0.0)
                self.sent_ns[seq] = time.monotonic_ns()
                self._state.put(msg)
                next_state += 1.0 / self.state_hz
            if now >= next_solve:
                self._solve.put(SolveRecord(
                    stamp_ns=seq, controller="cc-empc", status="Solve_Succeeded", success=True,
                    iterations=12, solve_time_s=0.004, leg_energy_to_go_j=900.0, cross_track_m=0.2,
                    predicted_x_m=xs, predicted_y_m=xs, predicted_psi_rad=xs,
                    predicted_thrust_port_n=xs, predicted_thrust_starboard_n=xs))
                next_solve += 1.0 / self.solve_hz
            self.stop.wait(max(0.0, min(next_state, next_solve) - time.monotonic()))

    def close(self) -> None:
        self.stop.set()
        self._thread.join(2)


async def _client(url: str, stats: ClientStats, until: float) -> None:
    from websockets.asyncio.client import connect

    async with connect(url, open_timeout=10, max_size=2**22) as ws:
        loop = asyncio.get_running_loop()
        while loop.time() < until:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=max(0.01, until - loop.time()))
            except TimeoutError:
                break
            t_ns = time.monotonic_ns()
            frame = json.loads(raw)
            stats.frames += 1
            state = frame.get("updates", {}).get("state")
            if state is not None:
                stats.latencies_ms.append(t_ns / 1e6)  # matched with the send time afterwards
                stats.latencies_ms.append(float(state["message"]["stamp_ns"]))


async def _slow_client(url: str, until: float, opened: asyncio.Event) -> None:
    """Connects, takes the first frame, then never reads again until the phase ends."""
    from websockets.asyncio.client import connect

    # close_timeout: its closing handshake cannot complete (the server is stuck sending to it).
    async with connect(url, open_timeout=10, max_queue=1, max_size=2**22, close_timeout=0.1) as ws:
        await ws.recv()
        opened.set()
        await asyncio.sleep(max(0.0, until - asyncio.get_running_loop().time()))


async def _phase(url: str, clients: int, seconds: float, slow: bool) -> tuple[list[ClientStats], float]:
    loop = asyncio.get_running_loop()
    until = loop.time() + seconds
    stats = [ClientStats() for _ in range(clients)]
    tasks = [asyncio.create_task(_client(url, s, until)) for s in stats]
    if slow:
        opened = asyncio.Event()
        tasks.append(asyncio.create_task(_slow_client(url, until, opened)))
    await asyncio.gather(*tasks)
    return stats, seconds


def _latencies(stats: list[ClientStats], sent_ns: dict[int, int]) -> list[float]:
    out = []
    for s in stats:
        pairs = s.latencies_ms
        for recv_ms, seq in zip(pairs[0::2], pairs[1::2], strict=True):
            sent = sent_ns.get(int(seq))
            if sent is not None:
                out.append(recv_ms - sent / 1e6)
    return out


def _start_server(env: dict[str, str], log_path: Path, *extra: str) -> tuple[subprocess.Popen, str]:
    exe = str(Path(sys.executable).parent / "seaway-groundstation")
    log = open(log_path, "wb")  # noqa: SIM115 - closed with the process
    proc = subprocess.Popen([exe, "--port", "0", "--log-level", "WARNING", *extra], env=env, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        m = re.search(r"groundstation: (http://\S+) token", log_path.read_text(errors="replace"))
        if m:
            return proc, m.group(1)
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    proc.kill()
    raise RuntimeError(f"seaway-groundstation did not start: {log_path.read_text(errors='replace')[-2000:]}")


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()


def _replay(res: BenchResult, args: argparse.Namespace, tmp: Path, env: dict[str, str]) -> None:
    from seaway_lab.bench import groundstation_replay

    def serve(runs: Path) -> tuple[str, Callable[[], None]]:
        proc, base = _start_server(env, tmp / "groundstation-replay.log", "--runs-dir", str(runs))
        return base, lambda: _stop(proc)

    groundstation_replay.measure(res, serve, tmp, env, args.replay_mb, args.replay_repeat,
                                 args.recording)


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench groundstation", description=__doc__.split("\n\n")[0])
    ap.add_argument("--clients", type=positive_int, default=50, help="timely stream clients (default 50)")
    ap.add_argument("--seconds", type=positive_float, default=10.0,
                    help="length of each phase [s] (default 10)")
    ap.add_argument("--state-hz", type=positive_float, default=20.0, help="state estimates published [Hz]")
    ap.add_argument("--solve-hz", type=positive_float, default=10.0, help="solve records published [Hz]")
    ap.add_argument("--replay-mb", type=non_negative_float, default=40.0,
                    help="size of the recording replayed [MB] (default 40; 0: no replay figures)")
    ap.add_argument("--replay-repeat", type=positive_int, default=3, help="opens of it timed (default 3)")
    ap.add_argument("--recording", type=Path, default=None,
                    help="replay this .mcap instead of making one from a lockstep run")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="seaway-bench-gs-") as tmp_dir:
        return _measure(args, Path(tmp_dir))


def _measure(args: argparse.Namespace, tmp: Path) -> BenchResult:
    folder = credentials.create(tmp / "credentials", harness=True).folder
    os.environ[ENV_RENDEZVOUS] = free_rendezvous()
    os.environ[credentials.ENV_CREDENTIALS] = str(folder)
    os.environ[credentials.ENV_IDENTITY] = "harness"
    env = {k: v for k, v in os.environ.items() if k != credentials.ENV_IDENTITY}
    env["PYTHONUNBUFFERED"] = "1"
    proc, base = _start_server(env, tmp / "groundstation.log")
    url = base.replace("http://", "ws://") + f"api/stream?vessel={VESSEL}"
    res = BenchResult("groundstation", f"Ground station stream: {args.clients} clients on /api/stream, "
                      f"state {args.state_hz:g} Hz + solve {args.solve_hz:g} Hz on the bus, "
                      f"{args.seconds:g} s per phase")
    try:
        with Bus.open(VESSEL) as bus:
            bus.declare_alive("estimator")
            vessel = Vessel(bus, args.state_hz, args.solve_hz)
            vessel.start()
            try:
                asyncio.run(_phase(url, 1, 2.0, slow=False))  # warm-up: the vessel is known, paths hot
                phases = {}
                for name, slow in (("steady", False), ("slow", True)):
                    cpu0, t0 = _server_cpu_s(proc.pid), time.monotonic()
                    stats, took = asyncio.run(_phase(url, args.clients, args.seconds, slow))
                    cpu = (_server_cpu_s(proc.pid) - cpu0) / (time.monotonic() - t0)
                    phases[name] = (stats, took, cpu)
            finally:
                vessel.close()
            rss = _server_rss_mib(proc.pid)
            sent = dict(vessel.sent_ns)
    finally:
        _stop(proc)
    p99 = {}
    for name, (stats, took, cpu) in phases.items():
        lat = _latencies(stats, sent)
        rates = [s.frames / took for s in stats]
        if not lat:
            raise SystemExit(f"seaway bench groundstation: no state reached the clients ({name} phase)")
        p99[name] = percentile(lat, 99)
        res.add(f"{name}_frames_per_client_hz", median(rates), note=f"median; min {min(rates):.1f}, "
                f"max {max(rates):.1f} (at most 20 Hz per kind: state {args.state_hz:g}, solve "
                f"{args.solve_hz:g})")
        res.add(f"{name}_latency_median_ms", median(lat), note="bus to client, the state")
        res.add(f"{name}_latency_p99_ms", p99[name], f"< {TARGET_P99_MS:g}", p99[name] < TARGET_P99_MS,
                note=f"{len(lat)} states timed")
        res.add(f"{name}_server_cpu_pct", 100 * cpu, note="of one core")
    ratio = p99["slow"] / p99["steady"]
    res.add("slow_over_steady_p99", ratio, f"<= {TARGET_SLOW_RATIO:g}", ratio <= TARGET_SLOW_RATIO,
            note="the timely clients' p99 with the slow client / without")
    res.add("server_rss_mib", rss)
    if args.replay_mb > 0 or args.recording is not None:
        _replay(res, args, tmp, env)
    res.meta.update(clients=args.clients, seconds_per_phase=args.seconds, state_hz=args.state_hz,
                    solve_hz=args.solve_hz, cpus=os.cpu_count())
    return res
