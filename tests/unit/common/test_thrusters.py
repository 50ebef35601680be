"""seaway.vessel.thrusters: saturation bounds (asymmetric), the dead zone and its compensation."""

from __future__ import annotations

import pytest
from seaway.vessel.model import load_vessel
from seaway.vessel.thrusters import (
    FULL_THRUST,
    apply_dead_zone,
    command_for,
    compensate_dead_zone,
    given_fractions,
    given_pair,
    loss_of,
    output_pair,
    output_stage,
    saturate,
)

BOAT = load_vessel("paper-boat")  # 75 N ahead, 10 N dead zone


@pytest.mark.parametrize(("demand", "want"), [(200.0, 75.0), (75.0, 75.0), (30.0, 30.0), (0.0, 0.0),
                                              (-49.0, -49.0), (-1e6, -50.0)])
def test_saturation_bounds_are_the_vessels_and_reverse_may_be_weaker(demand, want):
    class Bounds:
        thrust_max_n, reverse_max_n = 75.0, 50.0

    assert saturate(demand, Bounds()) == want


def test_saturation_uses_the_vessel_file():
    assert saturate(1e6, BOAT) == BOAT.thrust_max_n
    assert saturate(-1e6, BOAT) == -BOAT.reverse_max_n


def test_dead_zone_produces_nothing_below_and_everything_from_its_edge():
    dz = BOAT.dead_zone_n
    assert dz > 0
    assert apply_dead_zone(0.999 * dz, dz) == 0.0
    assert apply_dead_zone(-0.999 * dz, dz) == 0.0
    assert apply_dead_zone(dz, dz) == dz  # the edge is producible
    assert apply_dead_zone(-dz, dz) == -dz
    assert apply_dead_zone(3.0, 0.0) == 3.0  # no dead zone (the paper's vessel): unchanged


def test_compensation_sends_the_nearest_producible_thrust():
    assert compensate_dead_zone(6.0, 10.0) == 10.0
    assert compensate_dead_zone(-6.0, 10.0) == -10.0
    assert compensate_dead_zone(4.0, 10.0) == 0.0
    assert compensate_dead_zone(5.0, 10.0) == 0.0  # exactly half: rounds to zero
    assert compensate_dead_zone(12.0, 10.0) == 12.0
    assert compensate_dead_zone(0.0, 10.0) == 0.0
    # Whatever is sent survives the thruster's dead zone unchanged (or is exactly zero).
    for demand in (-9.0, -5.1, 0.3, 5.1, 9.99, 10.0, 40.0):
        sent = compensate_dead_zone(demand, 10.0)
        assert apply_dead_zone(sent, 10.0) == sent
        assert abs(sent - demand) <= 5.0


def test_the_output_stage_saturates_then_compensates_with_the_vessel_files_dead_zone():
    # What Seaway sends a thruster (vehicle I/O; the lockstep sim and the in-process loop in its
    # place): a demand in the dead zone's upper half is sent at its edge, one in the lower half as 0.
    assert output_stage(6.0, BOAT) == BOAT.dead_zone_n == 10.0
    assert output_stage(-6.0, BOAT) == -10.0
    assert output_stage(4.0, BOAT) == 0.0
    assert output_stage(1e6, BOAT) == BOAT.thrust_max_n
    assert output_stage(-1e6, BOAT) == -BOAT.reverse_max_n
    assert output_stage(30.0, BOAT) == 30.0
    assert output_pair(6.0, -4.0, BOAT) == (10.0, 0.0)
    paper = load_vessel("paper-sim")  # no dead zone: only saturation
    assert output_pair(6.0, 25.0, paper) == (6.0, paper.thrust_max_n)


def test_a_side_found_short_gives_that_much_less_of_its_command():
    assert given_fractions(None, None) == FULL_THRUST == (1.0, 1.0)
    assert given_fractions("port", 0.3) == pytest.approx((0.7, 1.0))
    assert given_fractions("starboard", 0.45) == pytest.approx((1.0, 0.55))
    assert given_fractions("port", 1.7) == (0.0, 1.0)  # at most all of it is lost
    assert given_pair(20.0, -10.0, (0.5, 1.0)) == (10.0, -10.0)
    assert given_pair(20.0, 12.0, FULL_THRUST) == (20.0, 12.0)


@pytest.mark.parametrize(("side", "surge_n", "yaw_sign"), [("port", -6.0, -1.0), ("starboard", -3.6, 1.0)])
def test_a_loss_takes_its_thrust_off_the_surge_and_turns_away_from_the_side(side, surge_n, yaw_sign):
    """Paper eq. 1: surge T1 + T2, yaw (T1 - T2) l; a port loss turns the boat to port (negative)."""
    arm_m = 0.3
    surge, yaw = loss_of(20.0, 12.0, given_fractions(side, 0.3), arm_m)
    assert surge == pytest.approx(surge_n)
    assert yaw == pytest.approx(yaw_sign * abs(surge_n) * arm_m)
    assert loss_of(20.0, 12.0, FULL_THRUST, arm_m) == (0.0, 0.0)


def test_the_command_for_a_thrust_asks_a_weak_side_for_more_within_its_bounds():
    assert command_for(20.0, 12.0, (0.5, 1.0), BOAT) == pytest.approx((40.0, 12.0))
    assert command_for(-20.0, 12.0, (1.0, 0.8), BOAT) == pytest.approx((-20.0, 15.0))
    assert command_for(50.0, 12.0, (0.5, 1.0), BOAT) == (BOAT.thrust_max_n, 12.0)  # saturated
    assert command_for(20.0, 12.0, (0.0, 1.0), BOAT) == (20.0, 12.0)  # gives nothing: as asked
    assert command_for(500.0, 12.0, FULL_THRUST, BOAT) == (500.0, 12.0)  # no loss: untouched
    port, starboard = command_for(20.0, 12.0, (0.6, 1.0), BOAT)
    assert given_pair(port, starboard, (0.6, 1.0)) == pytest.approx((20.0, 12.0))
