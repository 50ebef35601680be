"""Paper condition #1, closed loop, all three controllers: the shape of Table I.

Each controller must reach the last waypoint; CC-EMPC must have a lower average cross-track error than
EO-EMPC at no more than +0.5 % of its energy; both must use less than 20 % of the NMPC's energy.
Energies and times are also checked against Table I within the tolerances reproduction.md asks for
(5 % for the EMPCs; the NMPC's cost is not given by the paper, so a looser band).
"""

from __future__ import annotations

import pytest
from seaway.simkit.scenario import parse_scenario
from seaway_lab.closed_loop import TABLE_I, ClosedLoopResult, run_closed_loop

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
