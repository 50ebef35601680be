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

Authentication (issue 15): the stack runs with authentication on (the launcher's per-run
credentials: mutual TLS and access control) and off (``SEAWAY_CREDENTIALS=none``), alternately in
the same run (on, off, on, off... for ``--repeat``), so drift hits both; the figures on and off (wall
time, and the period: the time between the sim's consecutive answers, median and p99) and their
ratio on / off (target: within 10 %). The comparison with the in-process loop and the stage
breakdown are those with authentication on, as a stack runs.
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
from seaway.runtime.credentials import ENV_CREDENTIALS, ENV_IDENTITY, NONE
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.simkit.scenario import load_scenario
from seaway.vessel.metrics import median, percentile
from seaway_recorder import recording

from seaway_lab.bench.common import BenchResult, compare_auth
from seaway_lab.closed_loop import run_closed_loop

SCENARIO, CONTROLLER = "paper-c1", "cc-empc"
TARGET_RATIO, TARGET_REAL_TIME = 2.0, 100.0
STAGES = ("sim", "estimator", "controller", "recorder")
AUTH_FIGURES = {"wall_time_s": "wall time", "period_median_ms": "period median",
                "period_p99_ms": "period p99"}
"""The figures compared with authentication on and off (JSON name: table label)."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def through_processes(run_dir: Path, auth: bool = True) -> dict[str, list[int]]:
    """Run the stack once; per stage, the receive times [ns] of each period's answer (by period).

    ``auth``: the launcher makes the run's credentials (authentication on), else
    ``SEAWAY_CREDENTIALS=none`` (off). The stack registers next to ``run_dir``, not with the user's
    stacks, so the bench never meets another stack or another bench's credentials.
    """
    env = dict(os.environ, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{_free_port()}")
    env.pop("SEAWAY_ZENOH_CONFIG", None)
    env.pop(ENV_IDENTITY, None)  # the launcher names each of its processes
    env[ENV_STACKS_DIR] = str(run_dir.parent / "stacks")
    if auth:
        env.pop(ENV_CREDENTIALS, None)
    else:
        env[ENV_CREDENTIALS] = NONE
    subprocess.run([str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
                    SCENARIO, "--controller", CONTROLLER, "--run-dir", str(run_dir)],
                   env=env, check=True, capture_output=True, timeout=600)
    first: dict[str, dict[int, int]] = {s: {} for s in STAGES}
    topics = [keys.lockstep_spec(s).key("vessel1") for s in STAGES]
    for m in recording.iter_messages(recording.open_paths([run_dir]), topics):
        ans = PeriodDone.decode(m.data)
        first[ans.service].setdefault(ans.stamp_ns, m.log_time_ns)  # a repeat is not a new period
    return {s: [first[s][t] for t in sorted(first[s])] for s in STAGES}


def _stages(times: dict[str, list[int]], stage_ms: dict[str, list[float]]) -> None:
    """Add one run's per-period stage durations [ms] (see the module docstring) to ``stage_ms``."""
    n = min(len(v) for v in times.values() if v)
    chain = [(s, times[s][:n]) for s in STAGES if times[s]]
    for (sa, a), (sb, b) in itertools.pairwise(chain):
        stage_ms.setdefault(f"{sa} -> {sb}", []).extend(
            (y - x) / 1e6 for x, y in zip(a[1:], b[1:], strict=True))
    last, first = chain[-1], chain[0]
    stage_ms.setdefault(f"{last[0]} -> next {first[0]}", []).extend(
        (first[1][i + 1] - last[1][i]) / 1e6 for i in range(1, n - 1))


def _auth_figures(walls_s: list[float], periods_ms: list[float]) -> dict[str, float]:
    """The figures compared on / off: the median wall time [s] and the period [ms] (the sim's answer
    to its next), median and p99, over the runs of one setting."""
    return {"wall_time_s": median(walls_s), "period_median_ms": median(periods_ms),
            "period_p99_ms": percentile(periods_ms, 99)}


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench lockstep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs through the processes with authentication on, and as many with it "
                         "off, alternating (median)")
    args = ap.parse_args(argv)
    res = BenchResult("lockstep", "Lockstep: paper condition #1, CC-EMPC, through the processes vs "
                                  "in process")
    sc = load_scenario(SCENARIO)
    run_closed_loop(sc, CONTROLLER)  # warm: solvers loaded
    t0 = time.perf_counter()
    inproc = run_closed_loop(sc, CONTROLLER)
    inproc_s = time.perf_counter() - t0

    walls: dict[bool, list[float]] = {True: [], False: []}
    periods_ms: dict[bool, list[float]] = {True: [], False: []}
    stage_ms: dict[bool, dict[str, list[float]]] = {True: {}, False: {}}
    for _ in range(args.repeat):
        for auth in (True, False):  # alternate, so drift in the machine's load hits both
            with tempfile.TemporaryDirectory(prefix="seaway-bench-lockstep-") as tmp:
                times = through_processes(Path(tmp) / "run", auth)
            sim = times["sim"]
            walls[auth].append((sim[-1] - sim[1]) / 1e9)  # from the first step to the hold at the end
            periods_ms[auth].extend((b - a) / 1e6 for a, b in itertools.pairwise(sim[1:]))
            _stages(times, stage_ms[auth])
    wall, wall_off = median(walls[True]), median(walls[False])
    sim_s = inproc.travel_time_s
    ratio = wall / inproc_s
    res.add("in-process loop wall time [s]", inproc_s, note=f"{inproc.steps} periods")
    res.add("through the processes, warm [s]", wall, note=f"median of {args.repeat}, auth on")
    res.add("ratio processes / in process", ratio, f"<= {TARGET_RATIO:g}", ratio <= TARGET_RATIO)
    res.add("real-time factor through the processes", sim_s / wall, f">= {TARGET_REAL_TIME:g}",
            sim_s / wall >= TARGET_REAL_TIME)
    res.add("per period through the processes [ms]", 1e3 * wall / max(1, inproc.steps))
    for name, values in stage_ms[True].items():
        v_off = stage_ms[False].get(name, [])
        res.add(f"{name} median [ms]", median(values), note=f"p99 {percentile(values, 99):.3f} ms"
                + (f"; auth off: median {median(v_off):.3f}, p99 {percentile(v_off, 99):.3f} ms"
                   if v_off else ""))
    on, off = _auth_figures(walls[True], periods_ms[True]), _auth_figures(walls[False], periods_ms[False])
    res.add("through the processes, auth off [s]", wall_off, note=f"median of {args.repeat}")
    for label, fig in (("on", on), ("off", off)):
        res.add(f"period, auth {label}, median [ms]", fig["period_median_ms"],
                note=f"p99 {fig['period_p99_ms']:.3f} ms")
    compare_auth(res, on, off, lambda k: f"auth on / off, {AUTH_FIGURES[k]}")
    res.meta = {"cpus": os.cpu_count(), "scenario": SCENARIO, "controller": CONTROLLER}
    return res
