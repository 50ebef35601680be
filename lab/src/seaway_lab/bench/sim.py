"""``seaway bench sim``: simulated seconds per wall second in lockstep, against an instant responder.

The sim's lockstep loop (``seaway.runtime.lockstep_clock.LockstepClock`` over the sim's node: the
code ``seaway-sim`` runs in lockstep) runs in this process on its own Zenoh session; the responder
(``python -m seaway_lab.responder``) is a second process that answers each clock tick with a
ThrustCommand at once. Both use a private rendezvous port and vessel name, so a stack running on
the machine is neither heard nor disturbed.

Per period it times the whole protocol round: publish sensors, truth, disturbance and the tick,
wait for the command, step the plant. Target: >= 200x real time at the 0.1 s control period. The
baseline, measured in the same run, is the same core stepped in-process with no bus at all (plant,
disturbances and sensors, as the closed-loop benchmarks use it).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from seaway.runtime.argtypes import positive_float, positive_int, whole_number
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep_clock import LockstepClock
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode
from seaway_sim.world import load_world

from seaway_lab.bench.common import BenchResult, bench_credentials, free_rendezvous, restored_environ

TARGET_REAL_TIME_FACTOR = 200.0
READY_TIMEOUT_S = 30.0
BENCH_THRUST_N = (8.0, 6.0)
"""(T1 port, T2 starboard) [N] the responder answers with, and the plant alone is stepped with:
inside every shipped vessel's bounds (paper-sim's 10 N), so no demand is refused as absurd."""


@contextmanager
def _private_zenoh() -> Iterator[dict[str, str]]:
    """This process and its children on a private rendezvous port (restored afterwards)."""
    extra = bench_credentials()
    with restored_environ(ENV_RENDEZVOUS, ENV_CONFIG, *extra):
        os.environ[ENV_RENDEZVOUS] = free_rendezvous()
        os.environ.pop(ENV_CONFIG, None)
        os.environ.update(extra)
        yield dict(os.environ)


def _start_responder(env: dict[str, str], vessel: str) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-m", "seaway_lab.responder", "--vessel", vessel,
                          "--port-n", str(BENCH_THRUST_N[0]), "--starboard-n", str(BENCH_THRUST_N[1]),
                          "--log-level", "WARNING"],
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    ready = threading.Event()

    def watch() -> None:
        assert p.stdout is not None
        for line in p.stdout:
            if line.strip() == "READY":
                ready.set()

    threading.Thread(target=watch, daemon=True).start()
    if not ready.wait(READY_TIMEOUT_S):
        p.kill()
        raise RuntimeError("the lockstep responder did not start")
    return p


def _plant_only(scenario_name: str, period_ns: int, periods: int) -> list[float]:
    """Wall time per period of the core alone (step, sensors, truth and disturbance), no bus."""
    scenario, vessel = load_world(scenario_name)
    core = SimCore(scenario, vessel)
    out = []
    for _ in range(periods):
        t0 = time.perf_counter()
        core.advance(BENCH_THRUST_N, period_ns)
        core.take_samples()
        core.truth()
        core.disturbance()
        out.append(time.perf_counter() - t0)
    return out


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench sim", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="lake", help="scenario name or path (default lake)")
    ap.add_argument("--period", type=positive_float, default=0.1, help="control period [s]")
    ap.add_argument("--periods", type=positive_int, default=3000, help="timed lockstep periods")
    ap.add_argument("--warmup", type=whole_number(0), default=50, help="untimed periods first")
    args = ap.parse_args(argv)
    period_ns = round(args.period * 1e9)
    vessel_key = f"bench-{os.getpid()}"
    scenario, vessel = load_world(args.scenario)
    stop = threading.Event()
    walls: list[float] = []
    with _private_zenoh() as env:
        responder = _start_responder(env, vessel_key)
        try:
            with Bus.open(vessel_key) as bus:
                app = SimNode(SimCore(scenario, vessel), lockstep=True)
                loop = LockstepClock(bus, app, args.period, stop, stall_s=0.5)
                for k in range(args.warmup + args.periods):
                    t0 = time.perf_counter()
                    period = loop.publish_period()
                    cmd = loop.wait_for(period, loop.command)  # the responder is no member
                    if cmd is None:
                        raise RuntimeError(f"no command for t_k = {period.stamp_ns} ns")
                    loop.step(cmd, period)
                    if k >= args.warmup:
                        walls.append(time.perf_counter() - t0)
                stats = loop.stats
        finally:
            responder.terminate()
            responder.wait(5)
    base = _plant_only(args.scenario, period_ns, args.periods)

    res = BenchResult("sim", f"Sim lockstep against an instant responder process, scenario "
                             f"{scenario.name}, period {args.period:g} s")
    factor = args.periods * args.period / sum(walls)
    res.add("real_time_factor", factor, f">= {TARGET_REAL_TIME_FACTOR:g}",
            factor >= TARGET_REAL_TIME_FACTOR, "simulated s per wall s, whole run")
    res.add("period_wall_median_ms", median(walls) * 1e3, note="publish + wait command + step")
    res.add("period_wall_p99_ms", percentile(walls, 99) * 1e3)
    res.add("real_time_factor_at_median", args.period / median(walls))
    res.add("plant_only_real_time_factor", args.periods * args.period / sum(base),
            note="baseline: same core in-process, no bus")
    res.add("plant_only_period_median_us", median(base) * 1e6)
    res.add("bus_share_of_period", 1.0 - median(base) / median(walls),
            note="fraction of a period spent on the protocol round trip")
    res.meta.update({"periods_timed": args.periods, "stale_commands": stats.stale_commands,
                     "repeats": stats.repeats, "cpus": os.cpu_count()})
    return res
