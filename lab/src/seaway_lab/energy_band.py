"""How well the energy budget's band of the energy to finish covers the energy actually used.

    python -m seaway_lab.energy_band [--controller K ...] [--scenario S ...] [--json]

Each scenario's mission is flown by each controller in the in-process closed loop
(``seaway_lab.closed_loop``, the estimator alongside for the disturbance covariance, the battery
reported as the lockstep sim does). Every pricing of the budget (``EnergyBudget``, about once a
second) from the mission's start until a tenth of its time is left (as the report's check,
``seaway.vessel.metrics.energy_prediction_check``) is one sample: the nominal prediction, the band
as published (``energy_to_go_low_j`` .. ``energy_to_go_high_j``) and the energy actually used from
then to the end (``seaway.vessel.metrics.truth_energy_used``: the simulator's propulsion integral plus T^w t).

Printed per controller: the samples, the smallest and largest actual / predicted (what
``seaway.vessel.energy_prediction.MEASURED`` is derived from) and the coverage of the band as
published, with each scenario's. On the default scenarios the band's factors are those extremes, so
its coverage there is 1 by construction; other scenarios (``paper-c4-perturbed``,
``steady-current``) measure it out of sample. A non-finite end (published as None) is unbounded.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field

import numpy as np
from seaway.simkit.scenario import load_scenario
from seaway.vessel.metrics import CHECK_TAIL_FRAC, energy_used_at, truth_energy_used
from seaway.vessel.model import load_vessel
from seaway_estimator.core import EstimatorCore

from seaway_lab.closed_loop import run_closed_loop

SCENARIOS = ("paper-c1", "paper-c2", "paper-c3", "paper-c4", "paper-c5", "lake")
CONTROLLERS = ("cc-empc", "eo-empc", "nmpc")


@dataclass
class Sample:
    predicted_j: float
    low_j: float | None
    high_j: float | None
    actual_j: float

    @property
    def ratio(self) -> float:
        return self.actual_j / self.predicted_j

    @property
    def covered(self) -> bool:
        return (self.low_j is None or self.low_j <= self.actual_j) and (
            self.high_j is None or self.actual_j <= self.high_j
        )


@dataclass
class Measured:
    samples: dict[str, list[Sample]] = field(default_factory=dict)  # scenario -> samples

    def all(self) -> list[Sample]:
        return [s for v in self.samples.values() for s in v]


def samples_of(scenario: str, controller: str) -> list[Sample]:
    """The budget's predictions of one mission against what finishing took from each."""
    sc = load_scenario(scenario)
    assert sc.mission is not None, f"scenario {scenario} has no mission"
    r = run_closed_loop(sc, controller, estimator=EstimatorCore(vessel=load_vessel(sc.vessel)), battery=True)
    if not r.reached or r.metrics is None or r.metrics.travel_time_s is None:
        raise RuntimeError(f"{scenario} / {controller}: the mission did not complete")
    used = truth_energy_used(r.truth, sc.mission.task_power_w)
    t0 = r.truth[0].stamp_ns
    end_ns = t0 + round(r.metrics.travel_time_s * 1e9)
    tail_ns = end_ns - CHECK_TAIL_FRAC * (end_ns - t0)
    total = energy_used_at(used, end_ns)
    return [
        Sample(
            b.energy_to_go_j,
            b.energy_to_go_low_j,
            b.energy_to_go_high_j,
            total - energy_used_at(used, b.stamp_ns),
        )
        for b in r.budgets
        if b.energy_to_go_j is not None and b.energy_to_go_j > 0 and b.stamp_ns <= tail_ns
    ]


def summary(samples: list[Sample]) -> dict[str, float]:
    ratios = np.array([s.ratio for s in samples])
    return {
        "samples": len(samples),
        "ratio_low": float(ratios.min()),
        "ratio_high": float(ratios.max()),
        "worst_abs_error_pct": float(100 * np.max(np.abs(1.0 / ratios - 1.0))),
        "coverage": sum(s.covered for s in samples) / len(samples),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m seaway_lab.energy_band", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--controller", action="append", choices=CONTROLLERS)
    ap.add_argument("--scenario", action="append")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out: dict[str, dict] = {}
    for controller in args.controller or CONTROLLERS:
        m = Measured()
        for scenario in args.scenario or SCENARIOS:
            print(f"flying {scenario} with {controller} ...", file=sys.stderr, flush=True)
            m.samples[scenario] = samples_of(scenario, controller)
        out[controller] = summary(m.all()) | {
            "by_scenario": {k: summary(v) for k, v in m.samples.items() if v}
        }
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    for controller, s in out.items():
        print(
            f"{controller}: {s['samples']} predictions, actual/predicted "
            f"{s['ratio_low']:.4f}..{s['ratio_high']:.4f}, band covers {100 * s['coverage']:.1f} %"
        )
        for scenario, b in s["by_scenario"].items():
            print(
                f"  {scenario:20s} {b['samples']:4d}  covers {100 * b['coverage']:5.1f} %  worst "
                f"|error| {b['worst_abs_error_pct']:.1f} %"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
