"""``seaway bench lockstep``: a paper mission composed in one process, through the processes, and
its MPC solves alone, as ratios measured in the same run.

The mission is paper condition #1 flown by CC-EMPC (333.1 s of simulated time, 3331 periods), flown
two ways by ``seaway launch sim-batch --no-report``: **composed** (``--composed``: sim, estimator,
controller and recorder as nodes of one process over the in-memory bus) and **through the
processes** (one process each, on a private Zenoh rendezvous). The third figure is the **MPC solves
alone**: the sum of the solve times of the same mission, each solve's ``solve_time_s`` as the
controller published it on ``ctrl/solve`` and the recording kept it (the generated solver's call,
timed around it), from the runs through the processes. Composed, the controller's thread takes the
GIL back after the solver's call, waiting while another node's thread holds it, and that wait is
timed as the solve's: the composed run's own sum is reported beside, not used. Each figure has its
real-time factor: simulated time over wall time.

The wall time of a mission runs from the sim's first step (its ``work`` mark for the first period)
to its last answer (its ``sent`` mark for the last), read from the members' timeline marks
(``seaway.runtime.timeline``, one clock for every process): start-up, the mission's acceptance,
the stop and the recorder's close are outside it; the simulated time is the stamps' span between
the same two marks. A period is the sim's answer to its next; its median and p99 are over the
periods of the mission.
Targets (issue 58): composed at least 200x real time and at most 2x the MPC solves alone; through
the processes at least 60x real time.

``--repeat N`` flies the mission composed, then through the processes with authentication on (the
launcher's per-run credentials: mutual TLS and access control), then with it off
(``SEAWAY_CREDENTIALS=none``), N times over, so drift in the machine's speed hits every setting. A
ratio is the median over the repeats of each one's ratio of neighbours (the composed run over the
solves of the runs through the processes after it; the processes with authentication on over the
composed run just before; on over the off run just after: target within 10 %, issue 15); the wall
times and the periods are the medians over the runs of a setting. A composed run has no network, so
nothing to authenticate.

Where a period's time goes comes from the members' own marks, composed and through the processes
(authentication on): for each period, each hand-over (transport: the put, the bus, the hand to
Python; then the receiver's intake: decode, inputs handed to the service), each loop's wake-up,
and each member's work (the estimator's filter, the controller's solve and records, the recorder's
write and flush, the sim's step and publication); the sum along the critical path is the period.
"""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from seaway.contract import keys
from seaway.recording import reader
from seaway.runtime import cpus as cpusets
from seaway.runtime import timeline
from seaway.runtime.argtypes import positive_int
from seaway.runtime.credentials import ENV_CREDENTIALS, ENV_IDENTITY, NONE
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile

from seaway_lab.bench.common import BenchResult, compare_auth, free_rendezvous

SCENARIO, CONTROLLER = "paper-c1", "cc-empc"
TARGET_COMPOSED_REAL_TIME = 200.0
TARGET_COMPOSED_OVER_SOLVES = 2.0
TARGET_PROCESSES_REAL_TIME = 60.0
AUTH_FIGURES = {"wall_time_s": "wall time", "period_median_ms": "period median",
                "period_p99_ms": "period p99"}
"""The figures compared with authentication on and off (JSON name: table label)."""

Marks = dict[tuple[str, str, str], dict[int, int]]
"""(service, what, of) -> period stamp [ns] -> when it was first marked [ns] (``timeline.first_marks``)."""


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
takes the recorder's answer as a passive source (``seaway.runtime.lockstep_clock``): no ``arrived``; from the
recorder's put to the sim taking it from its ring, usually with the controller's next bundle, is
transport and waiting, off the critical path unless the sim waits for it (the figure after)."""


def breakdown(marks: Marks) -> dict[str, list[float]]:
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


@dataclass(frozen=True)
class Span:
    """A mission as its marks delimit it: wall time and simulated time [s]."""

    wall_s: float
    simulated_s: float


def mission_span(marks: Marks) -> Span:
    """From the sim's first step (its ``work`` mark of the first period it stepped) to its last
    answer (its ``sent`` mark of the last period): the wall time, and the simulated time between
    the two periods' stamps. Start-up, the wait for the mission's acceptance (the sim's answer for
    t_0 waits for it), the stop and the recorder's close are outside."""
    work, sent = marks.get(("sim", "work", ""), {}), marks.get(("sim", "sent", ""), {})
    if not work or not sent:
        raise ValueError("no marks of the sim's steps: was the trace folder set "
                         f"(${timeline.ENV_TRACE})?")
    first, last = min(work), max(sent)
    return Span((sent[last] - work[first]) / 1e9, (last - first) / 1e9)


def periods_ms(marks: Marks) -> list[float]:
    """Each period of the mission [ms]: the sim's answer to its next, after its first step (the
    first answer, for t_0, waited for the mission to be accepted)."""
    sent = marks.get(("sim", "sent", ""), {})
    start = min(marks.get(("sim", "work", ""), {0: 0}))
    return [(sent[b] - sent[a]) / 1e6 for a, b in itertools.pairwise(sorted(sent)) if a > start]


@dataclass(frozen=True)
class Flight:
    """One mission as a bench flies it: the members' marks and the controller's solve times."""

    marks: Marks
    solve_times_s: list[float]


def solve_times_s(run_dir: Path) -> list[float]:
    """Each MPC solve's time [s] in the run's recording (``ctrl/solve``, in log order)."""
    files = reader.open_paths([run_dir])
    solves = reader.decode_vessel(files, suffixes=[keys.SOLVE.suffix]).get(keys.SOLVE.suffix)
    return [s.solve_time_s for s in solves]  # type: ignore[attr-defined]


def fly(run_dir: Path, composed: bool, auth: bool = True, cpus: frozenset[int] | None = None,
        scenario: str = SCENARIO, controller: str = CONTROLLER) -> Flight:
    """Fly the mission once (``seaway launch sim-batch``), its members marking their timelines.

    ``composed``: as nodes of one process (``--composed``; ``auth`` and ``cpus`` do not apply).
    Else through the processes: ``auth``, the launcher makes the run's credentials (authentication
    on), else ``SEAWAY_CREDENTIALS=none`` (off); ``cpus``, ``seaway launch --cpus`` (with two or
    more, the lockstep chain on one and the rest on the others: ``seaway.runtime.cpus.split_chain``),
    None: where the kernel puts them. The stack registers next to ``run_dir``, not with the user's
    stacks, so the bench never meets another stack or another bench's credentials.
    """
    trace = run_dir.parent / "timeline"
    env = dict(os.environ)
    env[ENV_RENDEZVOUS] = free_rendezvous()
    env.pop(ENV_CONFIG, None)
    env.pop(ENV_IDENTITY, None)  # the launcher names each of its processes
    env[ENV_STACKS_DIR] = str(run_dir.parent / "stacks")
    env[timeline.ENV_TRACE] = str(trace)
    if auth:
        env.pop(ENV_CREDENTIALS, None)
    else:
        env[ENV_CREDENTIALS] = NONE
    how = ["--composed"] if composed else [] if cpus is None else ["--cpus", cpusets.format_cpus(cpus)]
    cmd = [str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario", scenario,
           "--controller", controller, "--run-dir", str(run_dir), "--no-report", *how]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} ended with {out.returncode}:\n"
                           f"{out.stdout[-2000:]}{out.stderr[-2000:]}")
    return Flight(timeline.first_marks(timeline.read(trace)), solve_times_s(run_dir))


def _fly_in_temp(composed: bool, auth: bool, cpus: frozenset[int] | None, scenario: str) -> Flight:
    with tempfile.TemporaryDirectory(prefix="seaway-bench-lockstep-") as tmp:
        return fly(Path(tmp) / "run", composed, auth, cpus, scenario)


def _auth_figures(walls_s: list[float], periods: list[float]) -> dict[str, float]:
    """The figures compared on / off (``AUTH_FIGURES``): the median wall time [s] and the period
    [ms], median and p99, over the runs of one setting (or one run)."""
    return {"wall_time_s": median(walls_s), "period_median_ms": median(periods),
            "period_p99_ms": percentile(periods, 99)}


def _values(xs: list[float], unit: str = "s") -> str:
    return ", ".join(f"{x:.3g}" for x in xs) + f" {unit}"


def _add_stages(res: BenchResult, prefix: str, stages: dict[str, list[float]],
                off: dict[str, list[float]] | None = None) -> None:
    for name, values in stages.items():
        if not values or name == "period":  # the period of every period is a figure of its own
            continue
        v_off = (off or {}).get(name, [])
        res.add(f"{prefix}: {name}, median [ms]", median(values),
                note=f"p99 {percentile(values, 99):.3f} ms"
                + (f"; auth off: median {median(v_off):.3f}, p99 {percentile(v_off, 99):.3f} ms"
                   if v_off else ""))


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench lockstep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=positive_int, default=2,
                    help="rounds of three flights: composed, through the processes with "
                         "authentication on, then off (medians; default 2, about a minute a round "
                         "on two CPUs; 3 or more for the on / off ratio: on a small shared machine "
                         "one stack run's wall time can differ from the next by more than its "
                         "target of 10 %%)")
    ap.add_argument("--no-pin", action="store_true",
                    help="leave the stack's processes where the kernel puts them (default, given two "
                         "CPUs or more: the sim, estimator and controller on one, the recorder and "
                         "the launcher on the others, as 'seaway launch --cpus' does); a composed "
                         "run is one process, always where the kernel puts it")
    ap.add_argument("--scenario", default=SCENARIO,
                    help=f"the mission's scenario, a name or a file (default {SCENARIO}; the "
                         "targets are paper-c1's)")
    args = ap.parse_args(argv)
    allowed = cpusets.allowed()
    split = None if args.no_pin else cpusets.split_chain(allowed)
    stack_cpus = allowed if split else None  # the launcher splits them so (--cpus)

    flights: dict[str, list[Flight]] = {"composed": [], "on": [], "off": []}
    for _ in range(args.repeat):
        # In turn, so drift in the machine's load hits every setting.
        flights["composed"].append(_fly_in_temp(True, True, None, args.scenario))
        flights["on"].append(_fly_in_temp(False, True, stack_cpus, args.scenario))
        flights["off"].append(_fly_in_temp(False, False, stack_cpus, args.scenario))
    return report(flights, args.scenario, split)


def report(flights: dict[str, list[Flight]], scenario: str = SCENARIO,
           split: tuple[frozenset[int], frozenset[int]] | None = None) -> BenchResult:
    """The table of ``flights`` (``composed``, ``on`` and ``off``: the processes with
    authentication on and off), each list in the order flown, one of each per repeat."""
    res = BenchResult("lockstep", f"Lockstep: {scenario}, {CONTROLLER}: composed, through the "
                                  "processes, and the MPC solves alone")
    comp = flights["composed"]
    spans = {k: [mission_span(f.marks) for f in fs] for k, fs in flights.items()}
    sim_s = spans["composed"][0].simulated_s
    walls = {k: [s.wall_s for s in ss] for k, ss in spans.items()}
    solves = {k: [sum(f.solve_times_s) for f in fs] for k, fs in flights.items()}
    period = {k: [p for f in fs for p in periods_ms(f.marks)] for k, fs in flights.items()}
    n = len(comp)
    res.add("simulated time [s]", sim_s,
            note="wall times from the sim's first step to its last answer")

    comp_wall, on_wall = median(walls["composed"]), median(walls["on"])
    rt_comp = sim_s / comp_wall
    res.add("composed: wall time [s]", comp_wall, note=f"median of {n}: {_values(walls['composed'])}")
    res.add("composed: real-time factor", rt_comp, f">= {TARGET_COMPOSED_REAL_TIME:g}",
            rt_comp >= TARGET_COMPOSED_REAL_TIME)
    res.add("composed: period median [ms]", median(period["composed"]),
            note=f"p99 {percentile(period['composed'], 99):.3f} ms")
    # The solves alone are those timed through the processes: composed, a solve's time also holds
    # the controller's wait for the GIL after the solver's call (another node's thread took it).
    alone = [median([sum(a.solve_times_s), sum(b.solve_times_s)])
             for a, b in zip(flights["on"], flights["off"], strict=True)]
    over = [w / s for w, s in zip(walls["composed"], alone, strict=True)]
    res.add("composed / MPC solves alone", median(over), f"<= {TARGET_COMPOSED_OVER_SOLVES:g}",
            median(over) <= TARGET_COMPOSED_OVER_SOLVES,
            note=f"median over {n} rounds of the composed wall time over the solves of the same "
                 "round's runs through the processes")

    res.add("MPC solves", len(comp[0].solve_times_s), note="one a period (the first composed run's)")
    alone_s = median(alone)
    solve_ms = [1e3 * t for k in ("on", "off") for f in flights[k] for t in f.solve_times_s]
    res.add("MPC solves alone: sum [s]", alone_s,
            note=f"each solve's time as the controller published it, through the processes (the "
                 f"solver alone in its process); median over {n} rounds: {_values(alone)}")
    res.add("MPC solves alone: real-time factor", sim_s / alone_s)
    res.add("MPC solve median [ms]", median(solve_ms),
            note=f"p99 {percentile(solve_ms, 99):.3f} ms, through the processes")
    comp_ms = [1e3 * t for f in comp for t in f.solve_times_s]
    res.add("composed: its solves, sum [s]", median(solves["composed"]),
            note=f"the solves as timed composed (with the wait for the GIL after each): median "
                 f"{median(comp_ms):.3f} ms, p99 {percentile(comp_ms, 99):.3f} ms; "
                 f"{_values(solves['composed'])}")

    rt_on = sim_s / on_wall
    res.add("processes: wall time [s]", on_wall,
            note=f"auth on, median of {n}: {_values(walls['on'])}")
    res.add("processes: real-time factor", rt_on, f">= {TARGET_PROCESSES_REAL_TIME:g}",
            rt_on >= TARGET_PROCESSES_REAL_TIME)
    res.add("processes: period median [ms]", median(period["on"]),
            note=f"p99 {percentile(period['on'], 99):.3f} ms, auth on")
    pairs = [p / c for p, c in zip(walls["on"], walls["composed"], strict=True)]
    res.add("processes / composed", median(pairs),
            note=f"median over {n} rounds of the processes' wall time over the composed run's "
                 f"before it ({min(pairs):.2f}-{max(pairs):.2f})")
    res.add("processes / MPC solves alone",
            median([w / s for w, s in zip(walls["on"], alone, strict=True)]))

    stages = {k: _merged([breakdown(f.marks) for f in fs]) for k, fs in flights.items()}
    _add_stages(res, "composed", stages["composed"])
    _add_stages(res, "processes", stages["on"], stages["off"])
    res.add("processes, auth off: wall time [s]", median(walls["off"]),
            note=f"median of {n}: {_values(walls['off'])}")
    # Each run with authentication on against the run with it off right after it (common says why).
    each = {k: [_auth_figures([mission_span(f.marks).wall_s], periods_ms(f.marks)) for f in flights[k]]
            for k in ("on", "off")}
    auth_pairs = {name: [a[name] / b[name] for a, b in zip(each["on"], each["off"], strict=True)]
                  for name in AUTH_FIGURES}
    compare_auth(res, _auth_figures(walls["on"], period["on"]),
                 _auth_figures(walls["off"], period["off"]),
                 lambda k: f"auth on / off, {AUTH_FIGURES[k]}", auth_pairs)
    res.meta = {"cpus": os.cpu_count(), "scenario": scenario, "controller": CONTROLLER,
                "stack placement": (f"chain on CPU {cpusets.format_cpus(split[0])}, the rest on "
                                    f"{cpusets.format_cpus(split[1])}") if split else "the kernel's",
                "composed placement": "one process, where the kernel puts it"}
    return res


def _merged(parts: list[dict[str, list[float]]]) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for part in parts:
        for name, values in part.items():
            out.setdefault(name, []).extend(values)
    return out

