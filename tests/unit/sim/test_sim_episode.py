"""A scenario load in lockstep replies once the stack is in the new episode: every member has
answered its first period. A request sent after the reply (a mission) then cannot reach the
controller while it still holds the old episode's last period. The sim's real loop and a member of
the runtime's own lockstep protocol, on the in-memory bus."""

from __future__ import annotations

import threading
import time

from seaway.contract import keys
from seaway.contract.messages import ScenarioRequest, ThrustCommand
from seaway.runtime import lockstep_clock as sim_lockstep
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_clock import LockstepClock
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryHub
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode

from tests.conftest import wait_for

VESSEL = "vessel1"


class Slow:
    """A lockstep member on a thread of its own, answering ``delay`` after it could (set: at once)."""

    def __init__(self, hub: MemoryHub, service: str, stop: threading.Event,
                 delay: threading.Event, hears: tuple[str, ...] | None = None) -> None:
        self.member = Member(hub.bus(VESSEL), service, watched=set(), hears=hears)
        self.stop, self.delay = stop, delay
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()
        self.member.join()

    def _loop(self) -> None:
        raise NotImplementedError

    def halt(self) -> None:
        """Stop answering (hung, or being restarted by the launcher)."""
        self.stop = threading.Event()
        self.stop.set()
        self.thread.join(5.0)
        assert not self.thread.is_alive()


class SlowMember(Slow):
    """A controller that answers each new period of the sim ``delay`` after it heard it: with hold,
    or (``flying``) with a thrust command, so the sim moves on at once."""

    def __init__(self, hub: MemoryHub, stop: threading.Event, delay: threading.Event,
                 flying: bool = False) -> None:
        self.answered: list[Period] = []
        self.flying = flying
        super().__init__(hub, "controller", stop, delay, hears=("sim",))

    def _loop(self) -> None:
        version, last = 0, None
        while not self.stop.is_set():
            version = self.member.wait(version, 0.05)
            with self.member.changed:
                tick = self.member.ledger.answer("sim")
            if tick is None or Period.of(tick) == last:
                continue
            self.delay.wait(0.3)  # a busy controller: set, it answers at once
            last = Period.of(tick)
            self.answered.append(last)  # before the answer: the sim may act on it at once
            if self.flying:
                cmd = ThrustCommand.make(stamp_ns=last.stamp_ns, thrust_port_n=5.0,
                                         thrust_starboard_n=5.0)
                self.member.answer(last, tick.period_ns, [(keys.THRUST, cmd)])
            else:
                self.member.answer(last, tick.period_ns, hold=True)


class SlowRecorder(Slow):
    """A recorder that answers each period ``delay`` after every member had, covering their answers
    (as the real one does once they are on disk)."""

    def __init__(self, hub: MemoryHub, stop: threading.Event, delay: threading.Event) -> None:
        super().__init__(hub, "recorder", stop, delay)

    def _loop(self) -> None:
        version, covered = 0, None
        while not self.stop.is_set():
            version = self.member.wait(version, 0.05)
            with self.member.changed:
                ledger = self.member.ledger
                tick, ctrl = ledger.answer("sim"), ledger.answer("controller")
            if tick is None or ctrl is None:
                continue
            covers = {"sim": tick.seq, "controller": ctrl.seq}
            if covers == covered:
                continue
            self.delay.wait(0.3)  # a slow disk: set, it answers at once
            covered = covers
            self.member.answer(Period.of(tick), tick.period_ns, covers=covers)


class Stack:
    """The sim's lockstep loop and a ``SlowMember``, past their first period (answered at once);
    with ``recorder``, a ``SlowRecorder`` too."""

    def __init__(self, flying: bool = False, recorder: bool = False,
                 until_s: float | None = None) -> None:
        self.hub = MemoryHub()
        self.scenario = load_scenario("paper-c1")
        app = SimNode(SimCore(self.scenario, load_vessel(self.scenario.vessel)),
                     lockstep=True)
        app.until_s = until_s
        self.app = app
        self.stop, self.fast = threading.Event(), threading.Event()
        bus = self.hub.bus(VESSEL)
        bus.queryable(keys.SIM_SCENARIO, app.handle_scenario)  # run_node's, for the sim's node
        sim = LockstepClock(bus, app, 0.1, self.stop)
        self.member = SlowMember(self.hub, self.stop, self.fast, flying)
        self.recorder = SlowRecorder(self.hub, self.stop, self.fast) if recorder else None
        # Joined in close(): a loop left running logs after the test, into pytest's closed capture.
        self.sim_thread = threading.Thread(target=sim.run, daemon=True)
        self.sim_thread.start()
        self.fast.set()
        wait_for(lambda: Period(0, 0) in self.member.answered, 10, what="the first period answered")

    def restart(self):
        return self.hub.bus(VESSEL).request(
            keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="restart"), timeout_s=10.0)

    def close(self) -> None:
        self.stop.set()
        self.fast.set()
        self.sim_thread.join(10.0)
        assert not self.sim_thread.is_alive(), "the sim's lockstep loop did not stop"


def test_a_scenario_restart_replies_once_every_member_answered_the_new_episode() -> None:
    stack = Stack()
    try:
        stack.fast.clear()  # from now on the member takes 0.3 s to answer
        reply = stack.restart()
        assert reply.accepted, reply.reason
        # At the reply, the member has answered the new episode's first period (it held the old
        # one's t_0 until then: nothing to fly).
        assert stack.member.answered[-1] == Period(1, 0), stack.member.answered
        assert reply.reason == f"scenario {stack.scenario.name} restarted"
    finally:
        stack.close()


def test_a_member_that_does_not_answer_delays_the_reply_only_so_long(monkeypatch) -> None:
    monkeypatch.setattr(sim_lockstep, "EPISODE_WAIT_S", 0.5)
    stack = Stack()
    try:
        stack.member.halt()
        reply = stack.restart()
        assert reply.accepted, reply.reason
        assert reply.reason.endswith("its first period not yet answered by controller"), reply.reason
    finally:
        stack.close()


def test_a_restart_while_flying_replies_once_the_new_episode_is_answered(monkeypatch) -> None:
    """A member with a mission answers the new episode's first period with a command, and the sim is
    periods further on by the time the waiting request looks: answering any period of the new
    episode counts (only each member's latest answer is kept)."""
    monkeypatch.setattr(sim_lockstep, "EPISODE_WAIT_S", 3.0)
    stack = Stack(flying=True)
    try:
        wait_for(lambda: len(stack.member.answered) > 20, 10, what="periods flown")
        for episode in (1, 2, 3):
            reply = stack.restart()
            assert reply.accepted, reply.reason
            # Not "its first period not yet answered by controller" after the whole wait.
            assert reply.reason == f"scenario {stack.scenario.name} restarted", reply.reason
            assert Period(episode, 0) in stack.member.answered
    finally:
        stack.close()


def test_a_restart_starts_the_new_episode_once_the_recorder_covers_the_old_ones_end() -> None:
    """The old episode's last period is finished (every member answered, the recorder covering
    them) before the new episode's first is published: the recorder logs each message in the time
    of the episode it was heard in, and the controller's last status of the old episode, heard after
    the new one began, was logged in the new one's time (where it ended the next mission)."""
    stack = Stack(recorder=True)
    heard: list[tuple[str, Period, dict[str, int]]] = []
    observer = stack.hub.bus(VESSEL)
    for service in ("sim", "recorder"):
        observer.subscribe(keys.lockstep_spec(service), inline=True, callback=lambda _k, a: heard.append(
            (a.service, Period.of(a), dict(a.covers))))
    try:
        stack.fast.clear()  # from now on the member and the recorder take 0.3 s to answer
        # The reply comes once the controller answered episode 1's t_0 (hold), not the recorder:
        # a second restart at once finds that answer not yet covered.
        assert stack.restart().accepted
        held = stack.member.member.last_answer
        assert held is not None and Period.of(held) == Period(1, 0)
        reply = stack.restart()
        assert reply.accepted, reply.reason
        assert reply.reason == f"scenario {stack.scenario.name} restarted", reply.reason
        new = next(i for i, (s, p, _) in enumerate(heard) if s == "sim" and p.episode == 2)
        assert any(s == "recorder" and c.get("controller") == held.seq for s, _, c in heard[:new]), (
            "episode 2 began before the recorder covered episode 1's last answer", heard)
    finally:
        stack.close()


def test_a_recorder_that_does_not_cover_the_old_episode_delays_the_new_one_only_so_long(
        monkeypatch) -> None:
    """A dead recorder (the launcher restarts it) holds a load back half of ``EPISODE_WAIT_S``;
    the reply then says what was not finished."""
    monkeypatch.setattr(sim_lockstep, "EPISODE_WAIT_S", 0.6)
    stack = Stack(recorder=True)
    try:
        recorder = stack.recorder
        assert recorder is not None
        wait_for(lambda: (a := recorder.member.last_answer) is not None and a.covers.get(
            "controller") == stack.member.member.last_answer.seq, 10, what="t_0 covered")
        recorder.halt()
        first = stack.restart()  # t_0 was covered: at once; episode 1's t_0 is then never covered
        assert first.reason == f"scenario {stack.scenario.name} restarted", first.reason
        reply = stack.restart()
        assert reply.accepted, reply.reason
        assert reply.reason.endswith("the last episode's last period was not finished (no answer "
                                     "from recorder)"), reply.reason
        wait_for(lambda: Period(2, 0) in stack.member.answered, 10, what="episode 2 started")
    finally:
        stack.close()


def test_the_sim_runs_one_period_ahead_of_the_recorder_and_no_more() -> None:
    """``RECORDER_LAG``: the sim publishes t_{k+1} once the recorder has answered t_{k-1}, so the
    recorder's writing overlaps the next period; a recorder that stops answering stops the sim two
    periods after the last one it answered (the members keep one bundle more for its successor)."""
    stack = Stack(flying=True, recorder=True)
    try:
        recorder = stack.recorder
        assert recorder is not None
        wait_for(lambda: len(stack.member.answered) > 10, 10, what="periods flown")
        recorder.halt()
        last = recorder.member.last_answer
        assert last is not None
        time_before = len(stack.member.answered)
        wait_for(lambda: stack.member.answered[-1].stamp_ns >= last.stamp_ns + 2 * 100_000_000, 10,
                 what="the sim two periods past the recorder's last answer")
        threading.Event().wait(0.5)  # and no further
        assert stack.member.answered[-1] == Period(0, last.stamp_ns + 2 * 100_000_000), (
            last, stack.member.answered[time_before - 1:])
    finally:
        stack.close()


def test_a_time_limit_holds_the_clock_at_the_last_period_before_it() -> None:
    """``--until-s 1.05`` with a period of 0.1 s: the world flies to t = 1.0 s and holds there, the
    clock's answer for 1.0 s the last; a new episode flies to the limit again."""
    stack = Stack(flying=True, recorder=True, until_s=1.05)
    try:
        last = Period(0, 1_000_000_000)
        wait_for(lambda: last in stack.member.answered, 10, what="t = 1.0 s answered")
        time.sleep(0.5)  # room for a period too many (each is answered at once)
        assert stack.member.answered[-1] == last
        assert stack.app.time_ns() == last.stamp_ns
        reply = stack.restart()
        assert reply.accepted, reply.reason
        wait_for(lambda: Period(1, last.stamp_ns) in stack.member.answered, 10,
                 what="the new episode's t = 1.0 s answered")
        time.sleep(0.5)
        assert stack.member.answered[-1] == Period(1, last.stamp_ns)
    finally:
        stack.close()
