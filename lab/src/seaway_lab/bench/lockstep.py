"""``seaway bench lockstep``: a paper mission through the real processes in lockstep, against the
in-process closed loop in the same run.

The mission is paper condition #1 flown by CC-EMPC (333 s of simulated time, 3331 periods). Through
the processes: ``seaway launch sim-batch`` (sim, estimator, controller, recorder on a private Zenoh
rendezvous); the figure is the WARM stack's wall time, from the sim's first step to its hold at the
end, read from the members' timeline marks. In process: ``seaway_lab.closed_loop.run_closed_loop``
(the same cores and the same solver, no bus), warm, run just before each stack run; the ratio is
the median over the stack runs of each one's wall time over its in-process run's.

Where a period's time goes comes from the members' own marks (``seaway.runtime.timeline``, on the
clock every process shares): for each period, each hand-over (transport: the put, Zenoh, the hand
to Python; then the receiver's intake: decode, inputs handed to the service), each loop's wake-up,
and each member's work (the estimator's filter, the controller's
solve and records, the recorder's write and flush, the sim's step and publication); the sum along
the critical path is the period.
Targets (issue 13): through the processes at most 2x the in-process loop, and at least 100x real time.
The floor beside them is what no split of these parts into processes can beat on this machine: the
in-process loop's period plus three hand-overs at the least (``seaway bench handover``'s put from
Zenoh's thread and receive into a callback), with nothing else in the period.

Authentication (issue 15): the stack runs with authentication on (the launcher's per-run
credentials: mutual TLS and access control) and off (``SEAWAY_CREDENTIALS=none``), alternately in
the same run (on, off, on, off... for ``--repeat``), so drift hits both; the figures on and off (wall
time, and the period: the time between the sim's consecutive answers, median and p99) and their
ratio on / off, the median over the pairs of each run on and the run off after it (target: within
10 %). ``--repeat`` is 3 by default: on a small shared machine one stack run's wall time can
differ from the next by more than the target, so one pair's ratio says little.
The comparison with the in-process loop and the stage breakdown are those with authentication on,
as a stack runs.
"""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seaway.runtime import cpus as cpusets
from seaway.runtime import timeline
from seaway.runtime.argtypes import positive_int
from seaway.runtime.credentials import ENV_CREDENTIALS, ENV_IDENTITY, NONE
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.simkit.scenario import load_scenario
from seaway.vessel.metrics import median, percentile
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore

from seaway_lab.bench.common import BenchResult, compare_auth, free_rendezvous
from seaway_lab.closed_loop import run_closed_loop

SCENARIO, CONTROLLER = "paper-c1", "cc-empc"
TARGET_RATIO, TARGET_REAL_TIME = 2.0, 100.0
AUTH_FIGURES = {"wall_time_s": "wall time", "period_median_ms": "period median",
                "period_p99_ms": "period p99"}
"""The figures compared with authentication on and off (JSON name: table label)."""


def through_processes(run_dir: Path, auth: bool = True, cpus: frozenset[int] | None = None
                      ) -> dict[tuple[str, str, str], dict[int, int]]:
    """Run the stack once, its members marking their timelines; the marks (``timeline.first_marks``).

    ``auth``: the launcher makes the run's credentials (authentication on), else
    ``SEAWAY_CREDENTIALS=none`` (off). ``cpus``: ``seaway launch --cpus`` (with two or more, the
    lockstep chain on one and the rest on the others: ``seaway.runtime.cpus.split_chain``); None:
    where the kernel puts them. The stack registers next to ``run_dir``, not with the user's
    stacks, so the bench never meets another stack or another bench's credentials.
    """
    env = dict(os.environ)
    env[ENV_RENDEZVOUS] = free_rendezvous()
    env.pop(ENV_CONFIG, None)
    env.pop(ENV_IDENTITY, None)  # the launcher names each of its processes
    env[ENV_STACKS_DIR] = str(run_dir.parent / "stacks")
    env[timeline.ENV_TRACE] = str(run_dir.parent / "timeline")
    if auth:
        env.pop(ENV_CREDENTIALS, None)
    else:
        env[ENV_CREDENTIALS] = NONE
    where = [] if cpus is None else ["--cpus", cpusets.format_cpus(cpus)]
    subprocess.run([str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
                    SCENARIO, "--controller", CONTROLLER, "--run-dir", str(run_dir), *where],
                   env=env, check=True, capture_output=True, timeout=600)
    return timeline.first_marks(timeline.read(run_dir.parent / "timeline"))


STAGES: tuple[tuple[str, tuple[str, str, str], tuple[str, str, str]], ...] = (
    # (label, from mark, to mark) per period k; a mark is (service, what, of)
    ("sim -> estimator: transport", ("sim", "sent", ""), ("estimator", "arrived", "sim")),
    ("estimator: intake", ("estimator", "arrived", "sim"), ("estimator", "heard", "sim")),
    ("estimator: wake-up", ("estimator", "heard", "sim"), ("estimator", "work", "")),
    ("estimator: filter and publish", ("estimator", "work", ""), ("estimator", "sent", "")),
    ("estimator -> controller: transport", ("estimator", "sent", ""),
     ("controller", "arrived", "estimator")),
    ("controller: intake", ("controller", "arrived", "estimator"),
     ("controller", "heard", "estimator")),
    ("controller: wake-up", ("controller", "heard", "estimator"), ("controller", "work", "")),
    ("controller: solve and publish", ("controller", "work", ""), ("controller", "sent", "")),
    ("controller -> sim: transport", ("controller", "sent", ""), ("sim", "arrived", "controller")),
    ("sim: intake of the controller's", ("sim", "arrived", "controller"),
     ("sim", "heard", "controller")),
    ("controller -> recorder: transport and intake", ("controller", "sent", ""),
     ("recorder", "heard", "controller")),
    ("recorder: write and flush", ("recorder", "heard", "controller"), ("recorder", "sent", "")),
    ("recorder -> sim: until taken", ("recorder", "sent", ""), ("sim", "heard", "recorder")),
)
"""The hand-overs and the work of one period, in the order of the protocol (services/sim/README.md).

Transport is from the sender's mark (its put follows) to Zenoh's call into the receiver's Python;
intake is the receiver taking the bundle there: first what its passive sources left in their rings,
then this bundle decoded and its inputs handed to the service, which may work on them at once (the
estimator's filter advances on each sensor sample and on the command: part of its work is here).
The recorder notes only its own ``heard`` (it takes bundles from its stream of samples). The sim
takes the recorder's answer as a passive source (``seaway_sim.lockstep``): no ``arrived``; from the
recorder's put to the sim taking it from its ring, usually with the controller's next bundle, is
transport and waiting, off the critical path unless the sim waits for it (the figure after)."""


def breakdown(marks: dict[tuple[str, str, str], dict[int, int]]) -> dict[str, list[float]]:
    """Per stage, its duration in each period [ms]; also the sim's wait for the recorder after the
    controller's answer, its step and publication after the last answer, and the period itself.

    Periods are those every member marked, the first and the last left out (start and hold)."""
    def get(mark: tuple[str, str, str]) -> dict[int, int]:
        return marks.get(mark, {})

    sent = get(("sim", "sent", ""))
    ticks = sorted(sent)
    need = [get(m) for _, a, b in STAGES for m in (a, b)]
    periods = [k for k in ticks[1:-1] if all(k in m for m in need)]
    out: dict[str, list[float]] = {label: [(get(b)[k] - get(a)[k]) / 1e6 for k in periods]
                                   for label, a, b in STAGES}
    nxt, prev = dict(itertools.pairwise(ticks)), {b: a for a, b in itertools.pairwise(ticks)}
    heard_ctl, heard_rec = get(("sim", "heard", "controller")), get(("sim", "heard", "recorder"))
    # The sim publishes t_{k+1} once the controller answered t_k and the recorder t_{k-1}
    # (seaway.runtime.lockstep.RECORDER_LAG): the recorder's answer it waits for is the one before.
    lagged = [k for k in periods if prev.get(k) in heard_rec]
    out["sim: waiting for the recorder (its answer to the period before)"] = [
        max(0, heard_rec[prev[k]] - heard_ctl[k]) / 1e6 for k in lagged]
    out["sim: step and publish after the last answer"] = [
        (sent[nxt[k]] - max(heard_ctl[k], heard_rec[prev[k]])) / 1e6 for k in lagged if k in nxt]
    out["period"] = [(sent[nxt[k]] - sent[k]) / 1e6 for k in periods if k in nxt]
    return out


def wall_s(marks: dict[tuple[str, str, str], dict[int, int]]) -> float:
    """From the sim's first step to its hold at the end [s] (its answers' marks)."""
    ticks = sorted(marks.get(("sim", "sent", ""), {}).items())
    return (ticks[-1][1] - ticks[1][1]) / 1e9


def _auth_figures(walls_s: list[float], periods_ms: list[float]) -> dict[str, float]:
    """The figures compared on / off: the median wall time [s] and the period [ms] (the sim's answer
    to its next), median and p99, over the runs of one setting."""
    return {"wall_time_s": median(walls_s), "period_median_ms": median(periods_ms),
            "period_p99_ms": percentile(periods_ms, 99)}


FLOOR_MESSAGES = 2000
"""Timed messages per case of the hand-over measure behind the floor (``seaway bench handover``)."""


def three_handovers_ms() -> float:
    """Three lockstep hand-overs at the least, as ``seaway bench handover`` measures them with
    authentication on [ms of CPU]: a put from Zenoh's thread and a receive into a Python callback,
    each, between processes doing nothing else (one round)."""
    from seaway_lab.bench import handover

    rounds = handover.measure_rounds(1, FLOOR_MESSAGES, 0.0005, 2000, auths=(True,))
    return rounds[True][0]["three_handovers_least_ms"]


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench lockstep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=positive_int, default=3,
                    help="runs through the processes with authentication on, and as many with it "
                         "off, alternating (median; default 3: on a small shared machine one stack "
                         "run's wall time can differ from the next by more than the on / off "
                         "target of 10 %%)")
    ap.add_argument("--no-pin", action="store_true",
                    help="leave the stack's processes where the kernel puts them (default, given two "
                         "CPUs or more: the sim, estimator and controller on one, the recorder and "
                         "the launcher on the others, as 'seaway launch --cpus' does)")
    ap.add_argument("--no-floor", action="store_true",
                    help="leave out the floor (the in-process loop plus three hand-overs at the "
                         "least, measured as 'seaway bench handover' does: about 20 s)")
    args = ap.parse_args(argv)
    # First, before this process opens a Zenoh session of its own (the measure sets Zenoh's runtime).
    handovers_ms = None if args.no_floor else three_handovers_ms()
    allowed = cpusets.allowed()
    split = None if args.no_pin else cpusets.split_chain(allowed)
    stack_cpus = allowed if split else None  # the launcher splits them so (--cpus)
    res = BenchResult("lockstep", "Lockstep: paper condition #1, CC-EMPC, through the processes vs "
                                  "in process")
    sc = load_scenario(SCENARIO)
    run_closed_loop(sc, CONTROLLER, battery=True)  # warm: solvers loaded
    t0 = time.perf_counter()
    inproc = run_closed_loop(sc, CONTROLLER, battery=True)
    bare_s = time.perf_counter() - t0
    # The same parts as the stack: the controller hears the sim's battery every period (its budget
    # prices the point of no return, as in the stack), and the estimator runs alongside on the
    # sim's sensors (it does not steer in process: the controller flies the true state, as the
    # paper's simulations do, so its budget has no disturbance band to price).
    cfg = EstimatorConfig().model_copy(update={"vessel": sc.vessel, "apply_dead_zone": sc.dead_zone})

    def in_process_s() -> float:
        t0 = time.perf_counter()
        run_closed_loop(sc, CONTROLLER, estimator=EstimatorCore(cfg), battery=True)
        return time.perf_counter() - t0

    walls: dict[bool, list[float]] = {True: [], False: []}
    inprocs: list[float] = []
    ratios: list[float] = []
    stage_ms: dict[bool, dict[str, list[float]]] = {True: {}, False: {}}
    runs: dict[bool, list[dict[str, float]]] = {True: [], False: []}  # each run's AUTH_FIGURES
    for _ in range(args.repeat):
        for auth in (True, False):  # alternate, so drift in the machine's load hits both
            # Each stack run is paired with an in-process run just before it: a shared machine's
            # speed drifts within minutes, so a ratio of runs minutes apart says more about the
            # machine than about the stack.
            before = in_process_s()
            with tempfile.TemporaryDirectory(prefix="seaway-bench-lockstep-") as tmp:
                marks = through_processes(Path(tmp) / "run", auth, stack_cpus)
            walls[auth].append(wall_s(marks))
            inprocs.append(before)
            if auth:
                ratios.append(walls[auth][-1] / max(before, 1e-9))
            stages = breakdown(marks)
            for name, values in stages.items():
                stage_ms[auth].setdefault(name, []).extend(values)
            runs[auth].append(_auth_figures([walls[auth][-1]], stages["period"]))
    wall, wall_off = median(walls[True]), median(walls[False])
    inproc_s = median(inprocs)
    sim_s = inproc.travel_time_s
    ratio = median(ratios)
    res.add("in-process loop wall time [s]", inproc_s,
            note=f"{inproc.steps} periods, estimator alongside, median of {len(inprocs)} (one before "
                 f"each stack run: {', '.join(f'{x:.2f}' for x in inprocs)}); without the "
                 f"estimator {bare_s:.3f} s")
    res.add("through the processes, warm [s]", wall, note=f"median of {args.repeat}, auth on")
    res.add("ratio processes / in process", ratio, f"<= {TARGET_RATIO:g}", ratio <= TARGET_RATIO,
            note=f"median over {len(ratios)} stack runs of each over the in-process run just before it")
    res.add("real-time factor through the processes", sim_s / wall, f">= {TARGET_REAL_TIME:g}",
            sim_s / wall >= TARGET_REAL_TIME)
    res.add("per period through the processes [ms]", 1e3 * wall / max(1, inproc.steps))
    if handovers_ms is not None:
        # A lower bound on any split of these parts into processes on this Zenoh: the chain works
        # one member at a time, so its work (the in-process loop's) and three hand-overs' CPU
        # (each a put in one member and a receive in the next, both on the critical path) add up,
        # with no bookkeeping, no decoding, no recorder and warm caches.
        inproc_ms = 1e3 * inproc_s / max(1, inproc.steps)
        least_ms = inproc_ms + handovers_ms
        res.add("floor: a period at the least [ms]", least_ms,
                note=f"the in-process loop's {inproc_ms:.3f} ms a period plus three hand-overs at "
                     f"the least, {handovers_ms:.3f} ms of CPU (seaway bench handover, auth on); "
                     f"no process split of these parts can be faster here")
        res.add("floor: real-time factor at the least", sim_s / (least_ms / 1e3 * inproc.steps),
                note=f"against the target of {TARGET_REAL_TIME:g}x")
        res.add("floor: ratio to the in process at the least", least_ms / inproc_ms,
                note=f"against the target of {TARGET_RATIO:g}")
    for name, values in stage_ms[True].items():
        v_off = stage_ms[False].get(name, [])
        res.add(f"{name}, median [ms]", median(values), note=f"p99 {percentile(values, 99):.3f} ms"
                + (f"; auth off: median {median(v_off):.3f}, p99 {percentile(v_off, 99):.3f} ms"
                   if v_off else ""))
    on = _auth_figures(walls[True], stage_ms[True]["period"])
    off = _auth_figures(walls[False], stage_ms[False]["period"])
    res.add("through the processes, auth off [s]", wall_off, note=f"median of {args.repeat}")
    # Each run with authentication on against the run with it off right after it (common says why).
    pairs = {k: [a[k] / b[k] for a, b in zip(runs[True], runs[False], strict=True)] for k in on}
    compare_auth(res, on, off, lambda k: f"auth on / off, {AUTH_FIGURES[k]}", pairs)
    res.meta = {"cpus": os.cpu_count(), "scenario": SCENARIO, "controller": CONTROLLER,
                "stack placement": (f"chain on CPU {cpusets.format_cpus(split[0])}, the rest on "
                                    f"{cpusets.format_cpus(split[1])}") if split else "the kernel's"}
    return res
