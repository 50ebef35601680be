"""A thruster that loses half its thrust (a scheduled scenario fault, ``seaway.simkit.faults``) in
the seeded in-process closed loop: the model then predicts a turn and a speed the boat does not
have. A run of rejected yaw rates or velocities over ground re-opens the disturbance's uncertainty,
so the disturbance takes up what the model lacks instead of the heading following the model away."""

from __future__ import annotations

import math

from seaway.simkit.faults import ThrusterFault
from seaway.simkit.scenario import load_scenario
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_lab.closed_loop import run_estimator_loop

FAULT_S = 10.0


def test_a_half_lost_port_thruster_is_taken_up_by_the_disturbance_not_the_heading() -> None:
    lake = load_scenario("lake")
    faulty = lake.model_copy(
        update={"faults": [ThrusterFault(kind="thruster", time_s=FAULT_S, thruster="port", factor=0.5)]}
    )
    core = EstimatorCore(EstimatorConfig(vessel=lake.vessel, apply_dead_zone=lake.dead_zone))
    run = run_estimator_loop(faulty, core, 30.0, speed_mps=1.0)
    c = core.counters
    after = [s for s in run.samples if s.t_s > FAULT_S]
    # Before: the heading followed the model away (up to 3.1 rad off) and was re-initialised 9
    # times in 20 s, the position twice (5.0 m off).
    assert c["heading_reinit"] == 0 and c["gnss_reinit"] == 0 and c["heading_rejected"] == 0
    assert max(abs(s.psi_err_rad) for s in after) < math.radians(3.0)
    assert max(s.pos_err_m for s in after) < 1.5
    assert c["disturbance_reopened"] >= 1
    # The yaw moment the weaker port side leaves: it turns the boat to starboard less than modelled.
    surge_n, _, yaw_nm = core.body_disturbance()
    assert yaw_nm < -0.3
    assert surge_n < -4.0  # and the thrust it no longer gives (half of ~17 N)


def test_without_a_fault_nothing_is_reopened() -> None:
    lake = load_scenario("lake")
    core = EstimatorCore(EstimatorConfig(vessel=lake.vessel, apply_dead_zone=lake.dead_zone))
    run_estimator_loop(lake, core, 30.0, speed_mps=1.0)
    assert core.counters["disturbance_reopened"] == 0 and core.counters["yaw_rate_rejected"] == 0


def test_a_thruster_lost_for_good_is_the_motion_faults_to_say_not_the_reopenings() -> None:
    """Re-openings are the filter taking up what its model lacks: a turn gives them too, several
    where the model is a rough identification (ArduPilot's SITL boat), so each is routine. A
    thruster that gives nothing is said as a motion fault, a warning."""
    lake = load_scenario("lake")
    faulty = lake.model_copy(
        update={"faults": [ThrusterFault(kind="thruster", time_s=FAULT_S, thruster="port", factor=0.0)]}
    )
    core = EstimatorCore(EstimatorConfig(vessel=lake.vessel, apply_dead_zone=lake.dead_zone))
    run_estimator_loop(faulty, core, 30.0, speed_mps=1.0)
    notices = core.take_notices()
    reopened = [n for n in notices if n.kind == "disturbance_reopened"]
    assert len(reopened) >= 3 and not any(n.persistent for n in reopened)
    faults = [n for n in notices if n.kind == "motion_fault"]
    assert faults and faults[0].persistent and faults[0].stamp_ns > FAULT_S * 1e9


def test_a_loss_the_first_reopening_takes_up_is_routine() -> None:
    """A port thruster at 70 %: one run of rejected yaw rates re-opens the disturbance, which then
    carries the loss; nothing comes again, so nothing is a warning (a turn's transient looks the
    same to the filter)."""
    lake = load_scenario("lake")
    faulty = lake.model_copy(
        update={"faults": [ThrusterFault(kind="thruster", time_s=FAULT_S, thruster="port", factor=0.7)]}
    )
    core = EstimatorCore(EstimatorConfig(vessel=lake.vessel, apply_dead_zone=lake.dead_zone))
    run_estimator_loop(faulty, core, 30.0, speed_mps=1.0)
    reopened = [n for n in core.take_notices() if n.kind == "disturbance_reopened"]
    assert len(reopened) == 1 and reopened[0].stamp_ns >= FAULT_S * 1e9
    assert not reopened[0].persistent
    _, _, yaw_nm = core.body_disturbance()
    assert yaw_nm < -0.3  # carried by the disturbance (+0.04 N m without the fault)
