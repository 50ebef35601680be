"""The estimator loop drops a sample the lockstep simulator republished."""

from seaway_estimator.config import load_estimator_config


def test_a_repeated_sample_is_used_once() -> None:
    from seaway.contract.messages import Attitude
    from seaway_estimator.core import EstimatorCore
    from seaway_estimator.node import EstimatorNode

    loop = EstimatorNode(EstimatorCore(load_estimator_config(None)))
    att = Attitude(stamp_ns=0, roll_rad=0, pitch_rad=0, yaw_rad=0.1, roll_rate_radps=0,
                   pitch_rate_radps=0, yaw_rate_radps=0)
    loop.queue("attitude", att)
    loop.queue("attitude", att)  # the lockstep sim republished its held period
    loop.queue("attitude", att.model_copy(update={"stamp_ns": 50_000_000}))
    assert loop.repeats == 1
    assert [p[0] for p in loop.pending] == [0, 50_000_000]
