"""Table tests for every MAVLink -> SI conversion and its range checks."""

from __future__ import annotations

import math
from types import SimpleNamespace as Ns

import pytest
from seaway_vehicle_io.conversions import (
    FieldError,
    GpsQuality,
    NoDataError,
    attitude_from_attitude,
    battery_from_battery_status,
    battery_from_sys_status,
    gnss_from_global_position_int,
    gps_quality_from_gps_raw_int,
    local_position_from_local_position_ned,
    wrap_pi,
)

NAN = float("nan")
INF = float("inf")
U16 = 65535


def angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def gpi(**kw):
    base = dict(lat=473977420, lon=85455940, alt=488_000, vx=150, vy=-50)
    base.update(kw)
    return Ns(**base)


@pytest.mark.parametrize(
    ("fields", "lat_rad", "lon_rad", "alt_m", "vn", "ve"),
    [
        # degE7 -> rad, mm -> m, cm/s -> m/s
        ({}, math.radians(47.397742), math.radians(8.545594), 488.0, 1.5, -0.5),
        ({"lat": 900000000, "lon": 1800000000}, math.pi / 2, math.pi, 488.0, 1.5, -0.5),
        ({"lat": -900000000, "lon": -1800000000}, -math.pi / 2, -math.pi, 488.0, 1.5, -0.5),
        ({"lat": 1, "lon": -1}, math.radians(1e-7), math.radians(-1e-7), 488.0, 1.5, -0.5),
        ({"alt": -12_345, "vx": 0, "vy": 0}, math.radians(47.397742), math.radians(8.545594),
         -12.345, 0.0, 0.0),
        ({"vx": -10_000, "vy": 10_000}, math.radians(47.397742), math.radians(8.545594), 488.0,
         -100.0, 100.0),
    ],
)
def test_global_position_int_units(fields, lat_rad, lon_rad, alt_m, vn, ve):
    fix = gnss_from_global_position_int(gpi(**fields), 123, None, 0)
    assert fix.stamp_ns == 123
    assert fix.lat_rad == pytest.approx(lat_rad, abs=1e-15)
    assert fix.lon_rad == pytest.approx(lon_rad, abs=1e-15)
    assert fix.alt_m == pytest.approx(alt_m, abs=1e-12)
    assert fix.vel_n_mps == pytest.approx(vn)
    assert fix.vel_e_mps == pytest.approx(ve)


def test_global_position_quality_from_gps_raw_or_default():
    q = GpsQuality(fix_type=6, horizontal_std_m=0.02, satellites=21)
    fix = gnss_from_global_position_int(gpi(), 1, q, 0)
    assert (fix.fix_type, fix.horizontal_std_m, fix.satellites) == (6, 0.02, 21)
    fix = gnss_from_global_position_int(gpi(), 1, None, 0)
    assert (fix.fix_type, fix.horizontal_std_m, fix.satellites) == (0, None, None)


@pytest.mark.parametrize(
    ("fields", "bad_field"),
    [
        ({"lat": 900000001}, "lat"),
        ({"lat": -900000001}, "lat"),
        ({"lon": 1800000001}, "lon"),
        ({"lon": NAN}, "lon"),
        ({"alt": 100_000_001}, "alt"),
        ({"alt": -1_000_001}, "alt"),
        ({"vx": 10_001}, "vx"),
        ({"vy": -10_001}, "vy"),
        ({"vx": INF}, "vx"),
    ],
)
def test_global_position_int_out_of_range(fields, bad_field):
    with pytest.raises(FieldError) as err:
        gnss_from_global_position_int(gpi(**fields), 1, None, 0)
    assert err.value.field == bad_field
    assert err.value.message_type == "GLOBAL_POSITION_INT"


def test_global_position_int_zero_is_no_data():
    with pytest.raises(NoDataError):
        gnss_from_global_position_int(gpi(lat=0, lon=0), 1, None, 0)


def att(**kw):
    base = dict(roll=0.1, pitch=-0.2, yaw=0.3, rollspeed=0.01, pitchspeed=-0.02, yawspeed=0.5)
    base.update(kw)
    return Ns(**base)


@pytest.mark.parametrize(
    ("fields", "expect"),
    [
        ({}, (0.1, -0.2, 0.3, 0.01, -0.02, 0.5)),
        ({"yaw": -3.0}, (0.1, -0.2, -3.0, 0.01, -0.02, 0.5)),
        # float32 pi is 3.1415927 > math.pi: accepted and wrapped into [-pi, pi]
        ({"yaw": 3.1415927}, (0.1, -0.2, math.pi, 0.01, -0.02, 0.5)),
        ({"yaw": -3.1415927}, (0.1, -0.2, -math.pi, 0.01, -0.02, 0.5)),
        ({"yawspeed": -40.0}, (0.1, -0.2, 0.3, 0.01, -0.02, -40.0)),
    ],
)
def test_attitude(fields, expect):
    a = attitude_from_attitude(att(**fields), 7)
    got = (a.roll_rad, a.pitch_rad, a.roll_rate_radps, a.pitch_rate_radps, a.yaw_rate_radps)
    assert got == pytest.approx(expect[:2] + expect[3:], abs=1e-6)
    assert angle_diff(a.yaw_rad, expect[2]) < 1e-6  # +pi and -pi are the same heading
    assert -math.pi <= a.yaw_rad <= math.pi


@pytest.mark.parametrize(
    ("fields", "bad_field"),
    [
        ({"roll": NAN}, "roll"),
        ({"pitch": 4.0}, "pitch"),
        ({"yaw": 3.2}, "yaw"),
        ({"yaw": -INF}, "yaw"),
        ({"rollspeed": 41.0}, "rollspeed"),
        ({"yawspeed": NAN}, "yawspeed"),
    ],
)
def test_attitude_rejects(fields, bad_field):
    with pytest.raises(FieldError) as err:
        attitude_from_attitude(att(**fields), 7)
    assert err.value.field == bad_field


def test_local_position_passthrough_and_rejects():
    m = Ns(x=1.0, y=-2.0, z=0.5, vx=0.1, vy=-0.2, vz=0.0)
    lp = local_position_from_local_position_ned(m, 5)
    assert (lp.x_m, lp.y_m, lp.z_m, lp.vx_mps, lp.vy_mps, lp.vz_mps) == (1.0, -2.0, 0.5, 0.1, -0.2, 0.0)
    for f, v in (("x", NAN), ("y", 2e6), ("vz", 101.0), ("vx", INF)):
        with pytest.raises(FieldError) as err:
            local_position_from_local_position_ned(Ns(**{**m.__dict__, f: v}), 5)
        assert err.value.field == f


@pytest.mark.parametrize(
    ("voltage_mv", "remaining_pct", "expect_v", "expect_frac"),
    [
        (16_200, 87, 16.2, 0.87),
        (U16, -1, None, None),  # both unknown
        (0, 0, 0.0, 0.0),
        (12_000, 100, 12.0, 1.0),
    ],
)
def test_sys_status_battery(voltage_mv, remaining_pct, expect_v, expect_frac):
    b = battery_from_sys_status(Ns(voltage_battery=voltage_mv, battery_remaining=remaining_pct,
                                   current_battery=-1))
    assert b.voltage_v == (pytest.approx(expect_v) if expect_v is not None else None)
    assert b.remaining_frac == (pytest.approx(expect_frac) if expect_frac is not None else None)


@pytest.mark.parametrize("remaining", [101, -2, 127])
def test_sys_status_rejects_remaining(remaining):
    with pytest.raises(FieldError) as err:
        battery_from_sys_status(Ns(voltage_battery=12_000, battery_remaining=remaining,
                                   current_battery=-1))
    assert err.value.field == "battery_remaining"


@pytest.mark.parametrize(
    ("cells", "ext", "expect_v"),
    [
        ([4100, 4100, 4100, 4100] + [U16] * 6, [0, 0, 0, 0], 16.4),  # four cells
        ([16_400] + [U16] * 9, [0, 0, 0, 0], 16.4),  # pack voltage in cell 0
        ([U16 - 1, 10_000] + [U16] * 8, [0, 0, 0, 0], 75.534),  # > 65.534 V split over 0 and 1
        ([U16] * 10, [0, 0, 0, 0], None),  # unknown
        ([3000] * 10, [3000, 3000, 0, 0], 36.0),  # 12 cells using the extension
    ],
)
def test_battery_status_voltage(cells, ext, expect_v):
    b = battery_from_battery_status(Ns(voltages=cells, voltages_ext=ext, battery_remaining=50,
                                       current_battery=-1, current_consumed=-1,
                                       energy_consumed=-1))
    assert b.voltage_v == (pytest.approx(expect_v) if expect_v is not None else None)
    assert b.remaining_frac == pytest.approx(0.5)


def test_gps_raw_int():
    q = gps_quality_from_gps_raw_int(Ns(fix_type=3, satellites_visible=12, h_acc=1200))
    assert q == GpsQuality(3, 1.2, 12)
    q = gps_quality_from_gps_raw_int(Ns(fix_type=0, satellites_visible=255, h_acc=0))
    assert q == GpsQuality(0, None, None)
    with pytest.raises(FieldError) as err:
        gps_quality_from_gps_raw_int(Ns(fix_type=9, satellites_visible=1, h_acc=0))
    assert err.value.field == "fix_type"


@pytest.mark.parametrize(("a", "w"), [(0.0, 0.0), (math.pi, math.pi), (-math.pi, -math.pi),
                                      (3 * math.pi / 2, -math.pi / 2), (7.0, 7.0 - 2 * math.pi)])
def test_wrap_pi(a, w):
    assert -math.pi <= wrap_pi(a) <= math.pi
    assert angle_diff(wrap_pi(a), w) < 1e-12
