"""Newtons -> normalised -> MANUAL_CONTROL, for both profiles: saturation, dead zone, sign,
asymmetric reverse, and a round trip through each autopilot's documented decoding."""

from __future__ import annotations

import itertools

import pytest
from seaway.vessel.model import load_vessel
from seaway.vessel.thrusters import apply_dead_zone, compensate_dead_zone
from seaway_vehicle_io.ardupilot import PROFILE as AP
from seaway_vehicle_io.profile import ManualControlAxes, clamp_int
from seaway_vehicle_io.px4 import PROFILE as PX4
from seaway_vehicle_io.thrust import ThrusterLimits, normalise, normalise_pair

# Asymmetric on purpose: 75 N ahead, 50 N astern, 10 N dead zone.
LIM = ThrusterLimits(thrust_max_n=75.0, reverse_max_n=50.0, dead_zone_n=10.0)
NO_DZ = ThrusterLimits(thrust_max_n=10.0, reverse_max_n=10.0, dead_zone_n=0.0)


@pytest.mark.parametrize(
    ("thrust_n", "expect"),
    [
        (0.0, 0.0),
        (75.0, 1.0),
        (100.0, 1.0),  # saturated ahead
        (-50.0, -1.0),
        (-80.0, -1.0),  # saturated astern at the reverse bound, not the ahead one
        (37.5, 0.5),
        (-25.0, -0.5),  # astern normalised by 50 N
        (10.0, 10.0 / 75.0),  # at the dead-zone edge: unchanged
        (6.0, 10.0 / 75.0),  # inside, above half: up to the edge
        (5.0, 0.0),  # exactly half: to zero
        (4.0, 0.0),
        (-6.0, -10.0 / 50.0),  # astern edge uses the astern bound
        (-4.9, 0.0),
        (1e-9, 0.0),
    ],
)
def test_normalise_table(thrust_n, expect):
    assert normalise(thrust_n, LIM) == pytest.approx(expect, abs=1e-12)


@pytest.mark.parametrize(("thrust_n", "expect"), [
    (0.3, 0.03), (-0.3, -0.03), (10.0, 1.0), (-10.0, -1.0), (11.0, 1.0), (-11.0, -1.0)])
def test_normalise_without_dead_zone_is_linear(thrust_n, expect):
    assert normalise(thrust_n, NO_DZ) == pytest.approx(expect)


def test_guard_lifts_only_values_at_the_edge():
    g = 0.002
    assert normalise(10.0, LIM, g) == pytest.approx(10.0 / 75.0 + g)
    assert normalise(-10.0, LIM, g) == pytest.approx(-(10.0 / 50.0 + g))
    assert normalise(20.0, LIM, g) == pytest.approx(20.0 / 75.0)  # well outside: untouched
    assert normalise(0.0, LIM, g) == 0.0  # neutral stays exact


@pytest.mark.parametrize(("t", "dz", "expect"), [
    (0.0, 10.0, 0.0), (9.99, 10.0, 10.0), (-5.01, 10.0, -10.0), (-5.0, 10.0, 0.0),
    (12.0, 10.0, 12.0), (3.0, 0.0, 3.0)])
def test_compensate_dead_zone(t, dz, expect):
    assert compensate_dead_zone(t, dz) == expect


def test_nonfinite_thrust_refused():
    with pytest.raises(ValueError):
        normalise(float("nan"), LIM)


def test_limits_from_vessel_file():
    lim = ThrusterLimits.from_vessel(load_vessel("paper-boat"))
    assert (lim.thrust_max_n, lim.reverse_max_n, lim.dead_zone_n) == (75.0, 75.0, 10.0)
    with pytest.raises(ValueError):
        ThrusterLimits(10.0, 10.0, 10.0)


# -- profiles: (L, R) -> axes -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("left", "right", "y", "z"),
    [
        (0.0, 0.0, 0, 500),  # neutral: z = 500 is PX4's stop
        (1.0, 1.0, 0, 1000),
        (-1.0, -1.0, 0, 0),
        (1.0, -1.0, 1000, 500),  # spin clockwise (turn right)
        (-1.0, 1.0, -1000, 500),
        (0.5, 0.0, 250, 625),
        (0.4, -0.2, 300, 550),
        (1.5, 1.5, 0, 1000),  # out of range clamps, never wraps
    ],
)
def test_px4_axes(left, right, y, z):
    assert PX4.manual_control(left, right) == ManualControlAxes(0, y, z, 0)


@pytest.mark.parametrize(
    ("left", "right", "y", "z"),
    [
        (0.0, 0.0, 0, 0),  # neutral: signed, 0 = stop on Rover
        (1.0, 1.0, 1000, 1000),
        (1.0, -1.0, 1000, -1000),
        (-0.5, 0.25, -500, 250),
        (-2.0, 2.0, -1000, 1000),
    ],
)
def test_ardupilot_axes(left, right, y, z):
    assert AP.manual_control(left, right) == ManualControlAxes(0, y, z, 0)


@pytest.mark.parametrize(("v", "expect"), [(0.5, 1), (-0.5, -1), (0.49, 0), (1000.4, 1000),
                                           (2000.0, 1000), (-2000.0, -1000)])
def test_clamp_int_rounds_half_away_from_zero(v, expect):
    assert clamp_int(v, -1000, 1000) == expect


def px4_decode(axes: ManualControlAxes, yaw_stick_gain: float = 1.0) -> tuple[float, float]:
    """What PX4 does with the axes (docs/autopilots.md A.1.1 and A.1.3): (L, R)."""
    thr = axes.z / 500.0 - 1.0
    d = axes.y / 1000.0 * yaw_stick_gain
    excess = abs(thr) + abs(d) - 1.0
    if excess > 0:  # "prioritize yaw rate": throttle reduced by the excess
        thr -= excess if thr > 0 else -excess
    return thr + d, thr - d


def ardupilot_decode(axes: ManualControlAxes) -> tuple[float, float]:
    """Rover with PILOT_STEER_TYPE=1: left paddle = y/1000, right paddle = z/1000 (B.1)."""
    return axes.y / 1000.0, axes.z / 1000.0


def produced(u: float, lim: ThrusterLimits) -> float:
    """The plant's thrust for a normalised command (scale, then the dead zone, as the plant does)."""
    return apply_dead_zone(u * (lim.thrust_max_n if u >= 0 else lim.reverse_max_n), lim.dead_zone_n)


DEMANDS = [-80.0, -50.0, -30.0, -10.0, -7.0, -5.0, -2.0, 0.0, 3.0, 5.1, 9.9, 10.0, 10.05, 25.0,
           74.0, 75.0, 90.0]


@pytest.mark.parametrize(("profile", "decode"), [(PX4, px4_decode), (AP, ardupilot_decode)],
                         ids=["px4", "ardupilot"])
def test_round_trip_through_the_autopilot(profile, decode):
    """Every pair of demands comes out of the autopilot as the compensated, saturated demand,
    within the wire's resolution, and a non-zero command never lands back in the dead zone."""
    tol_n = 0.0016 * LIM.thrust_max_n  # worst-case rounding of L or R, in newtons
    for port, stbd in itertools.product(DEMANDS, DEMANDS):
        left, right = normalise_pair(port, stbd, LIM, profile.quantisation_guard)
        out_l, out_r = decode(profile.manual_control(left, right))
        for demand, u in ((port, out_l), (stbd, out_r)):
            want = compensate_dead_zone(min(max(demand, -LIM.reverse_max_n), LIM.thrust_max_n),
                                        LIM.dead_zone_n)
            got = produced(u, LIM)
            assert (got == 0.0) == (want == 0.0), (port, stbd, demand, got)
            assert got == pytest.approx(want, abs=tol_n + profile.quantisation_guard * 75.0)
            assert (got > 0) == (want > 0)  # sign preserved: port is T1 (left), stbd T2 (right)


def test_turn_direction_px4():
    """More port thrust than starboard yaws clockwise (NED): PX4 roll (y) positive."""
    left, right = normalise_pair(40.0, 10.0, LIM)
    assert PX4.manual_control(left, right).y > 0
    assert AP.manual_control(left, right).y > AP.manual_control(left, right).z


@pytest.mark.parametrize("gain", [0.6, 1.0, 0.25])
def test_px4_mapper_undoes_the_yaw_stick_gain(gain):
    """With the firmware's RD_YAW_STK_GAIN read, every pair within reach (|L - R| <= 2 gain) comes
    out of PX4's mixing as sent; beyond it the difference is cut to 2 gain, the sum kept."""
    axes = PX4.mapper({"RD_YAW_STK_GAIN": gain})
    levels = [-1.0, -0.6, -0.2, 0.0, 0.15, 0.5, 0.9, 1.0]
    for left, right in itertools.product(levels, levels):
        out_l, out_r = px4_decode(axes(left, right), gain)
        if abs(left - right) <= 2 * gain:
            assert (out_l, out_r) == pytest.approx((left, right), abs=PX4.quantisation_guard)
        else:
            assert out_l - out_r == pytest.approx(2 * gain * (1 if left > right else -1), abs=2e-3)
            assert out_l + out_r == pytest.approx(left + right, abs=2.5e-3)


def test_px4_yaw_stick_gain_is_judged():
    base = {"COM_RC_IN_MODE": 1, "COM_RC_LOSS_T": 0.5, "NAV_RCL_ACT": 1}
    assert PX4.assess_failsafe({**base, "RD_YAW_STK_GAIN": 1.0}, 245).warnings == ()
    low = PX4.assess_failsafe({**base, "RD_YAW_STK_GAIN": 0.6}, 245)
    assert any("RD_YAW_STK_GAIN=0.6" in w and "1.2" in w for w in low.warnings), low
    assert not low.blocking
    zero = PX4.assess_failsafe({**base, "RD_YAW_STK_GAIN": 0.0}, 245)
    assert any("RD_YAW_STK_GAIN=0" in b for b in zero.blocking), zero
    assert PX4.mapper({"RD_YAW_STK_GAIN": 0.0})(0.5, 0.0) == PX4.manual_control(0.5, 0.0)
    assert PX4.mapper({})(0.5, 0.0) == PX4.manual_control(0.5, 0.0)  # absent: PX4's default 1
