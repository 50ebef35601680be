"""Over Zenoh, lockstep moves on on the thread that takes the completing bundle, never by waking a
loop thread: the sim's clock applies the controller's command and publishes the next period there,
and a member whose answers come from two sources answers there whichever arrives last.

Each hand-over from Zenoh's thread to a loop thread cost a thread switch every period on the
critical path, and a bundle held in a ring for the loop (a passive source) woke the loop to poll for
it. Real Zenoh sessions in this process, the test's own credentials.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest
from seaway.contract import keys
from seaway.contract.messages import StateEstimate, ThrustCommand
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_clock import LockstepClock
from seaway.runtime.lockstep_member import Member
from seaway.runtime.node import Answer, MemberDriver, MemberSpec, Node, PeriodAt
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode

from tests.conftest import wait_for

pytestmark = pytest.mark.system
P = 100_000_000
V = "vessel1"


class Steering(Node):
    """A controller that answers each period with a thrust command, noting the thread it answers
    on; it needs ``needs`` (the sim's answer, and the estimator's if given), as the real one."""

    name = "controller"

    def __init__(self, needs: tuple[str, ...], passive: tuple[str, ...] = ()) -> None:
        inputs = frozenset({keys.NAV_STATE.suffix}) if "estimator" in needs else frozenset()
        self.member = MemberSpec("controller", needs=needs, inputs=inputs, hears=needs,
                                 passive=passive)
        self.answers: list[tuple[Period, str]] = []

    def answer(self, at: PeriodAt) -> Answer:
        self.answers.append((at.period, threading.current_thread().name))
        cmd = ThrustCommand.make(stamp_ns=at.period.stamp_ns, thrust_port_n=1.0,
                                 thrust_starboard_n=1.0)
        return Answer([(keys.THRUST, cmd)])


def run_member(bus: Bus, node: Node, stop: threading.Event) -> tuple[MemberDriver, threading.Thread]:
    driver = MemberDriver(bus, node)
    node.attach(driver)
    # ``ready`` joins (a service's context declares its health token after): no health here.
    thread = threading.Thread(target=driver.run, args=(stop, lambda join: join()), name="member-loop",
                              daemon=True)
    thread.start()
    return driver, thread


def taken_or_repeated(source: Member, taken: Callable[[], bool], what: str) -> None:
    """Wait until ``taken``; meanwhile repeat ``source``'s last bundle every half second, as the
    protocol does for a newcomer: a session just opened may not yet have heard of the member's
    subscriptions, and Zenoh drops a put nobody is known to want (receivers drop what they have
    seen, so a repeat that crosses the first changes nothing)."""
    deadline = time.monotonic() + 10.0
    while not taken():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after 10 s waiting for {what}")
        wait_until = time.monotonic() + 0.5
        while not taken() and time.monotonic() < wait_until:
            time.sleep(0.01)
        if not taken():
            source.repeat()


def test_the_sims_clock_steps_and_publishes_on_the_thread_of_the_controllers_answer(zenoh_env):
    scenario = load_scenario("paper-c1")
    app = SimNode(SimCore(scenario, load_vessel(scenario.vessel)), lockstep=True)
    stepped_on: list[str] = []
    advance = app.advance
    app.advance = lambda cmd, period_ns: (stepped_on.append(threading.current_thread().name),  # type: ignore[method-assign]
                                          advance(cmd, period_ns))[1]
    stop = threading.Event()
    with Bus.open(V) as sim_bus, Bus.open(V) as ctl_bus:
        clock = LockstepClock(sim_bus, app, 0.1, stop)
        loop = threading.Thread(target=clock.run, name="clock-loop", daemon=True)
        node = Steering(needs=("sim",))
        _, member_loop = run_member(ctl_bus, node, stop)
        loop.start()
        try:
            wait_for(lambda: len(stepped_on) >= 30, 30, what="30 periods stepped")
        finally:
            stop.set()
            loop.join(5)
            member_loop.join(5)
    # The loop starts the run and may take a period now and then (it wakes at least every 0.25 s
    # to watch for stalls); the periods move on on Zenoh's thread.
    assert sum(name != "clock-loop" for name in stepped_on) > len(stepped_on) // 2, stepped_on


def test_a_member_answers_on_arrival_of_whichever_bundle_completes_its_period(zenoh_env):
    """The controller needs the sim's answer and the estimator's; the sim's comes last. Declared a
    passive source (as the real controller declares it), it waited in a ring and the controller's
    loop woke to look for it and answered the period itself."""
    stop = threading.Event()
    with Bus.open(V) as ctl_bus, Bus.open(V) as sim_bus, Bus.open(V) as est_bus:
        node = Steering(needs=("sim", "estimator"), passive=("sim",))
        driver, member_loop = run_member(ctl_bus, node, stop)
        sim = Member(sim_bus, "sim", watched=(), subscribe=False)
        est = Member(est_bus, "estimator", watched=(), subscribe=False)
        try:
            for k in range(10):
                period = Period(0, k * P)
                state = StateEstimate.make(stamp_ns=period.stamp_ns, u_mps=0.0, v_mps=0.0,
                                           r_radps=0.0, x_m=0.0, y_m=0.0, psi_rad=0.0)
                est.answer(period, P, [(keys.NAV_STATE, state)])
                taken_or_repeated(est, lambda: driver.member.ledger.answers.get("estimator") is not None
                                  and Period.of(driver.member.ledger.answers["estimator"]) == period,  # noqa: B023
                                  f"the estimator's answer to t_{k} taken")
                sim.answer(period, P)
                taken_or_repeated(sim, lambda: len(node.answers) > k, f"the answer to t_{k}")  # noqa: B023
        finally:
            stop.set()
            member_loop.join(5)
    assert [p for p, _ in node.answers] == [Period(0, k * P) for k in range(10)]
    assert all(name != "member-loop" for _, name in node.answers), node.answers
