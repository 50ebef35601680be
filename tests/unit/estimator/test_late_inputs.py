"""Measurements that come late (stamped before the filter's time: PX4 SITL's attitude arrives 0.1 to
0.17 s behind it, a telemetry radio's packets later still) are compared with the state back at
their stamp: the filter's now less the motion its prediction made since (``Prediction._back``),
not a first-order extrapolation at today's rates, which in a turn begun meanwhile is off by half
the yaw acceleration times the delay squared.

``data/trace_px4_sitl_lake.jsonl.gz``: the estimator's inputs of the ``sitl-px4`` profile's lake
mission on PX4 1.18 SITL's SIH rover (2026-12-07), in the order the recorder heard them, with a tick
at each estimate it published (``seaway_estimator.replay`` format). Replayed with the old settings
it gives what the live estimator logged: 13 headings rejected in the turns, a heading
re-initialised, degraded once.
"""

from __future__ import annotations

import gzip
from pathlib import Path

from seaway.contract.messages import ThrustCommand
from seaway_estimator.config import load_estimator_config
from seaway_estimator.core import EstimatorCore
from seaway_estimator.kalman import IPSI
from seaway_estimator.replay import decode_entry, replay

from tests.unit.estimator.test_core import MS, S, att, started

PX4_TRACE = Path(__file__).with_name("data") / "trace_px4_sitl_lake.jsonl.gz"


def test_a_late_time_gets_the_state_the_filter_predicted_for_it_in_a_turn() -> None:
    core = started()
    core.predict_to(1 * S)
    assert core.predict_to(1 * S - 50 * MS) is not None  # a late request: its motion is kept now
    core.on_thrust(ThrustCommand(stamp_ns=1 * S, thrust_port_n=-40.0, thrust_starboard_n=40.0))
    predicted = {}
    for k in range(1, 13):  # the turn begins: yaw rate from 0 upwards
        t = 1 * S + k * 50 * MS
        predicted[t] = core.predict_to(t)
    now = core.filter.t_ns
    assert abs(predicted[now].r_radps) > 0.05  # turning (to port), faster every step
    for back_ms in (100, 250, 400):
        t = now - back_ms * MS
        again = core.predict_to(t)
        assert abs(again.psi_rad - predicted[t].psi_rad) < 1e-9
        assert abs(again.r_radps - predicted[t].r_radps) < 1e-9
    # What the first-order extrapolation gave at 0.4 s: the heading the turn had not reached yet.
    f = core.filter
    first_order = f.z[IPSI] - predicted[now].r_radps * 0.4
    assert abs(first_order - predicted[now - 400 * MS].psi_rad) > 0.01


def test_the_motion_kept_for_late_inputs_is_bounded() -> None:
    """Only the last ``late_tolerance_s`` of motion is kept, however long late inputs come."""
    core = started()
    core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=10.0, thrust_starboard_n=12.0))
    for k in range(2, 2402):  # two minutes at 20 Hz, every heading 80 ms late
        t = k * 50 * MS
        core.predict_to(t)
        core.on_attitude(att(t - 80 * MS, core.filter.z[IPSI]))
        if k % 40 == 0:
            core.on_thrust(ThrustCommand(stamp_ns=t, thrust_port_n=10.0, thrust_starboard_n=12.0))
    moved = core.filter.moved
    assert moved is not None and core.counters["late_applied"] >= 2400
    span_s = (moved[-1][0] - moved[0][0]) / S
    assert span_s <= core.config.late_tolerance_s + 0.1 and len(moved) <= 40


def test_px4_sitl_headings_in_the_lake_missions_turns_are_all_taken() -> None:
    """The rover turns several times faster than its identified model; with the yaw acceleration's
    process noise of ``config/px4-sitl.toml`` the filter follows PX4's heading through every turn
    (at 0.5, as before: 10 rejected, degraded once)."""
    with gzip.open(PX4_TRACE, "rt", encoding="utf-8") as f:
        entries = [decode_entry(line) for line in f if line.strip()]
    config = load_estimator_config("px4-sitl").model_copy(update={"vessel": "px4-sitl-rover"})
    core = EstimatorCore(config)
    outputs = replay(entries, core=core)
    c = core.counters
    assert len(outputs) > 700 and c["late_applied"] > 500  # late inputs, as PX4 SITL sends them
    assert c["heading_accepted"] > 350 and c["gnss_accepted"] > 150
    assert (c["heading_rejected"], c["heading_reinit"], c["yaw_rate_rejected"]) == (0, 0, 0)
    assert c["degraded_entered"] == 0
