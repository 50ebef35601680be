"""``seaway bench lockstep``: a paper mission through the real processes in lockstep, against the
in-process closed loop in the same run.

The mission is paper condition #1 flown by CC-EMPC (333 s of simulated time, 3331 periods). Through
the processes: ``seaway launch sim-batch`` (sim, estimator, controller, recorder on a private Zenoh
rendezvous); the figure is the WARM stack's wall time, from the sim's first step to its hold at the
end, read from the recording (the recorder's receive time of each ``lockstep/*`` answer). In process:
``seaway_lab.closed_loop.run_closed_loop`` (the same cores and the same solver, no bus), warm.

Where a period's time goes comes from the same receive times: sim answer -> estimator answer
(transport and the estimator), -> controller answer (transport, the solve and its records),
-> recorder answer (transport and the write), -> the sim's next answer (transport and the plant).
Targets (issue 13): through the processes at most 2x the in-process loop, and at least 100x real time.
"""

from __future__ import annotations

import argparse
import itertools
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import PeriodDone
from seaway.simkit.scenario import load_scenario
from seaway.vessel.metrics import median, percentile
from seaway_recorder import recording

from seaway_lab.bench.common import BenchResult
from seaway_lab.closed_loop import run_closed_loop

SCENARIO, CONTROLLER = "paper-c1", "cc-empc"
TARGET_RATIO, TARGET_REAL_TIME = 2.0, 100.0
STAGES = ("sim", "estimator", "controller", "recorder")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def through_processes(run_dir: Path) -> dict[str, list[int]]:
    """Run the stack once; per stage, the receive times [ns] of each period's answer (by period)."""
    env = dict(os.environ, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{_free_port()}")
    env.pop("SEAWAY_ZENOH_CONFIG", None)
    subprocess.run([str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
                    SCENARIO, "--controller", CONTROLLER, "--run-dir", str(run_dir)],
                   env=env, check=True, capture_output=True, timeout=600)
    first: dict[str, dict[int, int]] = {s: {} for s in STAGES}
    topics = [keys.lockstep_spec(s).key("vessel1") for s in STAGES]
    for m in recording.iter_messages(recording.open_paths([run_dir]), topics):
        ans = PeriodDone.decode(m.data)
        first[ans.service].setdefault(ans.stamp_ns, m.log_time_ns)  # a repeat is not a new period
    return {s: [first[s][t] for t in sorted(first[s])] for s in STAGES}


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench lockstep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs through the processes (median)")
    args = ap.parse_args(argv)
    res = BenchResult("lockstep", "Lockstep: paper condition #1, CC-EMPC, through the processes vs "
                                  "in process")
    sc = load_scenario(SCENARIO)
    run_closed_loop(sc, CONTROLLER)  # warm: solvers loaded
    t0 = time.perf_counter()
    inproc = run_closed_loop(sc, CONTROLLER)
    inproc_s = time.perf_counter() - t0

    walls, stage_ms = [], {}
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory(prefix="seaway-bench-lockstep-") as tmp:
            times = through_processes(Path(tmp) / "run")
        sim = times["sim"]
        walls.append((sim[-1] - sim[1]) / 1e9)  # from the first step to the hold at the end
        n = min(len(v) for v in times.values() if v)
        chain = [(s, times[s][:n]) for s in STAGES if times[s]]
        for (sa, a), (sb, b) in itertools.pairwise(chain):
            stage_ms.setdefault(f"{sa} -> {sb}", []).extend(
                (y - x) / 1e6 for x, y in zip(a[1:], b[1:], strict=True))
        last, first = chain[-1], chain[0]
        stage_ms.setdefault(f"{last[0]} -> next {first[0]}", []).extend(
            (first[1][i + 1] - last[1][i]) / 1e6 for i in range(1, n - 1))
    wall = median(walls)
    sim_s = inproc.travel_time_s
    ratio = wall / inproc_s
    res.add("in-process loop wall time [s]", inproc_s, note=f"{inproc.steps} periods")
    res.add("through the processes, warm [s]", wall, note=f"median of {args.repeat}")
    res.add("ratio processes / in process", ratio, f"<= {TARGET_RATIO:g}", ratio <= TARGET_RATIO)
    res.add("real-time factor through the processes", sim_s / wall, f">= {TARGET_REAL_TIME:g}",
            sim_s / wall >= TARGET_REAL_TIME)
    res.add("per period through the processes [ms]", 1e3 * wall / max(1, inproc.steps))
    for name, values in stage_ms.items():
        res.add(f"{name} median [ms]", median(values), note=f"p99 {percentile(values, 99):.3f} ms")
    res.meta = {"cpus": os.cpu_count(), "scenario": SCENARIO, "controller": CONTROLLER}
    return res
