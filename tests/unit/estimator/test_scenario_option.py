"""``seaway-estimator --scenario``: the simulator's vessel, dead zone and origin, nothing else."""

from seaway.scenario import load_scenario
from seaway_estimator.config import load_estimator_config
from seaway_estimator.service import with_scenario


def test_scenario_sets_vessel_dead_zone_and_origin_only() -> None:
    base = load_estimator_config(None)
    cfg = with_scenario(base, load_scenario("lake"))
    assert (cfg.vessel, cfg.apply_dead_zone) == ("paper-boat", True)
    assert cfg.origin is not None and (cfg.origin.lat_deg, cfg.origin.lon_deg) == (28.18, 112.94)
    assert cfg.gnss_std_m == base.gnss_std_m and cfg.publish_rate_hz == base.publish_rate_hz
    paper = with_scenario(base, load_scenario("paper-c1"))
    assert (paper.vessel, paper.apply_dead_zone) == ("paper-sim", False)
