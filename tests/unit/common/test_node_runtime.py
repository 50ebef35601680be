"""The node runtime's drivers (``seaway.runtime.node``) on the in-memory bus: a lockstep member's
answers (once a period, after its inputs, again when a held period is rethought, afresh on a new
episode) and a paced real-time node's ticks. Pure logic, no network."""

from __future__ import annotations

import threading
import time
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import GnssFix, PeriodDone, StateEstimate
from seaway.runtime.clock import WallClock
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryHub
from seaway.runtime.node import Answer, LiveDriver, MemberDriver, MemberSpec, Node, Period, PeriodAt
from seaway.runtime.run import RunDescription
from seaway.runtime.service import ServiceContext

from tests.conftest import wait_for

P = 100_000_000
V = "vessel1"


def fix(stamp_ns: int) -> GnssFix:
    return GnssFix(stamp_ns=stamp_ns, lat_rad=0.5, lon_rad=0.1, alt_m=0.0, fix_type=3,
                   horizontal_std_m=0.3)


class Estimating(Node):
    """A member that needs the sim's answer and its GNSS fixes: it answers with a state at t_k
    whose x is the number of fixes taken so far, or holds until told to fly."""

    name = "estimator"
    member = MemberSpec("estimator", needs=("sim",), inputs=frozenset({keys.GNSS.suffix}),
                        hears=("sim",))

    def __init__(self) -> None:
        self.fixes: list[int] = []
        self.answers: list[tuple[Period, int]] = []
        self.restarts: list[Period] = []
        self.fly = True
        self.driver: Any = None

    def attach(self, driver: Any) -> None:
        self.driver = driver

    def take(self, key: str, msg: Any, now_ns: int | None) -> None:
        assert key.endswith(keys.GNSS.suffix) and now_ns is None
        self.fixes.append(msg.stamp_ns)

    def restart(self, period: Period) -> None:
        """What is stamped after the new t_k is a late input of the old episode; the rest stays:
        a bundle's inputs come before its answer, which is what tells of the new episode."""
        self.restarts.append(period)
        self.fixes = [t for t in self.fixes if t <= period.stamp_ns]

    def answer(self, at: PeriodAt) -> Answer:
        self.answers.append((at.period, len(self.fixes)))
        if not self.fly:
            return Answer(hold=True)
        return Answer([(keys.NAV_STATE, StateEstimate.make(
            stamp_ns=at.period.stamp_ns, u_mps=0.0, v_mps=0.0, r_radps=0.0,
            x_m=float(len(self.fixes)), y_m=0.0, psi_rad=0.0))])


def stack() -> tuple[Estimating, MemberDriver, Member, Member]:
    """The node under its driver, a sim that answers periods, and a listener to the node's bundles."""
    hub = MemoryHub()
    node = Estimating()
    driver = MemberDriver(hub.bus(V), node)
    node.attach(driver)
    driver.answer_on_arrival()  # what ``run`` does once the node is ready
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    listener = Member(hub.bus(V), "controller", watched={keys.NAV_STATE.suffix},
                      inputs={keys.NAV_STATE.suffix}, hears=("sim", "estimator"))
    listener.deliver = lambda _key, msg: listener.saw(keys.NAV_STATE.suffix, msg.stamp_ns)
    return node, driver, sim, listener


def test_a_member_answers_each_period_once_after_the_inputs_its_needs_list() -> None:
    node, _driver, sim, listener = stack()
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])
    sim.answer(Period(0, P), P, [(keys.GNSS, fix(P))])
    sim.repeat()  # a newcomer: the same period again, answered already
    assert node.answers == [(Period(0, 0), 1), (Period(0, P), 2)]  # the repeat: answered already
    assert node.fixes == [0, P, P]  # a repeat's messages come again (the node knows their stamp)
    state = listener.ledger.answer("estimator")
    assert state is not None and state.published == {keys.NAV_STATE.suffix: [P]}


def test_a_held_period_is_answered_again_on_rethink_and_only_then() -> None:
    node, driver, sim, listener = stack()
    node.fly = False
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])
    held = listener.ledger.answer("estimator")
    assert held is not None and held.hold
    driver.step()  # nothing new: no second answer
    assert len(node.answers) == 1
    node.fly = True
    driver.rethink()
    driver.step()
    assert [p for p, _ in node.answers] == [Period(0, 0), Period(0, 0)]
    flown = listener.ledger.answer("estimator")
    assert flown is not None and not flown.hold and flown.seq != held.seq


def test_a_new_episode_restarts_the_node_before_its_first_answer() -> None:
    node, _driver, sim, _listener = stack()
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])
    sim.answer(Period(0, P), P, [(keys.GNSS, fix(P))])
    sim.answer(Period(1, 0), P, [(keys.GNSS, fix(0))])  # a scenario load: time back to 0
    assert node.restarts == [Period(1, 0)]
    # Restarted before its first answer of the new episode: the old episode's later fix is gone.
    assert node.answers[-1] == (Period(1, 0), 2) and P not in node.fixes


def test_a_stamp_too_far_ahead_never_reaches_the_node() -> None:
    node, driver, sim, _listener = stack()
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])
    sim.answer(Period(0, P), P, [(keys.GNSS, fix(P)), (keys.GNSS, fix(10**15))])
    assert node.fixes == [0, P]
    assert driver.member.stamps.dropped == {(keys.GNSS.suffix, "ahead"): 1}


class Paced(Node):
    name = "paced"
    paced = True

    def __init__(self) -> None:
        self.ticks: list[int] = []
        self.finished = threading.Event()

    def tick(self, now_ns: int, out: Any) -> None:
        self.ticks.append(now_ns)

    def wake_s(self) -> float:
        return 0.001

    def finish(self) -> None:
        self.finished.set()


class Ctx:
    """What a driver uses of a ``ServiceContext``."""

    def __init__(self) -> None:
        self.bus = MemoryHub().bus(V)
        self.clock = WallClock()
        self.stop = threading.Event()
        self.ready_called = False

    def ready(self, joining: Any = None) -> None:
        self.ready_called = True


def test_a_paced_node_ticks_when_it_asks_and_finishes_at_the_stop() -> None:
    ctx, node = Ctx(), Paced()
    driver = LiveDriver(ctx, node, period_s=10.0)  # the period alone would tick once
    runner = threading.Thread(target=driver.run)
    runner.start()
    deadline = time.monotonic() + 10.0
    while len(node.ticks) < 5 and time.monotonic() < deadline:
        time.sleep(0.01)
    ctx.stop.set()
    runner.join(10.0)
    assert ctx.ready_called and len(node.ticks) >= 5 and node.finished.is_set()
    assert node.ticks == sorted(node.ticks)


def test_period_done_of_a_node_lists_what_it_published() -> None:
    """The bundle's answer names the node's messages (what a recorder and the clock rely on)."""
    _node, _driver, sim, listener = stack()
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])
    ans = listener.ledger.answer("estimator")
    assert isinstance(ans, PeriodDone) and ans.service == "estimator" and ans.period_ns == P


def test_a_member_is_a_member_before_its_health_token_says_it_is_ready() -> None:
    """A launcher starts the clock, or a replay, once the members' health tokens are up, and a
    replay paces each period by the members it knows then: a member token that came after the
    health token let a replay run its first periods without that member (the controller's commands
    lost). So the member token is declared first, and the period the clock repeats for the newcomer
    is answered."""
    hub = MemoryHub()
    seen: list[tuple[str, str]] = []  # (token kind, service), in the order they appeared
    watcher = hub.bus(V)
    watcher.watch_lockstep_members(lambda svc, alive: alive and seen.append(("member", svc)))
    watcher.watch_health(lambda svc, alive: alive and seen.append(("health", svc)))
    node = Estimating()
    ctx = ServiceContext("estimator", V, hub.bus(V), WallClock(), threading.Event(),
                         RunDescription(run_id="unit", vessel=V), agree=False)
    driver = MemberDriver(ctx.bus, node)
    node.attach(driver)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P, [(keys.GNSS, fix(0))])  # the clock's first period, before it joins
    runner = threading.Thread(target=driver.run, args=(ctx.stop, ctx.ready))
    runner.start()
    try:
        wait_for(lambda: ("health", "estimator") in seen, 10, what="the health token")
        assert seen.index(("member", "estimator")) < seen.index(("health", "estimator")), seen
        sim.repeat()  # what the clock does for a member that joins
        wait_for(lambda: node.answers, 10, what="the repeated period answered")
        assert node.answers[0][0] == Period(0, 0)
    finally:
        ctx.stop.set()
        runner.join(10)
