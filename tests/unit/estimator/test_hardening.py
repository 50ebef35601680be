"""Issue 14 in the estimator: absurd stamps (item 1) and the thrust the autopilot actually applies
(item 2), in the pure core and in the loop around it (in-memory bus, time passed in)."""

from __future__ import annotations

import logging
import time

import pytest
from seaway.contract.messages import ThrustCommand, VehicleStatus
from seaway.runtime.memory_bus import MemoryHub
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_estimator.node import EstimatorNode

from tests.unit.estimator.test_core import FIXED, MS, S, att, fix, started

WALL = 1_800_000_000 * S


def status(t_ns: int, withheld: str | None, armed: bool = True) -> VehicleStatus:
    return VehicleStatus(stamp_ns=t_ns, autopilot="px4", link_ok=withheld != "no_link",
                         armed=armed and withheld != "disarmed", mode="MANUAL",
                         thrust_withheld=withheld)  # type: ignore[arg-type]


def cmd(t_ns: int, thrust_n: float = 5.0) -> ThrustCommand:
    return ThrustCommand(stamp_ns=t_ns, thrust_port_n=thrust_n, thrust_starboard_n=thrust_n)


# -- item 1: absurd stamps ---------------------------------------------------------------------


@pytest.mark.timeout(20)
@pytest.mark.parametrize("ahead_ns", [2**62, 10**15, 31 * S])
def test_a_thrust_command_stamped_absurdly_ahead_is_refused_at_once(ahead_ns: int) -> None:
    """Before: ``on_thrust`` integrated the filter up to the stamp (10^4000 ns: for ever, inside the
    service's lock). Now a stamp more than ``max_gap_s`` ahead of the filter is refused, counted,
    and the filter stays where it was."""
    core = started()
    core.predict_to(1 * S)
    t0 = time.perf_counter()
    core.on_thrust(cmd(1 * S + ahead_ns))
    assert time.perf_counter() - t0 < 1.0
    assert core.counters["too_new"] == 1 and core.counters["thrust_received"] == 0
    assert core.filter is not None and core.filter.t_ns == 1 * S
    est = core.predict_to(1 * S + 100 * MS)
    assert est is not None and est.u_mps == pytest.approx(0.0, abs=1e-9)  # the command was not taken


def test_a_status_stamped_absurdly_ahead_is_refused_too() -> None:
    core = started()
    core.on_vehicle_status(status(2**62, "disarmed"))
    assert core.counters["too_new"] == 1 and core.thrust_withheld is None
    assert core.filter is not None and core.filter.t_ns == 0


def _loop() -> EstimatorNode:
    return EstimatorNode(EstimatorCore(FIXED))


def test_the_loop_drops_inputs_stamped_ahead_of_its_clock_before_the_core(caplog) -> None:
    """Real time: a command stamped +10 s of the wall clock would move the filter 10 s into the
    future (every later sample too old, nav/state stopped for 10 s). Dropped at the loop, counted,
    logged once."""
    caplog.set_level(logging.INFO, "seaway.estimator")
    loop = _loop()
    for k, msg in enumerate([cmd(WALL + 10 * S), cmd(WALL + 2**62), cmd(WALL + 11 * S)]):
        loop.queue("thrust", msg, lockstep=False, now_ns=WALL + k * MS)
    loop.queue("gnss", fix(WALL - 60 * S, 0.0, 0.0), lockstep=False, now_ns=WALL)  # older than 30 s
    loop.queue("thrust", cmd(WALL - 5 * MS), lockstep=False, now_ns=WALL)  # fine
    assert [p[3] for p in loop.pending] == ["thrust"] and loop.pending[0][0] == WALL - 5 * MS
    assert loop.stamps.dropped == {("ctrl/thrust", "ahead"): 3, ("sensors/gnss", "behind"): 1}
    warnings = [r for r in caplog.records if "dropped a message" in r.getMessage()]
    assert len(warnings) == 2  # once per key and direction


def test_inputs_queued_before_the_clock_stepped_back_are_dropped_not_fused_later() -> None:
    """Real time: a fix stamped half a second ahead waits for its time. The wall clock then steps an
    hour back (NTP or GPS time): kept, the fix would be fused as a current one an hour later, where
    the boat no longer is. Dropped at the next tick, counted as ahead; what is due stays."""
    from seaway.runtime.node import Outputs

    loop = _loop()
    loop.queue("gnss", fix(WALL + 500 * MS, 5.0, 5.0), lockstep=False, now_ns=WALL)
    loop.queue("attitude", att(WALL + 400 * MS, 0.0), lockstep=False, now_ns=WALL)
    assert len(loop.pending) == 2
    stepped = WALL - 3600 * S
    loop.queue("attitude", att(stepped - 10 * MS, 0.0), lockstep=False, now_ns=stepped)
    out = Outputs(MemoryHub().bus("vessel1"))
    loop.tick(stepped, out)
    assert loop.pending == []
    assert loop.stamps.dropped == {("sensors/gnss", "ahead"): 1, ("sensors/attitude", "ahead"): 1}
    loop.tick(WALL + 600 * MS, out)  # the clock comes round to the old stamps: nothing is fed
    assert loop.core.counters.values["gnss_accepted"] == 0


def test_lockstep_leftovers_too_far_ahead_are_dropped_at_the_period() -> None:
    """Lockstep: inputs queued before the member knew its period (at start) wait for their period;
    one stamped beyond any period to come soon would wait for ever (memory): dropped."""
    from seaway.contract.messages import PeriodDone
    from seaway.runtime.lockstep_member import Member
    from seaway.runtime.node import Period, PeriodAt

    hub = MemoryHub()
    loop = EstimatorNode(EstimatorCore(FIXED))
    member = Member(hub.bus("vessel1"), "estimator", watched=())
    loop.queue("gnss", fix(0, 0.0, 0.0))
    loop.queue("attitude", att(0, 0.0))
    loop.queue("attitude", att(50 * MS, 0.0))  # the next period's: waits
    loop.queue("gnss", fix(2**62, 0.0, 0.0))
    tick = PeriodDone(stamp_ns=0, service="sim", episode=0, seq=1, period_ns=100 * MS)
    loop.answer(PeriodAt(Period(0, 0), 100 * MS, {"sim": tick},
                         lambda suffix, stamp: member.admit(suffix, stamp, 0, 100 * MS)))
    assert [(p[0], p[3]) for p in loop.pending] == [(50 * MS, "attitude")]
    assert member.stamps.dropped == {("sensors/gnss", "ahead"): 1}


# -- item 2: the thrust the autopilot applies ----------------------------------------------------


def _surge_after_5_s(statuses: list[VehicleStatus]) -> float:
    core = started(EstimatorConfig(origin=FIXED.origin, thrust_timeout_s=100.0))
    core.on_thrust(cmd(0))
    for s in statuses:
        core.on_vehicle_status(s)
    est = core.predict_to(5 * S)
    assert est is not None
    return est.u_mps


@pytest.mark.parametrize("why", ["disarmed", "no_link", "mode", "autopilot_config"])
def test_withheld_thrust_is_predicted_as_zero(why: str) -> None:
    """An autopilot that rebooted comes back disarmed, the boat still: before, the filter
    dead-reckoned on the commanded 5 N a side (about 0.3 m/s here) and ran away from it."""
    assert _surge_after_5_s([]) > 0.25
    assert _surge_after_5_s([status(0, why)]) == pytest.approx(0.0, abs=1e-12)


def test_an_unhealthy_autopilot_still_applies_the_thrust() -> None:
    """'autopilot_unhealthy' keeps a new mission waiting, but what is commanded still drives the
    thrusters (issue 63): the filter predicts with it."""
    assert _surge_after_5_s([status(0, "autopilot_unhealthy")]) == pytest.approx(
        _surge_after_5_s([]), rel=1e-12)


def test_thrust_applies_again_from_the_status_that_says_so() -> None:
    # Withheld for the first 2 s, applied from then: the same as a command that starts at 2 s.
    withheld_then_applied = _surge_after_5_s([status(0, "disarmed"), status(2 * S, None)])
    core = started(EstimatorConfig(origin=FIXED.origin, thrust_timeout_s=100.0))
    core.predict_to(2 * S)
    core.on_thrust(cmd(2 * S))
    late_start = core.predict_to(5 * S).u_mps
    assert withheld_then_applied == pytest.approx(late_start, rel=1e-12)
    assert withheld_then_applied > 0.1


def test_the_loop_feeds_vehicle_status_in_real_time(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.estimator")
    loop = _loop()
    loop.queue("gnss", fix(WALL, 0.0, 0.0), lockstep=False, now_ns=WALL)
    loop.queue("attitude", att(WALL, 0.0), lockstep=False, now_ns=WALL)
    loop.queue("status", status(WALL, "disarmed"), lockstep=False, now_ns=WALL)
    loop.feed_pending(None)
    assert loop.core.thrust_withheld == "disarmed"
    assert any("withholds the thrust (disarmed): predicting with zero thrust" in r.getMessage()
               for r in caplog.records)


def _reboot_run(thrust_n: float) -> tuple[EstimatorCore, float]:
    """Thrust applied from 0 s; the autopilot stops it at 6 s and falls silent (rebooting), and is
    heard again, disarmed, at 10.5 s; fixes at 5 Hz of where the boat is. The truth is the model
    itself (a second core, predicting only, told of the stop at the moment it happened). Returns
    the core under test and its worst position error after the first fix back."""
    config = EstimatorConfig(origin=FIXED.origin, thrust_timeout_s=100.0)
    truth, core = started(config), started(config)
    truth.on_thrust(cmd(0, thrust_n))
    core.on_thrust(cmd(0, thrust_n))
    worst_m = 0.0
    for k in range(1, 101):  # 20 s
        t = k * 200 * MS
        if t == 6 * S:
            truth.on_vehicle_status(status(t, "disarmed"))
        if t == 10_400 * MS:
            core.on_vehicle_status(status(10_500 * MS, "disarmed"))
        real = truth.predict_to(t)
        if 6 * S < t < 10_600 * MS:
            continue  # the rebooting autopilot sends nothing
        core.on_gnss(fix(t, real.x_m, real.y_m, real.u_mps, real.v_mps))
        core.on_attitude(att(t, 0.0))
        if t >= 10_600 * MS:
            est = core.predict_to(t)
            worst_m = max(worst_m, ((est.x_m - real.x_m) ** 2 + (est.y_m - real.y_m) ** 2) ** 0.5)
    return core, worst_m


def test_a_reboot_that_stopped_the_thrust_unseen_is_no_motion_fault() -> None:
    """The thrust stopped when the autopilot rebooted, seconds before vehicle_io could say so: the
    filter dead-reckoned on commands the vessel never got, 2 m ahead of the boat. Before, the
    fixes back were gated out for 5 s, then the state jumped to them and the detector named a motion
    fault ('not_as_modelled') that paused the resumed mission. Now the first fix after the thrust is
    found withheld re-anchors the state and the detector starts afresh."""
    core, worst_m = _reboot_run(8.0)
    assert core.counters["withheld_anchored"] == 1
    assert core.mismatch.onsets == 0
    assert core.counters["gnss_rejected"] == 0
    assert worst_m < 0.3


def test_a_fault_raised_before_the_thrust_was_withheld_stays_raised() -> None:
    """The re-anchor starts a new window, but a raised fault is only cleared by the evidence."""
    core = started(EstimatorConfig(origin=FIXED.origin, thrust_timeout_s=100.0))
    core.on_thrust(cmd(0, 8.0))
    for k in range(1, 60):  # commanded on, fixes say still: not_moving
        core.on_gnss(fix(k * 200 * MS, 0.0, 0.0))
        core.on_attitude(att(k * 200 * MS, 0.0))
    assert core.mismatch.kind == "not_moving"
    core.on_vehicle_status(status(12 * S, "disarmed"))
    core.on_gnss(fix(12_200 * MS, 0.0, 0.0))
    assert core.mismatch.kind == "not_moving" and core.counters["withheld_anchored"] == 1
