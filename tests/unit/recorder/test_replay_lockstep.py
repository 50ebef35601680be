"""``seaway replay --lockstep``'s pacer on the in-memory bus: a recorded period is held until every
live member has answered it, as the sim holds its own (``seaway.runtime.lockstep_replay``).

Members here are scripted: each answers the sim's tick from inside its delivery (the in-memory bus
delivers synchronously), the recorder covering the others' latest answers.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import PeriodDone
from seaway.recording.reader import RecordingInfo
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Ledger, Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.lockstep_replay import LockstepPacer
from seaway.runtime.memory_bus import MemoryHub
from seaway_recorder.replay import KeyFilter, lockstep_vessel

V = "v1"
P_NS = 100_000_000


def recorded_tick(stamp_ns: int, seq: int = 7) -> PeriodDone:
    """A sim answer as a recording holds it: naming the recorded run's members, not ours."""
    return PeriodDone(stamp_ns=stamp_ns, service="sim", episode=0, seq=seq, period_ns=P_NS,
                      members=["estimator"])


class Scripted:
    """Members on their own buses; ``reply(service, tick) -> hold or None (no answer)``."""

    def __init__(self, hub: MemoryHub, services: tuple[str, ...],
                 reply: Callable[[str, PeriodDone], bool | None] = lambda _s, _t: False) -> None:
        self.ticks: list[PeriodDone] = []
        self.reply = reply
        self.members = {s: Member(hub.bus(V), s, watched=(), subscribe=False) for s in services}
        self.latest: dict[str, int] = {}
        hub.bus(V).subscribe(keys.lockstep_spec("sim"), callback=self.on_tick)
        for member in self.members.values():
            member.join()

    def on_tick(self, _key: str, tick: PeriodDone) -> None:
        self.ticks.append(tick)
        for service, member in self.members.items():
            if service == "recorder":
                continue
            hold = self.reply(service, tick)
            if hold is not None:
                self.latest[service] = member.answer(Period.of(tick), P_NS, hold=hold).seq
        if "recorder" in self.members:
            covers = {"sim": tick.seq, **self.latest}
            self.members["recorder"].answer(Period.of(tick), P_NS, covers=covers)


def pacer_on(hub: MemoryHub, stall_s: float = 30.0) -> tuple[LockstepPacer, threading.Event, Bus]:
    stop = threading.Event()
    bus = hub.bus(V)
    return LockstepPacer(bus, stop, stall_s=stall_s), stop, bus


def test_a_period_is_played_once_every_live_member_answered_and_names_them() -> None:
    hub = MemoryHub()
    members = Scripted(hub, ("estimator", "controller", "recorder"))
    pacer, _stop, _bus = pacer_on(hub)
    sent: list[str] = []
    assert pacer.play(recorded_tick(0), lambda: sent.append("samples"))
    assert sent == ["samples"]
    assert len(members.ticks) == 1
    assert members.ticks[0].members == ["controller", "estimator", "recorder"]  # live, not recorded
    assert pacer.periods == 1 and pacer.repeats == 0


def test_the_recorder_must_cover_every_latest_answer() -> None:
    ledger = Ledger(watched=(), consumed=False)
    tick = recorded_tick(0, seq=7)
    ledger.on_answer(tick)
    period = Period.of(tick)
    members = ("estimator", "controller", "recorder")
    ledger.on_answer(PeriodDone(stamp_ns=0, service="estimator", episode=0, seq=11, period_ns=P_NS))
    ledger.on_answer(PeriodDone(stamp_ns=0, service="controller", episode=0, seq=21, period_ns=P_NS))
    assert not ledger.all_answered(period, members, tick.seq)  # no recorder answer yet
    for covers, done in (({"sim": 7, "estimator": 11}, False),  # the controller's not covered
                         ({"sim": 7, "estimator": 11, "controller": 20}, False),  # an older one
                         ({"sim": 6, "estimator": 11, "controller": 21}, False),  # an older tick
                         ({"sim": 7, "estimator": 11, "controller": 21}, True)):
        ledger.on_answer(PeriodDone(stamp_ns=0, service="recorder", episode=0, seq=31,
                                    period_ns=P_NS, covers=covers))
        assert ledger.all_answered(period, members, tick.seq) is done, covers
    assert ledger.all_answered(period, ("estimator", "controller"), tick.seq)  # no recorder


def test_a_period_nobody_completes_is_sent_again_after_the_stall_time() -> None:
    hub = MemoryHub()
    calls = {"n": 0}

    def reply(service: str, _tick: PeriodDone) -> bool | None:
        if service == "controller":  # silent the first time (a message lost, say)
            calls["n"] += 1
            return None if calls["n"] == 1 else False
        return False

    members = Scripted(hub, ("estimator", "recorder", "controller"), reply)
    ticks = itertools.count(0.0, 1.0)  # the stall clock [s]: one second per look
    pacer = LockstepPacer(hub.bus(V), threading.Event(), stall_s=2.0, clock=lambda: next(ticks))
    sent: list[str] = []
    assert pacer.play(recorded_tick(0), lambda: sent.append("samples"))
    assert pacer.repeats == 1 and len(members.ticks) == 2 and sent == ["samples", "samples"]


def test_a_controller_hold_is_waited_past_unless_the_hold_ends_the_recording() -> None:
    hub = MemoryHub()
    members = Scripted(hub, ("estimator", "controller"), lambda s, _t: s == "controller")
    pacer, stop, _bus = pacer_on(hub)
    # The mission's end: the recording ends (or repeats this period), so the hold is an answer.
    assert pacer.play(recorded_tick(0), lambda: None, hold_ends=True)
    # No mission yet: the pacer holds until the controller answers with a command.
    controller = members.members["controller"]
    timer = threading.Timer(0.2, lambda: controller.answer(Period(0, P_NS), P_NS))
    timer.start()
    try:
        assert pacer.play(recorded_tick(P_NS), lambda: None)
    finally:
        timer.cancel()
    assert pacer.holds == 1 and pacer.repeats == 0
    # Stopped while held: play says so.
    stop.set()
    assert not pacer.play(recorded_tick(2 * P_NS), lambda: None)


def test_a_controller_that_holds_after_flying_ends_its_mission_and_the_replay_goes_on() -> None:
    """A live controller whose mission ends before the recorded one (another controller, or a
    replay that diverged) holds mid-recording: that is its answer, not a wait without end; in a new
    episode a hold is again a controller waiting for its mission."""
    hub = MemoryHub()
    flying = {"on": True}
    Scripted(hub, ("estimator", "controller"),
             lambda s, _t: s == "controller" and not flying["on"])
    pacer, stop, _bus = pacer_on(hub)
    assert pacer.play(recorded_tick(0), lambda: None)
    assert not pacer.ended_early
    flying["on"] = False  # the mission is complete: every answer from now on is a hold
    assert pacer.play(recorded_tick(P_NS), lambda: None)
    assert pacer.play(recorded_tick(2 * P_NS), lambda: None)
    assert pacer.ended_early and pacer.periods == 3 and pacer.holds == 0
    # A new episode (a scenario load): its first hold waits for a mission, until stopped.
    new_episode = PeriodDone(stamp_ns=0, service="sim", episode=1, seq=8, period_ns=P_NS,
                             members=["estimator"])
    timer = threading.Timer(0.3, stop.set)
    timer.start()
    try:
        assert not pacer.play(new_episode, lambda: None)
    finally:
        timer.cancel()
    assert pacer.holds == 1


def test_a_member_that_joins_gets_the_period_again_and_is_waited_for() -> None:
    hub = MemoryHub()
    members = Scripted(hub, ("estimator",))
    pacer, _stop, _bus = pacer_on(hub)
    assert pacer.play(recorded_tick(0), lambda: None)
    late = Member(hub.bus(V), "controller", watched=(), subscribe=False)
    answered: list[int] = []

    def on_tick(_key: str, tick: PeriodDone) -> None:
        if "controller" in tick.members:
            answered.append(late.answer(Period.of(tick), P_NS).stamp_ns)
        elif tick.stamp_ns == P_NS:
            late.join()  # the controller joins while period 1 is out without it

    hub.bus(V).subscribe(keys.lockstep_spec("sim"), callback=on_tick)
    samples: list[int] = []
    assert pacer.play(recorded_tick(P_NS), lambda: samples.append(1))
    assert pacer.repeats == 1 and len(samples) == 2  # the period's samples went out again
    assert answered == [P_NS]
    assert [t.members for t in members.ticks[-2:]] == [["estimator"], ["controller", "estimator"]]


def test_an_answer_on_another_members_key_is_not_counted() -> None:
    hub = MemoryHub()
    pacer, _stop, _bus = pacer_on(hub)
    impostor = hub.bus(V).publisher(keys.lockstep_spec("estimator"))
    impostor.put(PeriodDone(stamp_ns=0, service="controller", episode=0, seq=1, period_ns=P_NS))
    assert pacer.ledger.answers == {}


def test_the_lockstep_replay_needs_one_vessels_kept_sim_answers() -> None:
    def info(*topics: str) -> RecordingInfo:
        return RecordingInfo(files=[Path("x.mcap")], topics=dict.fromkeys(topics, 1))

    assert lockstep_vessel(info("seaway/a/lockstep/sim", "seaway/a/nav/state"), KeyFilter()) == "a"
    with pytest.raises(ValueError, match="not made in lockstep"):
        lockstep_vessel(info("seaway/a/nav/state"), KeyFilter())
    with pytest.raises(ValueError, match="leave them out"):
        lockstep_vessel(info("seaway/a/lockstep/sim"), KeyFilter(exclude=["lockstep/sim"]))
    fleet = info("seaway/a/lockstep/sim", "seaway/b/lockstep/sim")
    with pytest.raises(ValueError, match="a, b: keep one"):
        lockstep_vessel(fleet, KeyFilter())
    assert lockstep_vessel(fleet, KeyFilter(only=["seaway/b/**"])) == "b"
