"""Contract between the simulated PX4 (services/sim) and vehicle_io's PX4 profile.

They are written against the same document (docs/autopilots.md) by different hands; these checks
keep the two halves of the MAVLink thrust path and the failsafe check consistent.
"""

from __future__ import annotations

import itertools

import pytest
from seaway_sim import px4_mixer, px4_params
from seaway_vehicle_io.px4 import PROFILE


def test_every_failsafe_parameter_vehicle_io_reads_is_served_by_the_sim() -> None:
    missing = [p for p in PROFILE.failsafe_params if p not in px4_params.BY_NAME]
    assert not missing, f"the simulated PX4 does not answer {missing}"


@pytest.mark.parametrize(("left", "right"), list(itertools.product([-1.0, -0.4, 0.0, 0.3, 1.0], repeat=2)))
def test_vehicle_io_encoding_decodes_to_the_same_thrusts_in_the_sim(left: float, right: float) -> None:
    axes = PROFILE.manual_control(left, right)
    assert (axes.x, axes.r) == (0, 0)  # PX4 differential Manual ignores them
    got = px4_mixer.manual_control_to_normalised(axes.y, axes.z)
    assert got == pytest.approx((left, right), abs=2.5e-3)  # integer wire fields: 1/500 per step


@pytest.mark.parametrize("gain", [0.6, 1.0])
def test_the_yaw_stick_gain_means_the_same_on_both_sides(gain: float) -> None:
    """RD_YAW_STK_GAIN, served by the sim and read by vehicle_io, scales the same axis the same way."""
    assert px4_params.BY_NAME["RD_YAW_STK_GAIN"].used
    axes = PROFILE.mapper({"RD_YAW_STK_GAIN": gain})(0.5, 0.1)
    got = px4_mixer.manual_control_to_normalised(axes.y, axes.z, gain)
    assert got == pytest.approx((0.5, 0.1), abs=2.5e-3)
