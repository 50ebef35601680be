"""PX4's MANUAL_CONTROL -> thrust mapping (differential Manual mode) and the inverse vehicle_io uses."""

from __future__ import annotations

import itertools

import pytest
from seaway_sim import px4_mixer as mx


@pytest.mark.parametrize(("y", "z", "left", "right"), [
    (0, 500, 0.0, 0.0),          # z = 500 is stop
    (0, 1000, 1.0, 1.0),         # full ahead
    (0, 0, -1.0, -1.0),          # z = 0 is full astern (PX4: z / 500 - 1)
    (0, 750, 0.5, 0.5),
    (500, 500, 0.5, -0.5),       # roll right, no throttle: spin clockwise (port ahead)
    (-1000, 500, -1.0, 1.0),     # full roll left: spin counter-clockwise
    (200, 900, 1.0, 0.6),        # thr 0.8, d 0.2: no cut, |0.8| + |0.2| = 1
    (500, 1000, 1.0, 0.0),       # thr 1, d 0.5: cut to thr 0.5 -> (1.0, 0.0)
    (-500, 0, -1.0, 0.0),        # thr -1, d -0.5: cut to thr -0.5 -> (-1.0, 0.0)
    (1001, 1000, 1.0, 1.0),      # y out of PX4's range: roll left at 0
    (0, -1, 0.0, 0.0),           # z below 0: throttle left at 0 (stop), not reverse
    (0, 1001, 0.0, 0.0),         # z above 1000: throttle 0
])
def test_forward_table(y: int, z: int, left: float, right: float) -> None:
    assert mx.manual_control_to_normalised(y, z) == pytest.approx((left, right), abs=1e-12)


def test_thrust_is_normalised_times_thrust_max_port_is_left() -> None:
    assert mx.manual_control_to_thrust_n(200, 900, 10.0) == pytest.approx((10.0, 6.0))
    assert mx.manual_control_to_thrust_n(0, 250, 75.0) == pytest.approx((-37.5, -37.5))


def test_output_never_leaves_the_unit_box() -> None:
    for y, z in itertools.product(range(-1000, 1001, 50), range(0, 1001, 50)):
        left, right = mx.manual_control_to_normalised(y, z)
        assert -1.0 - 1e-12 <= left <= 1.0 + 1e-12 and -1.0 - 1e-12 <= right <= 1.0 + 1e-12


@pytest.mark.parametrize(("left", "right"), [
    (0.0, 0.0), (1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (0.3, -0.7), (0.999, 0.001),
    (-0.25, 0.8), (0.6, 0.6),
])
def test_inverse_round_trip_within_quantisation(left: float, right: float) -> None:
    y, z = mx.normalised_to_manual_control(left, right)
    assert -1000 <= y <= 1000 and 0 <= z <= 1000
    got = mx.manual_control_to_normalised(y, z)
    # y quantises d = (L - R)/2 to 0.001 and z quantises thr to 0.002: L, R within 0.0015.
    assert got == pytest.approx((left, right), abs=0.0015)


def test_inverse_clamps_to_the_accepted_ranges() -> None:
    assert mx.normalised_to_manual_control(3.0, -2.0) == (1000, 500)
    assert mx.normalised_to_manual_control(-5.0, -5.0) == (0, 0)
