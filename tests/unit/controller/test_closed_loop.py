"""Paper condition #1, closed loop (``seaway_lab.closed_loop``), all three controllers: the shape of
Table I, and what the loop is made of.

Each controller must reach the last waypoint; CC-EMPC must have a lower average cross-track error than
EO-EMPC at no more than +0.5 % of its energy; both must use less than 20 % of the NMPC's energy.
Energies and times are also checked against Table I within the tolerances reproduction.md asks for
(5 % for the EMPCs; the NMPC's cost is not given by the paper, so a looser band).
"""

from __future__ import annotations

import math

import pytest
from seaway.contract.units import NS_PER_S
from seaway.simkit.scenario import load_scenario, parse_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel
from seaway_estimator.core import EstimatorCore
from seaway_lab.closed_loop import TABLE_I, ClosedLoopResult, run_closed_loop
from seaway_sim.core import SimCore

TABLE_I_C1 = TABLE_I[1]  # controller -> (energy J, cross-track m, time s)


@pytest.fixture(scope="module")
def runs() -> dict[str, ClosedLoopResult]:
    return {kind: run_closed_loop("paper-c1", kind) for kind in TABLE_I_C1}


@pytest.mark.parametrize("kind", list(TABLE_I_C1))
def test_reaches_the_last_waypoint_without_failures(runs, kind):
    r = runs[kind]
    assert r.reached, f"{kind} did not finish within the time limit"
    assert r.unconverged == 0 and r.fallback_count == 0
    assert len(r.solve_times_s) == r.steps


def test_cc_empc_trades_a_little_energy_for_accuracy(runs):
    cc, eo = runs["cc-empc"], runs["eo-empc"]
    assert cc.cross_track_mean_m < eo.cross_track_mean_m
    assert cc.energy_j <= eo.energy_j * 1.005


def test_empcs_use_a_fraction_of_the_nmpc_energy(runs):
    nmpc = runs["nmpc"]
    for kind in ("cc-empc", "eo-empc"):
        assert runs[kind].energy_j < 0.2 * nmpc.energy_j
        assert runs[kind].travel_time_s > 5 * nmpc.travel_time_s
    assert nmpc.cross_track_mean_m > runs["eo-empc"].cross_track_mean_m


@pytest.mark.parametrize("kind", ["cc-empc", "eo-empc"])
def test_empc_energy_and_time_match_table_one(runs, kind):
    energy, _, time_s = TABLE_I_C1[kind]
    assert runs[kind].energy_j == pytest.approx(energy, rel=0.05)
    assert runs[kind].travel_time_s == pytest.approx(time_s, rel=0.05)


def test_nmpc_is_tuned_near_table_one(runs):
    energy, _, time_s = TABLE_I_C1["nmpc"]
    assert runs["nmpc"].energy_j == pytest.approx(energy, rel=0.15)
    assert runs["nmpc"].travel_time_s == pytest.approx(time_s, rel=0.15)


@pytest.mark.parametrize("kind", list(TABLE_I_C1))
def test_sharp_turns_across_the_heading_cut(kind):
    # Start heading 3.1 rad toward a waypoint behind the +-pi cut, then turns of 100-140 degrees:
    # the warm start must follow the wrapped heading estimate, and every leg must be completed.
    sc = parse_scenario({
        "name": "wrap", "seed": 1, "vessel": "paper-sim",
        "start": {"x_m": 0.0, "y_m": 0.0, "psi_rad": 3.1},
        "mission": {"waypoints_m": [[0, 0], [-8, -0.3], [-12, 3], [-10, 6], [-14, 4]],
                    "coa_radius_m": 1.0, "task_power_w": 0.49}})
    r = run_closed_loop(sc, kind)
    assert r.reached
    assert r.unconverged <= 3  # a rare failed solve is absorbed by the fallback chain
    assert r.cross_track_mean_m < 0.6


def test_the_loop_is_the_simulators_core_holding_each_command_for_one_period(runs):
    # Replaying the commands through a fresh SimCore, one 0.1 s advance each, gives the same
    # positions bit for bit: the loop adds no plant of its own.
    sc = load_scenario("paper-c1")
    r = runs["nmpc"]
    sim = SimCore(sc, load_vessel(sc.vessel))
    for t_s, x, y, t1, t2 in r.trajectory:
        assert (t_s, x, y) == (sim.t_ns / NS_PER_S, sim.truth().x_m, sim.truth().y_m)
        sim.advance((t1, t2), 100_000_000)
    assert len(r.trajectory) == r.steps and r.metrics is not None
    assert r.metrics.end_ns == sim.t_ns  # completed at the state reached by the last command


def test_figures_are_the_reports_metrics_of_the_simulators_truth(runs):
    r = runs["cc-empc"]
    assert r.metrics is not None and r.metrics.completed
    assert r.travel_time_s == r.metrics.travel_time_s == r.metrics.end_ns / NS_PER_S
    assert r.energy_j == r.metrics.energy_j
    assert r.cross_track_mean_m == r.metrics.avg_cross_track_m
    # The task power over the travel time, plus the propulsion energy the simulator integrated.
    assert r.metrics.task_energy_j == pytest.approx(0.49 * r.travel_time_s, rel=1e-12)


def test_a_mission_in_degrees_flies_like_the_same_mission_in_metres(runs):
    # The scenario's mission goes through MissionSpec.to_request and the controller converts the
    # waypoints through the scenario's origin, as on the bus.
    sc = load_scenario("paper-c1")
    origin = GeoOrigin.from_degrees(sc.origin.lat_deg, sc.origin.lon_deg, sc.origin.alt_m)
    deg = []
    for x, y in sc.mission.waypoints_m:
        lat, lon, _ = origin.to_geodetic(x, y, 0.0)
        deg.append((math.degrees(lat), math.degrees(lon)))
    mission = sc.mission.model_copy(update={"waypoints_m": None, "waypoints_deg": deg})
    r = run_closed_loop(sc.model_copy(update={"mission": mission}), "nmpc")
    ref = runs["nmpc"]
    assert r.reached
    assert r.steps == ref.steps
    assert r.energy_j == pytest.approx(ref.energy_j, rel=1e-6)
    assert r.cross_track_mean_m == pytest.approx(ref.cross_track_mean_m, rel=1e-6)


def test_an_estimator_can_ride_along_without_steering(runs):
    r = run_closed_loop("paper-c1", "nmpc", estimator=EstimatorCore())
    ref = runs["nmpc"]
    assert r.trajectory == ref.trajectory  # it observes; the controller still reads the truth
    assert r.run is not None and len(r.run.samples) > 300
    assert max(s.pos_err_m for s in r.run.samples) < 0.05  # the scenario's noise-free sensors


def test_the_in_process_loop_flies_the_scenarios_plant_not_the_model() -> None:
    # paper-c4-perturbed: the controller models paper-sim, the plant is 20 % heavier and less damped.
    nominal = run_closed_loop("paper-c4", "cc-empc")
    perturbed = run_closed_loop("paper-c4-perturbed", "cc-empc")
    assert nominal.reached and perturbed.reached
    # Less damping makes the real vessel faster than the model predicts (266 s through the processes).
    assert perturbed.travel_time_s < nominal.travel_time_s - 30.0


def test_the_closed_loop_does_not_judge_solves_by_wall_time(monkeypatch):
    """A solve the machine's load made slow is not a failed one: the in-process loop is a
    simulation, like lockstep (a unit test must not depend on machine load; issue 14, item 13).
    The solver here reports 0.5 s per solve, five times the period."""
    from seaway_controller import core as core_module

    from tests.unit.controller.test_core import ScriptedSolver

    monkeypatch.setattr(core_module, "make_solver", lambda ocp, kind: ScriptedSolver(time_s=0.5))
    r = run_closed_loop("paper-c1", "cc-empc", max_time_s=1.0)
    assert r.steps >= 10 and r.unconverged == 0 and r.fallback_count == 0
