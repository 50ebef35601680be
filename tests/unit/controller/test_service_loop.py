"""The controller's node (``ControllerNode``) run by the runtime's drivers on the in-memory bus.

No network and no hand-written fake: the sim, the estimator, the operator and the observers are
other buses on the same ``MemoryHub``, as they would be other processes on Zenoh, and they speak the
lockstep protocol (``seaway.runtime.lockstep``) with real ``PeriodDone`` answers. The core has an
injected solver (test_core's ``ScriptedSolver``), so nothing is compiled.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import pytest
from seaway.contract import bundle, keys
from seaway.contract.messages import (
    BatteryState,
    MissionCommand,
    PeriodDone,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.bus_typed import TypedSubscriber
from seaway.runtime.clock import WallClock
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway.runtime.node import LiveDriver, Period
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import ServiceContext
from seaway_controller import checkpoint
from seaway_controller import keeper as keeper_module
from seaway_controller import realtime as realtime_module
from seaway_controller.node import ControllerNode
from seaway_controller.realtime import warn_slow_step

from tests.conftest import wait_for
from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state

VESSEL = "vessel1"
LOGGER = "seaway_controller"  # the node's modules log under it


def live_context(hub: MemoryHub, bus: MemoryBus | None = None) -> ServiceContext:
    """A real-time controller's context on ``hub`` (its own bus unless ``bus``)."""
    return ServiceContext(name="controller", vessel=VESSEL, bus=bus or hub.bus(VESSEL),
                          clock=WallClock(), stop=threading.Event(),
                          run=RunDescription(run_id="unit", vessel=VESSEL))


def live_driver(ctx: ServiceContext, node: ControllerNode, period_s: float) -> LiveDriver:
    """The runtime's wall-clock driver, attached to ``node`` (``run`` on a thread runs it)."""
    driver = LiveDriver(ctx, node, period_s)
    node.attach(driver)
    return driver


class Running(NamedTuple):
    hub: MemoryHub  # the network: the test joins it with buses of its own
    bus: MemoryBus  # the controller's bus (its stats)


@contextlib.contextmanager
def running_controller(state_file: Path | None = None) -> Iterator[Running]:
    """A lockstep controller run by the runtime (``run_node``) on a thread, as its process would."""
    hub = MemoryHub()
    bus = hub.bus(VESSEL)
    stop = threading.Event()
    ctx = ServiceContext(name="controller", vessel=VESSEL, bus=bus, clock=WallClock(), stop=stop,
                         run=RunDescription(run_id="unit", vessel=VESSEL, clock="lockstep"))
    node = ControllerNode(make_core(ScriptedSolver()), state_file=state_file)
    loop = threading.Thread(target=run_node, args=(ctx, node, DT_NS / 1e9),
                            name="controller-loop", daemon=True)
    loop.start()
    wait_for(lambda: ctx.is_ready, 5, what="the controller to be ready")
    try:
        yield Running(hub, bus)
    finally:
        stop.set()
        loop.join(2.0)
        bus.close()
    assert not loop.is_alive()


@pytest.fixture
def controller() -> Iterator[Running]:
    with running_controller() as running:
        yield running


class World:
    """The sim and the estimator of the protocol, driven by the test one period at a time."""

    def __init__(self, hub: MemoryHub) -> None:
        self.sim = Member(hub.bus(VESSEL), "sim", watched=(), seq_start=100)
        self.est = Member(hub.bus(VESSEL), "estimator", watched=(), seq_start=200)
        observer = hub.bus(VESSEL)
        self.answers: TypedSubscriber = observer.subscribe(keys.LOCKSTEP_CONTROLLER, mode="fifo")
        self.thrust: TypedSubscriber = observer.subscribe(keys.THRUST, mode="fifo")
        self.status: TypedSubscriber = observer.subscribe(keys.MISSION_STATUS, mode="fifo")

    def period(self, k: int, st: StateEstimate | None, episode: int = 0) -> PeriodDone:
        """Sim and estimator answer t_k (with ``st`` stamped t_k, or no state); the controller's answer."""
        p = Period(episode, k * DT_NS)
        self.sim.answer(p, DT_NS)
        if st is not None:
            st = st.model_copy(update={"stamp_ns": p.stamp_ns})
        self.est.answer(p, DT_NS, [(keys.NAV_STATE, st)] if st is not None else [])
        return self.next_answer(p)

    def next_answer(self, p: Period) -> PeriodDone:
        """The controller's next answer; a copy of its previous one sent again for a recorder (on a
        repeat: ``PeriodDone.resent``) is passed over."""
        ans = wait_for(lambda: (a := self.answers.get(0.05)) and not a.resent and a, 5,
                       what=f"the controller's answer to {p}")
        assert Period.of(ans) == p
        return ans


def test_answers_each_period_holds_when_idle_and_restarts_with_the_world(controller: Running) -> None:
    hub = controller.hub
    world = World(hub)
    operator = hub.bus(VESSEL)

    # Idle: the answer is "hold" (nothing to fly), with the status and no command.
    idle = world.period(0, state(0))
    assert idle.hold and keys.THRUST.suffix not in idle.published
    assert world.status.get(1.0).state == "idle" and world.thrust.drain() == []

    # A mission: the held period is answered again, now with a command stamped t_0.
    reply = operator.request(keys.MISSION_SET, mission(), timeout_s=2.0)
    assert reply.accepted, reply.reason
    again = world.next_answer(Period(0, 0))
    assert not again.hold and again.published[keys.THRUST.suffix] == [0] and again.seq > idle.seq
    assert world.thrust.get(1.0).source == "cc-empc"

    # The energy budget is priced at the mission's first period, then once a second of the
    # periods' clock (seaway_controller.budget.BUDGET_INTERVAL_NS).
    assert again.published[keys.MISSION_ENERGY.suffix] == [0]

    # One answer per period, listing what it published, in order.
    for k in range(1, 6):
        ans = world.period(k, state(k))
        assert ans.published == {keys.THRUST.suffix: [k * DT_NS], keys.SOLVE.suffix: [k * DT_NS],
                                 keys.MISSION_STATUS.suffix: [k * DT_NS]}
    assert [c.stamp_ns for c in world.thrust.drain()] == [k * DT_NS for k in range(1, 6)]

    # The estimator has no state (re-initialising): zero thrust, so that time goes on.
    blind = world.period(6, None)
    assert not blind.hold
    cmd = world.thrust.get(1.0)
    assert (cmd.source, cmd.thrust_port_n, cmd.thrust_starboard_n) == ("no-state", 0.0, 0.0)

    # The sim repeats t_6 for a newcomer: the controller repeats its answer, not a second solve.
    world.sim.repeat()
    rep = world.next_answer(Period(0, 6 * DT_NS))
    assert rep.published == blind.published and rep.seq > blind.seq
    assert world.thrust.get(1.0).source == "no-state"

    # A malformed state in the estimator's bundle is counted (on its key) and dropped by the
    # controller's bus; the loop goes on.
    again_6 = PeriodDone(stamp_ns=6 * DT_NS, service="estimator", episode=0, seq=999, period_ns=DT_NS,
                         published={keys.NAV_STATE.suffix: [6 * DT_NS]})
    operator.raw_publisher(keys.LOCKSTEP_ESTIMATOR.key(VESSEL), bundle.ENCODING).put(bundle.encode(
        again_6.encode(), [(keys.NAV_STATE.suffix, b'{"stamp_ns": 600000000, "x_m": NaN}')]))
    paused = operator.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="pause"))
    assert paused.accepted, paused.reason
    assert world.period(7, state(7)).hold  # paused: nothing to fly, time stops
    assert controller.bus.stats.malformed_by_key == {keys.NAV_STATE.key(VESSEL): 1}
    resumed = operator.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="resume"))
    assert resumed.accepted, resumed.reason
    assert not world.next_answer(Period(0, 7 * DT_NS)).hold
    world.status.drain()

    # The world restarts (time goes back to 0 in a new episode): the mission starts again.
    world.period(0, state(0), episode=1)
    restarted = world.status.drain()[-1]
    assert (restarted.state, restarted.active_leg, restarted.energy_used_j) == ("active", 1, 0.0)

    # A request the core refuses comes back refused, with its reason.
    refused = operator.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="resume"))
    assert not refused.accepted and refused.reason


def test_lockstep_checkpoint_follows_simulated_time(tmp_path: Path) -> None:
    """The checkpoint's energy count is re-saved every simulated second, not every wall second: in
    lockstep a wall second is many simulated ones, which a restart would lose (issue 14, item 9)."""
    path = tmp_path / "controller-state.json"
    with running_controller(path) as controller:
        world = World(controller.hub)
        operator = controller.hub.bus(VESSEL)
        world.period(0, state(0))
        assert operator.request(keys.MISSION_SET, mission(), timeout_s=2.0).accepted
        world.next_answer(Period(0, 0))
        statuses = []
        for k in range(1, 26):  # 2.5 s of simulated time, in a small fraction of a wall second
            world.period(k, state(k))
            statuses.append(wait_for(lambda: world.status.get(0.05), 5, what=f"status {k}"))
    saved = checkpoint.load(path)
    assert saved is not None and saved.state == "active"
    # Saved at t = 2.0 s of simulated time (every 1 s), so it holds the count of period 20, not the
    # zero written when the mission was accepted.
    at_20 = next(s.energy_used_j for s in statuses if s.stamp_ns == 20 * DT_NS)
    assert at_20 > 0
    assert saved.energy_used_j == pytest.approx(at_20, rel=1e-12)


def test_a_mission_after_a_restart_is_flown_from_the_new_episodes_first_state(
        controller: Running) -> None:
    """After a long idle episode (more states kept than the controller's window of recent ones),
    the world restarts and a mission comes: its first period t_0 is flown from the new episode's
    state at t_0. The state store dropped the lowest stamp when full, and the new t_0 state arrives
    before the loop has dropped the old episode's (stamped up to its end): it was that state that
    went, and the mission's first command was "no-state" zero thrust, its start a period late."""
    world = World(controller.hub)
    operator = controller.hub.bus(VESSEL)
    for k in range(40):  # 4 s idle: each period held, each state kept in the window
        assert world.period(k, state(k)).hold
    assert world.period(0, state(0), episode=1).hold  # a new episode, still nothing to fly
    world.thrust.drain()
    assert operator.request(keys.MISSION_SET, mission(), timeout_s=2.0).accepted
    again = world.next_answer(Period(1, 0))
    assert not again.hold and keys.SOLVE.suffix in again.published, again.published
    first = world.thrust.get(1.0)
    assert (first.stamp_ns, first.source) == (0, "cc-empc")


def test_a_real_time_controller_stopping_in_order_commands_zero_thrust_last() -> None:
    """Ctrl-C of a mission in progress: the thrusters kept the last command until vehicle_io's
    watchdog cut them 0.3 s later with a WARNING. The real-time loop's last command is now zero
    thrust (source 'stop'), so the thrusters stop at once and the watchdog's trip is the expected
    end of a run (vehicle_io: after a zero command it is INFO)."""
    hub = MemoryHub()
    ctx = live_context(hub)
    stop = ctx.stop
    node = ControllerNode(make_core(ScriptedSolver()), max_state_age_s=0.5)
    driver = live_driver(ctx, node, 1 / 50.0)
    observer = hub.bus(VESSEL)
    thrust: TypedSubscriber = observer.subscribe(keys.THRUST, mode="fifo")
    estimator = hub.bus(VESSEL)
    nav = estimator.publisher(keys.NAV_STATE)
    assert node._serve("mission/set", node.core.handle_mission, mission()).accepted
    loop = threading.Thread(target=driver.run, daemon=True)
    loop.start()
    seen = []

    def flying() -> bool:  # a fresh state each look, as the estimator publishes them
        now = ctx.clock.now_ns()
        nav.put(state(0).model_copy(update={"stamp_ns": now}))
        seen.extend(thrust.drain())
        return any(c.source != "idle" and (c.thrust_port_n, c.thrust_starboard_n) != (0.0, 0.0)
                   for c in seen)

    wait_for(flying, 10, interval_s=0.05, what="the mission to drive the thrusters")
    stop.set()
    loop.join(5)
    assert not loop.is_alive()
    seen.extend(thrust.drain())
    last = seen[-1]
    assert (last.thrust_port_n, last.thrust_starboard_n, last.source) == (0.0, 0.0, "stop")
    assert last.seq > seen[-2].seq
    for bus in (ctx.bus, observer, estimator):
        bus.close()


def test_a_mission_that_comes_while_the_period_cannot_be_answered_is_flown_once_it_can(
        controller: Running) -> None:
    """Seen in a CI-like run: the first mission of a fresh stack came while the estimator's answer of
    the held t_0 lacked a state (its repeat for a newcomer crossing the state). The loop looked,
    could not answer, and forgot the mission; once the estimator's answer was whole the hold stood,
    a repeat only repeats it, and the run stalled at t = 0 for good (the sim's restart too)."""
    import time

    hub = controller.hub
    world = World(hub)
    operator = hub.bus(VESSEL)
    assert world.period(0, state(0)).hold  # idle: nothing to fly
    lacking = PeriodDone(stamp_ns=0, service="estimator", episode=0, seq=500, period_ns=DT_NS,
                         published={keys.NAV_STATE.suffix: [0, 1]})  # a state it does not carry
    operator.raw_publisher(keys.LOCKSTEP_ESTIMATOR.key(VESSEL), bundle.ENCODING).put(
        bundle.encode(lacking.encode(), []))
    reply = operator.request(keys.MISSION_SET, mission(), timeout_s=2.0)
    assert reply.accepted, reply.reason
    time.sleep(0.3)  # the loop looks now and cannot answer (a slower machine only weakens the test)
    assert world.answers.get(0.05) is None or world.answers.drain() == []  # nothing answered yet
    at_t0 = state(0).model_copy(update={"stamp_ns": 0})
    world.est.answer(Period(0, 0), DT_NS, [(keys.NAV_STATE, at_t0)])  # whole again
    flown = world.next_answer(Period(0, 0))
    assert not flown.hold and flown.published[keys.THRUST.suffix] == [0]
    assert world.thrust.get(1.0).source == "cc-empc"


class _PromptBus(MemoryBus):
    """A bus whose battery and vehicle status callbacks run the moment they are subscribed, as
    Zenoh's thread may run them before the subscriber's constructor has returned."""

    def subscribe(self, spec, mode="latest", capacity=10_000, callback=None, **kw):  # type: ignore[override]
        sub = super().subscribe(spec, mode, capacity, callback, **kw)
        if callback is not None and spec is keys.VEHICLE_BATTERY:
            callback(spec.suffix, BatteryState.make(stamp_ns=time.time_ns(), source="autopilot",
                                                    remaining_j=5_000.0, reserve_j=1_000.0))
        if callback is not None and spec is keys.VEHICLE_STATUS:
            callback(spec.suffix, VehicleStatus.make(stamp_ns=time.time_ns(), autopilot="px4",
                                                     armed=True, mode="MANUAL", link_ok=True))
        return sub


def test_a_report_that_comes_as_the_real_time_service_subscribes_is_taken() -> None:
    """A restarted real-time controller died on its first battery report: the subscription was made
    before ``self.stamps`` existed, and a report that came at once raised AttributeError on the
    bus's thread (and was lost). Every input is taken from the moment it is subscribed."""
    hub = MemoryHub()
    bus = _PromptBus(VESSEL, hub)
    ctx = live_context(hub, bus)
    node = ControllerNode(make_core(ScriptedSolver()))
    driver = live_driver(ctx, node, 0.02)
    loop = threading.Thread(target=driver.run, daemon=True)
    loop.start()
    try:
        wait_for(lambda: ctx.is_ready, 5, what="the controller to be ready")  # all subscribed
        report = node.core.battery.report
        assert report is not None and report.remaining_j == 5_000.0
        assert node.core.vehicle is not None
    finally:
        ctx.stop.set()
        loop.join(5)
        bus.close()
    assert not loop.is_alive()


class SlowSolver(ScriptedSolver):
    """Takes ``sleep_s`` of wall time in each solve, as a reference IPOPT on the loop could."""

    def __init__(self, sleep_s: float) -> None:
        super().__init__()
        self.sleep_s = sleep_s

    def solve(self, w0, p, lam_x0, lam_g0):
        time.sleep(self.sleep_s)
        return super().solve(w0, p, lam_x0, lam_g0)


def test_a_real_time_step_longer_than_the_period_names_itself_in_the_log(caplog) -> None:
    """A real-time controller stalled in its step (issue #56 item 2: the vessel stopped with
    ``thrust_stale`` and nothing in the controller's log said why): a step that takes longer
    than the control period is logged as a WARNING with how long it took."""
    hub = MemoryHub()
    ctx = live_context(hub)
    stop = ctx.stop
    period_s = 0.02
    node = ControllerNode(make_core(SlowSolver(sleep_s=5 * period_s)), max_state_age_s=5.0)
    driver = live_driver(ctx, node, period_s)
    estimator = hub.bus(VESSEL)
    nav = estimator.publisher(keys.NAV_STATE)
    assert node._serve("mission/set", node.core.handle_mission, mission()).accepted
    loop = threading.Thread(target=driver.run, daemon=True)
    caplog.set_level("WARNING", logger=LOGGER)

    def slow_step_logged() -> bool:
        nav.put(state(0).model_copy(update={"stamp_ns": ctx.clock.now_ns()}))
        return any("control step took" in r.getMessage() for r in caplog.records)

    try:
        loop.start()
        wait_for(slow_step_logged, 10, interval_s=0.05, what="the slow step's WARNING")
    finally:
        stop.set()
        loop.join(5)
        for bus in (ctx.bus, estimator):
            bus.close()
    slow = [r for r in caplog.records if "control step took" in r.getMessage()]
    assert slow[0].levelname == "WARNING"
    took_s = float(slow[0].getMessage().split("took ")[1].split(" s")[0])
    assert took_s > period_s


def test_a_step_within_the_period_is_not_logged(caplog) -> None:
    caplog.set_level("WARNING", logger=LOGGER)
    ratelog = RateLimitedLog(logging.getLogger(LOGGER))
    assert not warn_slow_step(ratelog, 0.05, 0.1)
    assert warn_slow_step(ratelog, 0.15, 0.1)
    assert len(caplog.records) == 1


class StuckSolver(ScriptedSolver):
    """Blocks in its solve until released, as a hung computation on the loop's thread would."""

    def __init__(self) -> None:
        super().__init__()
        self.release = threading.Event()

    def solve(self, w0, p, lam_x0, lam_g0):
        self.release.wait(30)
        return super().solve(w0, p, lam_x0, lam_g0)


def test_a_real_time_step_stuck_for_long_is_logged_with_where_it_is_while_stuck(
        caplog, monkeypatch) -> None:
    """A controller silent on ctrl/thrust for seconds is restarted by the launcher's liveness, and
    its log said nothing of why (issue #56 item 2). While a step is stuck, the log now says so with
    the loop thread's stack (here: inside the solver), before the step returns."""
    monkeypatch.setattr(realtime_module, "STEP_STALL_S", 0.2)
    hub = MemoryHub()
    ctx = live_context(hub)
    stop = ctx.stop
    solver = StuckSolver()
    node = ControllerNode(make_core(solver), max_state_age_s=5.0)
    driver = live_driver(ctx, node, 1 / 50.0)
    estimator = hub.bus(VESSEL)
    nav = estimator.publisher(keys.NAV_STATE)
    assert node._serve("mission/set", node.core.handle_mission, mission()).accepted
    loop = threading.Thread(target=driver.run, daemon=True)
    caplog.set_level("WARNING", logger=LOGGER)

    def stuck_logged() -> bool:
        nav.put(state(0).model_copy(update={"stamp_ns": ctx.clock.now_ns()}))
        return any("running for" in r.getMessage() for r in caplog.records)

    try:
        loop.start()
        wait_for(stuck_logged, 10, interval_s=0.05, what="the stuck step's WARNING")
        assert not solver.release.is_set()  # said while the step is still stuck
        stuck = next(r for r in caplog.records if "running for" in r.getMessage())
        assert stuck.levelname == "WARNING"
        assert "StuckSolver" in stuck.getMessage() or "in solve" in stuck.getMessage()
        assert "release.wait" in stuck.getMessage()  # the line the loop is stuck on
        solver.release.set()
        wait_for(lambda: any("stuck step ended" in r.getMessage() for r in caplog.records), 10,
                 what="the stuck step's end")
    finally:
        solver.release.set()
        stop.set()
        loop.join(5)
        for bus in (ctx.bus, estimator):
            bus.close()


@contextlib.contextmanager
def stuck_real_time_controller(period_s: float) -> Iterator[tuple[ControllerNode, StuckSolver,
                                                                   TypedSubscriber, Any]]:
    """A real-time controller flying a mission whose first solve blocks until released; yields
    (node, solver, a subscriber to ctrl/thrust, a function that publishes a fresh state)."""
    hub = MemoryHub()
    ctx = live_context(hub)
    stop = ctx.stop
    solver = StuckSolver()
    node = ControllerNode(make_core(solver), max_state_age_s=5.0)
    driver = live_driver(ctx, node, period_s)
    observer, estimator = hub.bus(VESSEL), hub.bus(VESSEL)
    thrust: TypedSubscriber = observer.subscribe(keys.THRUST, mode="fifo")
    nav = estimator.publisher(keys.NAV_STATE)
    assert node._serve("mission/set", node.core.handle_mission, mission()).accepted
    loop = threading.Thread(target=driver.run, daemon=True)

    def fresh_state() -> None:
        nav.put(state(0).model_copy(update={"stamp_ns": ctx.clock.now_ns()}))

    try:
        fresh_state()
        loop.start()
        yield node, solver, thrust, fresh_state
    finally:
        solver.release.set()
        stop.set()
        loop.join(5)
        for bus in (ctx.bus, observer, estimator):
            bus.close()
    assert not loop.is_alive()


def test_a_real_time_step_that_overruns_still_commands_the_thrusters_once_a_period(caplog) -> None:
    """Issue #56 item 2: the controller stopped commanding at the return decision (vehicle_io's
    ``thrust_stale``, the vessel stopped) while one step ran long. The loop published one command
    per step, so a step that overran left the thrusters without one. While a step overruns, the
    keeper now sends the fallback chain's line-of-sight guidance on the active leg, from the newest
    state, once a period; the step's own command follows when it ends, and none of the keeper's
    after it."""
    caplog.set_level("WARNING", logger=LOGGER)
    with stuck_real_time_controller(period_s=0.02) as (_node, solver, thrust, fresh_state):
        seen: list = []

        def kept() -> bool:
            fresh_state()
            seen.extend(thrust.drain())
            return sum(c.source == keeper_module.SOURCE_LOS for c in seen) >= 3

        wait_for(kept, 10, interval_s=0.01, what="commands sent in the stuck step's place")
        assert not solver.release.is_set()  # all while the step is still stuck
        los = [c for c in seen if c.source == keeper_module.SOURCE_LOS]
        assert all((c.thrust_port_n, c.thrust_starboard_n) != (0.0, 0.0) for c in los)
        assert [c.stamp_ns for c in los] == sorted(c.stamp_ns for c in los)  # the newest state
        assert len({c.stamp_ns for c in los}) > 1
        assert any("commanding overrun-los thrust in its place" in r.getMessage()
                   for r in caplog.records)
        solver.release.set()

        def flown() -> bool:
            fresh_state()
            seen.extend(thrust.drain())
            return any(c.source == "cc-empc" for c in seen)

        wait_for(flown, 10, interval_s=0.01, what="the MPC's command once the step ended")
        first_mpc = next(i for i, c in enumerate(seen) if c.source == "cc-empc")
        assert all(c.source != keeper_module.SOURCE_LOS for c in seen[first_mpc:])


def test_a_real_time_step_that_hangs_gets_zero_thrust_then_silence(caplog, monkeypatch) -> None:
    """A step that does not end is a hang, not a late step: after ``KEEP_MAX_S`` the keeper sends
    zero thrust once, logs an ERROR and stops, so that the launcher's liveness (silence on
    ``ctrl/thrust``) restarts the process rather than line-of-sight guidance flying on a leg the
    stuck core no longer switches."""
    monkeypatch.setattr(keeper_module, "KEEP_MAX_S", 0.3)
    caplog.set_level("WARNING", logger=LOGGER)
    with stuck_real_time_controller(period_s=0.02) as (node, solver, thrust, fresh_state):
        seen: list = []

        def stopped() -> bool:
            fresh_state()
            seen.extend(thrust.drain())
            return any(c.source == keeper_module.SOURCE_STOP for c in seen)

        wait_for(stopped, 10, interval_s=0.01, what="the keeper's zero thrust")
        stop = next(c for c in seen if c.source == keeper_module.SOURCE_STOP)
        assert (stop.thrust_port_n, stop.thrust_starboard_n) == (0.0, 0.0)
        assert seen[-1] is stop and any(c.source == keeper_module.SOURCE_LOS for c in seen)
        assert node.live is not None
        sent = node.live.keeper.sent
        for _ in range(20):  # still stuck: nothing more, whatever comes in
            fresh_state()
            time.sleep(0.01)
        assert not solver.release.is_set()
        assert thrust.drain() == [] and node.live.keeper.sent == sent
        assert any(r.levelname == "ERROR" and "stopped commanding in its place" in r.getMessage()
                   for r in caplog.records)


def test_max_state_age_has_an_upper_bound_in_files_and_flags(capsys) -> None:
    """An hour-old state steered (--max-state-age-s 3600 was accepted): at most 2 s now."""
    from seaway.contract.config import ConfigError, parse_config
    from seaway.runtime.config import parse_service_args
    from seaway_controller.config import MAX_STATE_AGE_S, ControllerServiceConfig
    from seaway_controller.main import build_parser

    with pytest.raises(ConfigError, match=r"probe.toml.*\n  max_state_age_s: .*less than or equal to 2"):
        parse_config({"max_state_age_s": 3600.0}, ControllerServiceConfig, "probe.toml")
    assert parse_config({"max_state_age_s": MAX_STATE_AGE_S}, ControllerServiceConfig).max_state_age_s == 2.0
    with pytest.raises(SystemExit):
        parse_service_args(build_parser(), ["--max-state-age-s", "3600"])
    assert "argument --max-state-age-s: '3600' is not a finite number above 0 and at most 2" in (
        capsys.readouterr().err)
