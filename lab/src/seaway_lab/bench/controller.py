"""``seaway bench controller``: per-step solve time over whole missions, and the closed-loop results.

For each controller and each of the paper's five conditions, the whole mission is flown in process
(``closed_loop``) ``--repeats`` times with the generated SQP solver. The runs are deterministic (the
period budget is disabled so that machine noise cannot change a command), so step i of every repeat
solves the same problem: the noise-filtered time of step i is its minimum over the repeats.

Plain IPOPT solves the same NLP instances in the same run: every ``--ipopt-every``-th step's instance
(initial guess, parameters, multipliers) is captured from the first repeat and solved by IPOPT
``--repeats`` times, filtered the same way (minimum per instance). Speed-up = IPOPT's filtered median /
the generated solver's filtered median on the same steps.

Two IPOPTs, both with default options, on the same expressions:

* ``ipopt`` (the reference of the target): the NLP as a matrix (MX) graph calling the RK4 step once
  per stage, as CasADi's Opti stack and its multiple-shooting examples build it. This is the "IPOPT,
  default options" row of solver-notes.md, which lists expanding to SX among the tunings.
* ``ipopt_sx``: the NLP as one scalar (SX) graph, the form the generated solver is built from (what
  ``expand=True`` gives). Shown so that the speed-up over a partly tuned IPOPT is visible too.

Targets (CC-EMPC, filtered, all five missions pooled): median <= 0.3 ms, p99 <= 1 ms, zero unconverged,
>= 30x faster than IPOPT's median. The closed-loop energy, cross-track error and travel time of each
run are printed beside Table I's.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import casadi as ca
import numpy as np
from seaway.runtime.argtypes import positive_int
from seaway.simkit.scenario import load_scenario
from seaway.vessel.metrics import median, percentile
from seaway.vessel.model import load_vessel
from seaway.vessel.native import cache_dir
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.ocp import CONTROLLER_KINDS, Ocp
from seaway_controller.solvers import IpoptSolver

from seaway_lab.bench.common import BenchResult, pin_to_one_core
from seaway_lab.bench.progress import Progress, duration_text
from seaway_lab.closed_loop import TABLE_I, ClosedLoopResult, run_closed_loop

TARGET_MEDIAN_MS = 0.3
TARGET_P99_MS = 1.0
TARGET_SPEEDUP = 30.0


class _Work:
    """How much of the bench is done, in units of one controller on one condition: its closed-loop
    runs take ``fly_share`` of a unit, IPOPT the rest. The share is a guess (a half) until a unit is
    done, then the measured one of the units done so far."""

    def __init__(self, repeats: int, clock: Callable[[], float] = time.monotonic) -> None:
        self.repeats = repeats
        self.clock = clock
        self.units = 0  # units done
        self.fly_share = 0.5
        self._fly_s = self._solve_s = 0.0
        self._t0 = clock()
        self._t_flown: float | None = None

    @property
    def done(self) -> float:
        return float(self.units)

    def flying(self, runs_done: int, run_fraction: float) -> float:
        """Done so far, with ``runs_done`` runs of this unit flown and ``run_fraction`` of the
        next (clamped to [0, 1]: a run may last longer than the paper's travel time)."""
        fraction = (runs_done + min(max(run_fraction, 0.0), 1.0)) / self.repeats
        return self.units + self.fly_share * min(fraction, 1.0)

    def flown(self) -> None:
        self._t_flown = self.clock()

    def solving(self, solved: int, instances: int) -> float:
        """Done so far, with ``solved`` of this unit's ``instances`` IPOPT instances solved."""
        return self.units + self.fly_share + (1 - self.fly_share) * solved / max(instances, 1)

    def solved(self) -> None:
        """The unit is done: the share of flying in it is learned."""
        now = self.clock()
        flown = self._t_flown if self._t_flown is not None else now
        self._fly_s += flown - self._t0
        self._solve_s += now - flown
        if self._fly_s + self._solve_s > 0:
            self.fly_share = self._fly_s / (self._fly_s + self._solve_s)
        self.units += 1
        self._t0, self._t_flown = now, None


def _ms(values: list[float], q: float | None = None) -> float:
    return 1e3 * (median(values) if q is None else percentile(values, q))


def parse_args(argv: list[str]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="seaway bench controller", description=__doc__.split("\n")[0])
    ap.add_argument("--conditions", default="1,2,3,4,5", help="paper conditions, e.g. 1,4")
    ap.add_argument("--controllers", default=",".join(CONTROLLER_KINDS),
                    help=f"comma-separated controllers (default {','.join(CONTROLLER_KINDS)})")
    ap.add_argument("--repeats", type=positive_int, default=3, help="runs per mission for the noise filter")
    ap.add_argument("--ipopt-every", type=positive_int, default=3,
                    help="solve every N-th step's NLP with IPOPT too (1: every step)")
    ap.add_argument("--quick", action="store_true",
                    help="condition 1 only, 1 repeat, IPOPT on every 20th step")
    ap.add_argument("--no-progress", action="store_true",
                    help="no progress on stderr (by default: a line rewritten on a terminal, else a "
                         "line per run and per IPOPT batch, each with an estimate of the time left)")
    args = ap.parse_args(argv)
    if args.quick:
        args.conditions, args.repeats, args.ipopt_every = "1", 1, 20
    args.conditions = [int(c) for c in args.conditions.split(",") if c]
    args.controllers = [c for c in args.controllers.split(",") if c]
    for c in args.conditions:
        if c not in TABLE_I:
            ap.error(f"no paper condition {c}; use 1-5")
    for k in args.controllers:
        if k not in CONTROLLER_KINDS:
            ap.error(f"unknown controller {k!r}; known: {', '.join(CONTROLLER_KINDS)}")
    return args


def run(argv: list[str]) -> BenchResult:
    args = parse_args(argv)
    cpu = pin_to_one_core()
    # The work: one unit per controller and condition, its closed-loop runs taking a share of it
    # and IPOPT on their instances the rest (the share measured once a unit is done).
    progress = Progress(len(args.controllers) * len(args.conditions), not args.no_progress)
    work = _Work(args.repeats)
    res = BenchResult("controller", "Controller: per-step solve time over whole missions "
                      "(generated SQP vs plain IPOPT) and closed-loop results vs Table I")
    t_start = time.perf_counter()
    # One core per vessel file and controller: the solvers are compiled or loaded once.
    cores: dict[str, ControllerCore] = {}
    config = ControllerConfig(solve_budget_s=None)
    pooled: dict[str, dict[str, list[float]]] = {}
    runs: dict[tuple[int, str], ClosedLoopResult] = {}
    nondeterministic: list[str] = []
    for kind in args.controllers:
        acc = pooled.setdefault(kind, {"raw": [], "filtered": [], "fast_sampled": [], "ipopt": [],
                                       "ipopt_raw": [], "unconverged": [], "ipopt_failed": [],
                                       "ipopt_sx": [], "ipopt_sx_failed": [], "graph_gap": []})
        for cond in args.conditions:
            sc = load_scenario(f"paper-c{cond}")
            vp = load_vessel(sc.vessel)
            core = cores.setdefault(sc.vessel, ControllerCore(vp, config))
            ctrl = core.controller(kind)
            repeats: list[ClosedLoopResult] = []
            captured: list = []
            t_mission_s = TABLE_I[cond][kind][2]  # the paper's travel time: the run's length, near
            for rep in range(args.repeats):
                ctrl.capture = captured if rep == 0 else None
                label = f"c{cond} {kind} run {rep + 1}/{args.repeats}"
                t_run = time.monotonic()
                repeats.append(run_closed_loop(
                    sc, kind, core=core, vessel=vp,
                    progress=lambda t, label=label, rep=rep, t_mission_s=t_mission_s: progress.show(
                        work.flying(rep, t / t_mission_s), f"{label}: {t:6.1f} s simulated")))
                progress.step(work.flying(rep + 1, 0.0),
                              f"{label} flown in {duration_text(time.monotonic() - t_run)}")
            work.flown()
            ctrl.capture = None
            first = repeats[0]
            runs[(cond, kind)] = first
            if any(r.trajectory != first.trajectory for r in repeats[1:]):
                nondeterministic.append(f"c{cond}/{kind}")
            n = min(len(r.solve_times_s) for r in repeats)
            filtered = [min(r.solve_times_s[i] for r in repeats) for i in range(n)]
            acc["raw"] += first.solve_times_s
            acc["filtered"] += filtered
            acc["unconverged"].append(first.unconverged)
            # IPOPT on the same NLP instances (every N-th step of the first repeat).
            ipopt = IpoptSolver(Ocp(config.spec(kind), vp, graph="MX"))
            ipopt_sx = IpoptSolver(Ocp(config.spec(kind), vp, graph="SX"))
            picks = list(range(0, len(captured), args.ipopt_every))
            for j, i in enumerate(picks):
                progress.show(work.solving(j, len(picks)),
                              f"c{cond} {kind} IPOPT: {j + 1}/{len(picks)} instances")
                outs = [ipopt.solve(*captured[i]) for _ in range(args.repeats)]
                outs_sx = [ipopt_sx.solve(*captured[i]) for _ in range(args.repeats)]
                acc["ipopt_raw"].append(outs[0].solve_time_s)
                acc["ipopt"].append(min(o.solve_time_s for o in outs))
                acc["ipopt_sx"].append(min(o.solve_time_s for o in outs_sx))
                acc["ipopt_failed"].append(0 if outs[0].success else 1)
                acc["ipopt_sx_failed"].append(0 if outs_sx[0].success else 1)
                # Same expressions, same algorithm: the two graphs must reach the same point.
                acc["graph_gap"].append(float(np.max(np.abs(outs[0].w - outs_sx[0].w))))
                acc["fast_sampled"].append(filtered[i] if i < n else first.solve_times_s[i])
            work.solved()
            progress.step(work.done, f"c{cond} {kind} IPOPT: {len(picks)} instances solved")
    progress.close()
    for kind, acc in pooled.items():
        pre = f"{kind}/"
        is_cc = kind == "cc-empc"
        med_f, p99_f = _ms(acc["filtered"]), _ms(acc["filtered"], 99)
        unconv = sum(acc["unconverged"])
        speedup = median(acc["ipopt"]) / median(acc["fast_sampled"])
        speedup_sx = median(acc["ipopt_sx"]) / median(acc["fast_sampled"])
        res.add(pre + "steps", len(acc["raw"]))
        res.add(pre + "raw_median_ms", _ms(acc["raw"]))
        res.add(pre + "raw_p99_ms", _ms(acc["raw"], 99))
        res.add(pre + "raw_max_ms", 1e3 * max(acc["raw"]))
        res.add(pre + "filtered_median_ms", med_f, f"<= {TARGET_MEDIAN_MS}" if is_cc else None,
                med_f <= TARGET_MEDIAN_MS if is_cc else None)
        res.add(pre + "filtered_p99_ms", p99_f, f"<= {TARGET_P99_MS}" if is_cc else None,
                p99_f <= TARGET_P99_MS if is_cc else None)
        res.add(pre + "filtered_max_ms", 1e3 * max(acc["filtered"]))
        res.add(pre + "unconverged", unconv, "0" if is_cc else None, unconv == 0 if is_cc else None)
        res.add(pre + "ipopt_raw_median_ms", _ms(acc["ipopt_raw"]),
                note=f"{len(acc['ipopt'])} instances; MX graph, default options")
        res.add(pre + "ipopt_filtered_median_ms", _ms(acc["ipopt"]))
        res.add(pre + "ipopt_filtered_p99_ms", _ms(acc["ipopt"], 99))
        res.add(pre + "ipopt_unconverged", sum(acc["ipopt_failed"]))
        res.add(pre + "speedup_vs_ipopt", speedup, f">= {TARGET_SPEEDUP:g}" if is_cc else None,
                speedup >= TARGET_SPEEDUP if is_cc else None,
                "filtered medians, same instances")
        res.add(pre + "ipopt_sx_filtered_median_ms", _ms(acc["ipopt_sx"]),
                note="SX graph (expanded), default options")
        res.add(pre + "ipopt_sx_filtered_p99_ms", _ms(acc["ipopt_sx"], 99))
        res.add(pre + "ipopt_sx_unconverged", sum(acc["ipopt_sx_failed"]))
        res.add(pre + "speedup_vs_ipopt_sx", speedup_sx, note="filtered medians, same instances")
        res.add(pre + "ipopt_mx_vs_sx_max_gap", max(acc["graph_gap"]),
                note="max |w_MX - w_SX| over the instances (same point expected)")
    for (cond, kind), r in sorted(runs.items()):
        e_ref, x_ref, t_ref = TABLE_I[cond][kind]
        pre = f"c{cond}/{kind}/"
        if not r.reached:
            res.add(pre + "reached", "no", "yes", False)
            continue
        res.add(pre + "energy_j", r.energy_j, note=f"Table I {e_ref} ({r.energy_j / e_ref - 1:+.1%})")
        res.add(pre + "cross_track_m", r.cross_track_mean_m, note=f"Table I {x_ref}")
        res.add(pre + "time_s", r.travel_time_s,
                note=f"Table I {t_ref} ({r.travel_time_s / t_ref - 1:+.1%})")
    for cond in args.conditions:
        cc, eo = runs.get((cond, "cc-empc")), runs.get((cond, "eo-empc"))
        if cc and eo and cc.reached and eo.reached:
            ok = (cc.cross_track_mean_m < eo.cross_track_mean_m
                  and cc.energy_j <= 1.005 * eo.energy_j)
            res.add(f"c{cond}/cc_vs_eo", f"XTE {cc.cross_track_mean_m / eo.cross_track_mean_m - 1:+.1%}"
                    f", energy {cc.energy_j / eo.energy_j - 1:+.2%}", "XTE lower, energy <= +0.5%", ok)
    res.meta.update({
        "conditions": args.conditions, "controllers": args.controllers, "repeats": args.repeats,
        "ipopt_every": args.ipopt_every, "pinned_cpu": cpu, "casadi": ca.__version__,
        "solver": ("sqpmethod+qrqp (KKT factorisation reused while the active set holds), exact "
                   "Hessian, eigen-clip, generated C (gcc -O3 -fno-semantic-interposition), ctypes"),
        "reference": "nlpsol ipopt, default options, MX graph (ipopt_sx: the same on the SX graph)",
        "cache_dir": str(cache_dir()),
        "deterministic": "yes" if not nondeterministic else f"NO: {', '.join(nondeterministic)}",
        "wall_s": round(time.perf_counter() - t_start, 1),
    })
    return res
