"""``seaway bench hotpath``: where a period of the in-process closed loop goes, part by part.

The mission is paper condition #1 by CC-EMPC in the in-process loop
(``seaway_lab.closed_loop.run_closed_loop``; ``seaway bench lockstep`` flies it composed and through
the processes), the estimator alongside on the sim's sensors and the controller hearing the sim's
battery once a second, so that its energy budget prices the point of no return as in a stack.
Each period is split into

* **energy budget**: ``ControllerCore`` taking the battery's report and pricing its budget
  (``seaway_controller.budget``, when due, and the due check when not);
* **estimator**: every call into ``EstimatorCore`` (sensor samples, the command, the estimate);
* **simulator**: every call into ``SimCore`` (the plant's RK4 and the sensors, its outputs);
* **MPC solve**: ``MpcController.solve`` (parameters, warm start, the solver, the cost split);
  the solver alone is reported beside it (its own ``solve_time_s``);
* **the rest**: the controller's bookkeeping around the solve, the loop, messages.

The parts are timed by wrapping those methods of the classes (``perf_counter_ns`` around each call)
for the runs that measure them; a period runs from one ``SimCore.advance`` to the next. Figures are
per period, in ms, median, mean and p99 over the periods of a run, then the median over ``--repeat``
runs (the budget is priced once a second, so its median is its due check and its mean its cost);
each part's share is of the run's mean period, and its ratio is to the MPC solve of the same run.
The wall time is measured apart, on runs without the wrappers, alternating with the measured ones.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import time
from collections.abc import Callable, Iterator
from typing import Any

from seaway.runtime.argtypes import positive_int
from seaway.simkit.scenario import Scenario, load_scenario
from seaway.vessel.metrics import median, percentile
from seaway_controller.core_energy import EnergyAccount
from seaway_controller.mpc import MpcController
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_estimator.core_estimate import PublishedEstimate
from seaway_sim.core import SimCore

from seaway_lab.bench.common import BenchResult
from seaway_lab.closed_loop import ClosedLoopResult, run_closed_loop

SCENARIO, CONTROLLER = "paper-c1", "cc-empc"
MPC = "MPC solve"
REST = "the rest"
PARTS: dict[str, tuple[tuple[type, str], ...]] = {
    "energy budget": ((EnergyAccount, "_update_budget"), (EnergyAccount, "on_battery")),
    "estimator": ((EstimatorCore, "on_attitude"), (EstimatorCore, "on_gnss"),
                  (PublishedEstimate, "predict_to"), (EstimatorCore, "on_thrust")),
    "simulator": ((SimCore, "advance"), (SimCore, "truth"), (SimCore, "take_samples"),
                  (SimCore, "battery"), (SimCore, "disturbance")),
    MPC: ((MpcController, "solve"),),
}
"""Each part and the methods whose calls are its time. None of them calls another's."""
TARGET_SHARE = 2.0
"""Issue 58's target for the composed loop: wall time at most twice the sum of its solve times."""


class Meter:
    """Per-period time of each part [ns]: ``periods`` has one dict per period closed so far."""

    def __init__(self) -> None:
        self.periods: list[dict[str, int]] = []
        self._now: dict[str, int] = dict.fromkeys([*PARTS, "period"], 0)
        self._start: int | None = None
        self._depth = 0

    def boundary(self, t_ns: int) -> None:
        """A period begins at ``t_ns`` (``perf_counter_ns``): close the one before."""
        if self._start is not None:
            self._now["period"] = t_ns - self._start
            self.periods.append(self._now)
        # Before the first step: the mission's set-up and first solve, not a period (left out).
        self._now = dict.fromkeys(self._now, 0)
        self._start = t_ns

    def wrap(self, part: str, fn: Callable[..., Any], starts_period: bool) -> Callable[..., Any]:
        clock = time.perf_counter_ns

        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self._depth:  # a part calling itself (the controller's step after an area stop)
                return fn(*args, **kwargs)
            t0 = clock()
            if starts_period:
                self.boundary(t0)
            self._depth += 1
            try:
                return fn(*args, **kwargs)
            finally:
                self._depth -= 1
                self._now[part] += clock() - t0
        return timed


@contextlib.contextmanager
def metered() -> Iterator[Meter]:
    """The parts' methods timed into a ``Meter`` while inside; the classes restored after."""
    meter, saved = Meter(), []
    for part, methods in PARTS.items():
        for cls, name in methods:
            fn = cls.__dict__[name]
            saved.append((cls, name, fn))
            setattr(cls, name, meter.wrap(part, fn, (cls, name) == (SimCore, "advance")))
    try:
        yield meter
    finally:
        for cls, name, fn in saved:
            setattr(cls, name, fn)


def fly(sc: Scenario) -> ClosedLoopResult:
    """The mission in process: the estimator alongside, the controller hearing the battery."""
    cfg = EstimatorConfig().model_copy(update={"vessel": sc.vessel, "apply_dead_zone": sc.dead_zone})
    return run_closed_loop(sc, CONTROLLER, estimator=EstimatorCore(cfg), battery=True)


def split(periods: list[dict[str, int]]) -> dict[str, list[float]]:
    """Per part (and the rest, and the period), its time in each period [ms]."""
    out: dict[str, list[float]] = {p: [d[p] / 1e6 for d in periods] for p in [*PARTS, "period"]}
    out[REST] = [(d["period"] - sum(d[p] for p in PARTS)) / 1e6 for d in periods]
    return out


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench hotpath", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=positive_int, default=3,
                    help="measured runs, and as many unmeasured ones for the wall time, alternating "
                         "(medians; default 3)")
    args = ap.parse_args(argv)
    sc = load_scenario(SCENARIO)
    fly(sc)  # warm: solvers and the estimator's compiled steps loaded
    walls: list[float] = []
    solves: list[float] = []
    per_run: list[dict[str, list[float]]] = []
    result = None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        result = fly(sc)
        walls.append(time.perf_counter() - t0)
        solves.append(sum(result.solve_times_s))
        with metered() as meter:
            fly(sc)
        per_run.append(split(meter.periods))
    assert result is not None
    res = BenchResult("hotpath", "Hot path: where a period of the in-process loop goes (paper "
                                 "condition #1, CC-EMPC, estimator and battery alongside)")
    wall, solve = median(walls), median(solves)
    sim_s = result.travel_time_s
    res.add("wall time [s]", wall, note=f"{result.steps} periods, median of {len(walls)} "
            f"({', '.join(f'{w:.2f}' for w in walls)})")
    res.add("real-time factor", sim_s / wall, note=f"{sim_s:.1f} s simulated")
    res.add("sum of the solver's solve times [s]", solve)
    res.add("wall time / sum of solve times", wall / solve, f"<= {TARGET_SHARE:g}",
            wall / solve <= TARGET_SHARE)
    mean_period = [sum(r["period"]) / len(r["period"]) for r in per_run]
    mpc_med = [median(r[MPC]) for r in per_run]
    section: dict[str, float] = {}
    for part in [*PARTS, REST, "period"]:
        med = median([median(r[part]) for r in per_run])
        mean = median([sum(r[part]) / len(r[part]) for r in per_run])
        p99 = median([percentile(r[part], 99) for r in per_run])
        share = median([sum(r[part]) / len(r[part]) / m for r, m in zip(per_run, mean_period,
                                                                         strict=True)])
        ratio = median([median(r[part]) / m for r, m in zip(per_run, mpc_med, strict=True)])
        res.add(f"{part}, median [ms]", med,
                note=f"mean {mean:.3f} ms, p99 {p99:.3f} ms; {100 * share:.1f} % of the period's mean; "
                     f"{ratio:.2f} x the MPC solve's median")
        key = part.replace(" ", "_")
        section |= {f"{key}_median_ms": med, f"{key}_mean_ms": mean, f"{key}_p99_ms": p99,
                    f"{key}_share": share,
                    f"{key}_per_mpc_solve": ratio}
    res.sections["parts"] = section
    res.meta = {"scenario": SCENARIO, "controller": CONTROLLER, "repeat": args.repeat}
    return res
