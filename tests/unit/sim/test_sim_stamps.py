"""Issue 14, item 1, in the lockstep sim: what a command's stamp can make the sim keep is bounded.
A command stamped beyond the next periods is dropped (counted, logged once); nothing the sim keeps
grows with the number of commands. In memory, no step taken."""

from __future__ import annotations

import threading

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.runtime.lockstep_clock import LockstepClock
from seaway.runtime.memory_bus import MemoryHub
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode

PERIOD_NS = 100_000_000


def lockstep() -> LockstepClock:
    sc = load_scenario("paper-c1")
    app = SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=True)
    return LockstepClock(MemoryHub().bus("vessel1"), app, PERIOD_NS / 1e9, threading.Event())


def cmd(stamp_ns: int) -> ThrustCommand:
    return ThrustCommand(stamp_ns=stamp_ns, thrust_port_n=1.0, thrust_starboard_n=1.0)


def test_commands_stamped_beyond_the_next_periods_are_dropped() -> None:
    ls = lockstep()
    key = keys.THRUST.key("vessel1")
    ls._on_thrust(key, cmd(0))
    ls._on_thrust(key, cmd(10 * 10**9))  # +10 s
    ls._on_thrust(key, cmd(2**62))
    assert set(ls._commands) == {0}
    assert ls.member.stamps.dropped == {(keys.THRUST.suffix, "ahead"): 2}


def test_nothing_kept_grows_with_the_commands() -> None:
    ls = lockstep()
    key = keys.THRUST.key("vessel1")
    for k in range(5000):
        ls.app.core.t_ns = k * PERIOD_NS  # as if the sim had stepped to t_k
        ls._on_thrust(key, cmd(k * PERIOD_NS))
    assert len(ls._commands) <= 64
    assert sum(len(s) for s in ls.member.ledger.seen.values()) == 0  # it noted 5000 before


def test_the_lockstep_sim_applies_vehicle_ios_output_stage_to_the_demand() -> None:
    """The lockstep sim takes the controller's demand where vehicle I/O would: on the lake's boat
    (10 N dead zone) 6 N is applied as 10 N and 4 N as 0, as vehicle I/O sends them; applying the
    raw demand would lose both to the dead zone (NMPC parked 3 m from a waypoint that way)."""
    sc = load_scenario("lake")
    assert sc.dead_zone
    app = SimNode(SimCore(sc, load_vessel(sc.plant_vessel_file)),
                 lockstep=True)
    ls = LockstepClock(MemoryHub().bus("vessel1"), app, PERIOD_NS / 1e9, threading.Event())
    period = ls.period
    assert ls.step(ThrustCommand(stamp_ns=period.stamp_ns, thrust_port_n=6.0, thrust_starboard_n=4.0),
                   period)
    truth = app.core.truth()
    assert (truth.thrust_port_n, truth.thrust_starboard_n) == (10.0, 0.0)


def test_the_lockstep_sim_refuses_an_absurd_demand_as_vehicle_io_does(caplog) -> None:
    """Issue 56, item 5: 1e9 N is not saturated to full power in vehicle I/O's place; the period
    gets neutral, and the refusal is counted and logged. Twice the bound is still saturated."""
    sc = load_scenario("lake")
    vessel = load_vessel(sc.plant_vessel_file)
    app = SimNode(SimCore(sc, vessel), lockstep=True)
    ls = LockstepClock(MemoryHub().bus("vessel1"), app, PERIOD_NS / 1e9, threading.Event())
    period = ls.period
    with caplog.at_level("WARNING", logger="seaway_sim"):
        assert ls.step(ThrustCommand(stamp_ns=period.stamp_ns, thrust_port_n=1e9,
                                     thrust_starboard_n=1e9), period)
    truth = app.core.truth()
    assert (truth.thrust_port_n, truth.thrust_starboard_n) == (0.0, 0.0)
    assert app.refused_commands == 1
    assert any("absurd" in r.getMessage() for r in caplog.records)
    period = ls.period
    assert ls.step(ThrustCommand(stamp_ns=period.stamp_ns, thrust_port_n=2 * vessel.thrust_max_n,
                                 thrust_starboard_n=0.0), period)
    assert app.core.truth().thrust_port_n == vessel.thrust_max_n
    assert app.refused_commands == 1


def test_a_recorder_answer_for_a_period_not_yet_published_records_nothing(caplog) -> None:
    """A recorder answer stamped far after the sim's period (the int64 end) would count as
    "recorded" for every period of the episode, and a recorder dying after it would leave the sim
    running unrecorded: the sim refuses it, naming why, and waits for a real answer."""
    from seaway.runtime.lockstep import Period
    from seaway.runtime.lockstep_member import Member

    hub = MemoryHub()
    sc = load_scenario("paper-c1")
    app = SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=True)
    ls = LockstepClock(hub.bus("vessel1"), app, PERIOD_NS / 1e9, threading.Event())
    ls.members = {"recorder"}
    period = ls.publish_period()
    rec = Member(hub.bus("vessel1"), "recorder", watched=(), subscribe=False)
    covers = {"sim": ls.member.last_answer.seq}
    rec.answer(Period(period.episode, 2**63 - 1), PERIOD_NS, covers=covers)
    ls.member.drain()
    with ls.member.changed:
        assert not ls.answered(period)
    assert ls.member.refused == {"ahead": 1}
    assert "refused (ahead: recorder's answer for t = about 10^9 s" in caplog.text
    rec.answer(period, PERIOD_NS, covers=covers)
    ls.member.drain()
    with ls.member.changed:
        assert ls.answered(period)
