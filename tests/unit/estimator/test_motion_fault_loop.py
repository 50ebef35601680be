"""The motion fault in the seeded in-process closed loop (``seaway_lab.closed_loop``): the
simulator's core with a scheduled stuck thruster or grounding (``seaway.simkit.faults``), the
estimator's core fed as in lockstep. The fault is named in the published estimates within a bounded
time, once, with a notice worth a WARNING; the paper's scenarios and the lake, flown normally by the
controller with realistic sensors, raise none."""

from __future__ import annotations

import math

import pytest
from seaway.simkit.faults import GroundingFault, StuckThrusterFault
from seaway.simkit.scenario import load_scenario
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_lab.closed_loop import REALISTIC_NOISE, run_closed_loop, run_estimator_loop

FAULT_S = 20.0
WINDOW_AND_ONSET_S = 5.0 + 3.0  # MismatchConfig: window_s + onset_s
LATENCY_SLACK_S = 2.0  # the vessel's own deceleration, fix instants


def estimator(sc) -> EstimatorCore:
    return EstimatorCore(EstimatorConfig(vessel=sc.vessel, apply_dead_zone=sc.dead_zone))


@pytest.mark.parametrize("fault", [
    GroundingFault(kind="grounding", time_s=FAULT_S),
    StuckThrusterFault(kind="stuck_thruster", time_s=FAULT_S, thruster="port", thrust_n=0.0),
], ids=["grounding", "stuck_thruster"])
def test_a_vessel_that_does_not_follow_its_thrust_is_named_once(fault) -> None:
    sc = load_scenario("lake").model_copy(update={"faults": [fault]})
    core = estimator(sc)
    run = run_estimator_loop(sc, core, 45.0, speed_mps=1.0)
    faulted = [s for s in run.samples if s.est.motion_fault is not None]
    assert faulted, "no motion fault published"
    first = faulted[0]
    assert FAULT_S < first.t_s <= FAULT_S + WINDOW_AND_ONSET_S + LATENCY_SLACK_S
    assert first.est.motion_fault == "not_moving"
    assert "commanded" in first.est.motion_fault_detail and "measured" in first.est.motion_fault_detail
    assert all(s.est.motion_fault == "not_moving" for s in run.samples if s.t_s >= first.t_s)
    onsets = [n for n in core.take_notices() if n.kind == "motion_fault"]
    assert len(onsets) == 1 and onsets[0].persistent  # logged once, at WARNING
    assert core.counters["motion_faults"] == 1
    # Re-anchored on the measurements: the published state is where the boat is, and still.
    after = [s for s in run.samples if s.t_s > first.t_s + 1.0]
    truth = {t.stamp_ns: t for t in run.truth}
    assert max(s.pos_err_m for s in after) < 0.6
    assert max(abs(math.hypot(s.est.u_mps, s.est.v_mps)
                   - math.hypot(truth[s.est.stamp_ns].u_mps, truth[s.est.stamp_ns].v_mps))
               for s in after) < 0.15


@pytest.mark.parametrize(("scenario", "controller"), [
    ("paper-c1", "cc-empc"), ("paper-c4", "cc-empc"), ("paper-c5", "nmpc"),
    ("paper-c4-perturbed", "nmpc"), ("lake", "cc-empc"), ("steady-current", "cc-empc"),
])
def test_normal_runs_raise_no_motion_fault(scenario: str, controller: str) -> None:
    sc = load_scenario(scenario)
    if scenario != "lake":  # the paper's sensors are perfect; the lake's are already realistic
        sc = sc.model_copy(update={"sensors": REALISTIC_NOISE})
    core = estimator(sc)
    result = run_closed_loop(sc, controller, estimator=core)
    assert result.reached
    assert core.mismatch.onsets == 0, [n.detail for n in core.take_notices() if n.kind == "motion_fault"]
    assert core.counters["motion_anchored"] == 0
