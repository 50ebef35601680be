"""A scenario's disturbances and start are bounded (``seaway.simkit.scenario.MAX_*``): a valid file
with a current of 10^5 m/s, a wind of 10^6 m/s, a drag area of 10^9 m^2 or a gust std of 10^200 m/s
crashed the sim at its first steps (a GNSS speed over MAVLink's 16 bits, a heading of inf), and one
loaded at run time and kept in the sim's state file crashed it at every restart. Past a bound a file
is refused naming the field and the bound; at the bounds every shipped vessel's plant stays finite
and its telemetry packs. The same for the sensors and the origin's altitude: a speed std of 10^5 m/s,
a position std of 10^7 m, an altitude of 10^7 m overflowed a MAVLink field, a rate of 10^-300 Hz
the sensor's period, and outages starting 10^300 times a second hung the sim."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink
from seaway.contract.config import MAX_ALT_M, MIN_ALT_M, ConfigError
from seaway.simkit import scenario as sc
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config

from tests.conftest import REPO

VESSELS = sorted(p.stem for p in (REPO / "deploy" / "vessels").glob("*.toml"))


def lake_with(**changes) -> dict:
    doc = sc.load_scenario("lake").model_dump(mode="json")
    doc.pop("area")  # the lake's area holds its own start, not the far ones tried here
    doc.update(changes)
    return doc


@pytest.mark.parametrize(("changes", "field", "bound"), [
    ({"disturbances": [{"kind": "current", "north_mps": 1e5}]}, "north_mps", sc.MAX_CURRENT_MPS),
    ({"disturbances": [{"kind": "wind", "speed_mps": 1e6, "from_rad": 0.0}]}, "speed_mps", sc.MAX_WIND_MPS),
    ({"disturbances": [{"kind": "wind", "speed_mps": 3.0, "from_rad": 0.0, "drag_area_m2": 1e9}]},
     "drag_area_m2", sc.MAX_DRAG_AREA_M2),
    ({"disturbances": [{"kind": "wind", "speed_mps": 3.0, "from_rad": 0.0, "gust_std_mps": 1e200}]},
     "gust_std_mps", sc.MAX_GUST_STD_MPS),
    ({"disturbances": [{"kind": "wind", "speed_mps": 3.0, "from_rad": 0.0,
                        "gust_direction_std_rad": 1e308}]}, "gust_direction_std_rad", math.pi),
    ({"disturbances": [{"kind": "body_constant", "yaw_nm": -50.0}]}, "yaw_nm", -sc.MAX_MOMENT_NM),
    ({"disturbances": [{"kind": "world_constant", "east_n": 1e4}]}, "east_n", sc.MAX_FORCE_N),
    ({"disturbances": [{"kind": "world_grid", "xs_m": [0, 1], "ys_m": [0, 1],
                        "north_n": [[0, 0], [0, 0]], "east_n": [[0, 0], [0, 1e3]]}]},
     "east_n", sc.MAX_FORCE_N),
    ({"start": {"x_m": 1e300}}, "x_m", sc.MAX_START_RANGE_M),
    ({"start": {"u_mps": 300.0}}, "u_mps", sc.MAX_START_SPEED_MPS),
    # The sensors and the origin: each of these was accepted, then crashed the sim's first samples
    # (a MAVLink field overflowed), its start (an infinite period) or hung it (outages).
    ({"sensors": {"sog_std_mps": 1e5}}, "sog_std_mps", sc.MAX_SOG_STD_MPS),
    ({"sensors": {"gnss_std_m": 1e7}}, "gnss_std_m", sc.MAX_GNSS_STD_M),
    ({"sensors": {"gnss_std_m": 1e300}}, "gnss_std_m", sc.MAX_GNSS_STD_M),
    ({"sensors": {"heading_std_rad": 1e300}}, "heading_std_rad", sc.MAX_HEADING_STD_RAD),
    ({"sensors": {"yaw_rate_std_radps": 1e300}}, "yaw_rate_std_radps", sc.MAX_YAW_RATE_STD_RADPS),
    ({"sensors": {"gnss_rate_hz": 1e-300}}, "gnss_rate_hz", sc.MIN_SENSOR_RATE_HZ),
    ({"sensors": {"attitude_rate_hz": 1e-300}}, "attitude_rate_hz", sc.MIN_SENSOR_RATE_HZ),
    ({"sensors": {"gnss_dropout_rate_per_s": 1e300, "gnss_dropout_duration_s": 1e-9}},
     "gnss_dropout_rate_per_s", sc.MAX_DROPOUT_RATE_PER_S),
    ({"sensors": {"gnss_dropout_rate_per_s": 0.1, "gnss_dropout_duration_s": 1e300}},
     "gnss_dropout_duration_s", sc.MAX_DROPOUT_DURATION_S),
    ({"origin": {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 1e7}}, "alt_m", MAX_ALT_M),
    ({"origin": {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": -1e300}}, "alt_m", MIN_ALT_M),
])
def test_a_world_past_the_bounds_is_refused_naming_the_field_and_the_bound(changes, field,
                                                                           bound) -> None:
    with pytest.raises(ConfigError) as err:
        sc.parse_scenario(lake_with(**changes), "probe.toml")
    text = str(err.value)
    assert field in text and f"{bound:g}" in text and "probe.toml" in text, text


@pytest.mark.parametrize("vessel", VESSELS)
def test_at_the_bounds_the_plant_stays_finite_and_its_telemetry_packs(vessel: str) -> None:
    worst = lake_with(vessel=vessel, start={"x_m": sc.MAX_START_RANGE_M, "y_m": -sc.MAX_START_RANGE_M,
                                            "u_mps": sc.MAX_START_SPEED_MPS}, disturbances=[
        {"kind": "wind", "speed_mps": sc.MAX_WIND_MPS, "from_rad": 1.0,
         "drag_area_m2": sc.MAX_DRAG_AREA_M2, "gust_std_mps": sc.MAX_GUST_STD_MPS},
        {"kind": "current", "north_mps": sc.MAX_CURRENT_MPS, "east_mps": -sc.MAX_CURRENT_MPS},
        {"kind": "body_constant", "surge_n": sc.MAX_FORCE_N, "sway_n": -sc.MAX_FORCE_N,
         "yaw_nm": sc.MAX_MOMENT_NM},
        {"kind": "world_constant", "north_n": sc.MAX_FORCE_N, "east_n": sc.MAX_FORCE_N}])
    scenario = sc.parse_scenario(worst, "worst.toml")
    model = load_vessel(scenario.vessel)
    core = SimCore(scenario, model)
    ap = Px4Autopilot(Px4Config(thrust_max_n=model.thrust_max_n))
    mav = mavlink.MAVLink(None)
    fixes = 0
    for k in range(600):  # 60 s, the thrusters hard over one way
        core.advance((model.thrust_max_n, -model.thrust_max_n), 100_000_000)
        samples = core.take_samples()
        truth = core.truth()  # a message: refuses a non-finite field
        assert all(math.isfinite(v) for v in (truth.x_m, truth.y_m, truth.psi_rad, truth.u_mps)), k
        for msg in ap.sensor_telemetry(samples.gnss, samples.attitude, 0):
            msg.pack(mav)  # a field out of its MAVLink type raises here
        fixes += sum(f is not None for f in samples.gnss)
    assert fixes > 100


@pytest.mark.parametrize(("sensors", "alt_m"), [
    ({"gnss_std_m": sc.MAX_GNSS_STD_M, "sog_std_mps": sc.MAX_SOG_STD_MPS,
      "heading_std_rad": sc.MAX_HEADING_STD_RAD, "yaw_rate_std_radps": sc.MAX_YAW_RATE_STD_RADPS,
      "gnss_rate_hz": 100.0, "attitude_rate_hz": 250.0,
      "gnss_dropout_rate_per_s": sc.MAX_DROPOUT_RATE_PER_S, "gnss_dropout_duration_s": 1e-9},
     MAX_ALT_M),
    ({"gnss_rate_hz": sc.MIN_SENSOR_RATE_HZ, "attitude_rate_hz": sc.MIN_SENSOR_RATE_HZ,
      "gnss_dropout_rate_per_s": sc.MAX_DROPOUT_RATE_PER_S,
      "gnss_dropout_duration_s": sc.MAX_DROPOUT_DURATION_S}, MIN_ALT_M),
], ids=["noisiest-fastest", "slowest-longest-outages"])
def test_at_the_sensor_and_origin_bounds_the_sim_runs_and_its_telemetry_packs(sensors, alt_m) -> None:
    doc = lake_with(sensors=sensors, origin={"lat_deg": 28.18, "lon_deg": 112.94, "alt_m": alt_m})
    scenario = sc.parse_scenario(doc, "worst.toml")
    model = load_vessel(scenario.vessel)
    core = SimCore(scenario, model)
    ap = Px4Autopilot(Px4Config(thrust_max_n=model.thrust_max_n))
    mav = mavlink.MAVLink(None)
    for _ in range(300):  # 30 s
        core.advance((0.5 * model.thrust_max_n, 0.4 * model.thrust_max_n), 100_000_000)
        samples = core.take_samples()
        for msg in ap.sensor_telemetry(samples.gnss, samples.attitude, 0):
            msg.pack(mav)  # a field out of its MAVLink type raises here
