"""``seaway-estimator --scenario``: the simulator's vessel, dead zone and origin, nothing else."""

from seaway.simkit.scenario import load_scenario
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


def test_a_repeated_sample_is_used_once() -> None:
    from seaway.contract.messages import Attitude
    from seaway_estimator.core import EstimatorCore
    from seaway_estimator.service import EstimatorLoop

    class _Pub:
        def put(self, msg) -> None:  # the loop's outputs are not under test here
            pass

    class _Bus:
        def publisher(self, spec):
            return _Pub()

    loop = EstimatorLoop(EstimatorCore(load_estimator_config(None)), _Bus())
    att = Attitude(stamp_ns=0, roll_rad=0, pitch_rad=0, yaw_rad=0.1, roll_rate_radps=0,
                   pitch_rate_radps=0, yaw_rate_radps=0)
    loop.queue("attitude", att)
    loop.queue("attitude", att)  # the lockstep sim republished its held period
    loop.queue("attitude", att.model_copy(update={"stamp_ns": 50_000_000}))
    assert loop.repeats == 1
    assert [p[0] for p in loop.pending] == [0, 50_000_000]
