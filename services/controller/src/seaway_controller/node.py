"""The controller as a node of ``seaway.runtime.node``: the bus-facing half of ``ControllerCore``.

Inputs: ``nav/state`` (StateEstimate), ``nav/origin`` (NavOrigin), ``vehicle/battery``
(BatteryState), ``vehicle/status`` (VehicleStatus), requests ``mission/set`` (MissionRequest),
``mission/command`` (MissionCommand) and ``mission/home`` (HomeRequest), each answered with a Reply.
In lockstep the state and origin come in the estimator's bundle, the battery in the sim's
(``seaway.contract.bundle``), and the outputs go in the controller's own.
Outputs: ``ctrl/thrust`` (ThrustCommand, stamped with the state's stamp), ``ctrl/solve``
(SolveRecord, one per solve), ``mission/status`` (MissionStatus), ``mission/energy`` (the energy
budget), ``area/active`` and ``mission/accepted`` (MissionAccepted: the mission accepted, in local
NED; real time: at once and every second, lockstep: in the answer of the period that follows the
acceptance).

Two clocks:

* real time (``tick``): every control period of the run on the wall clock; each tick uses the
  newest state if a new one arrived; a state older than ``max_state_age_s`` gives zero thrust; a
  step that overruns gets a command sent in its place, once a period (``realtime.py``); stopping,
  the last command is zero thrust (``finish``);
* lockstep (``answer``): one answer per period of the sim, once the estimator's bundle (its answer
  and the state) is in: the command for that state (zero thrust if the estimator has no state yet),
  or "hold" when there is nothing to fly (no mission, paused, over), which stops simulated time
  until a mission request makes the controller answer the period again (``rethink``). A new episode
  (the sim restarted or loaded a scenario) restarts a mission in progress from its first leg.

Solvers (``solver_builds.SolverBuilds``): the fast solver a mission needs is made when the mission comes,
on a thread of its own; the mission starts once it is ready, or after ``SOLVER_REPLY_WAIT_S`` (a
compile). Until it is ready, real time flies with the reference IPOPT (``solver_builds.StagedSolver``)
and lockstep answers "hold" (simulated time waits, so the run is the one a warm start gives); the
mission/set reply and ``MissionStatus.reason`` say so.

The mission checkpoint (``--state-file``) is ``checkpointing.py``'s.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    HomeRequest,
    MissionCommand,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    Reply,
    StateEstimate,
    ThrustCommand,
    VehicleStatus,
)
from seaway.runtime.node import (
    Answer,
    LiveDriver,
    MemberDriver,
    MemberSpec,
    Node,
    Outputs,
    Period,
    PeriodAt,
)
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.vessel.frames import GeoOrigin

from seaway_controller.checkpointing import Checkpoints
from seaway_controller.core import ControllerCore
from seaway_controller.realtime import Flying, RealTime, flying_of
from seaway_controller.solver_builds import SolverBuilds

log = logging.getLogger(__name__)
NAME = "controller"

SOLVER_REPLY_WAIT_S = 2.0
"""How long a mission waits for its solver before it starts: enough to load a cached one, so that
only a compile still under way is flown on the fallbacks and worth a word in the reply [s]."""

STATES_KEPT = 16
"""Lockstep: the states of recent periods kept for the estimator's answers to name."""

MEMBER = MemberSpec(
    NAME, needs=("sim", "estimator"),
    inputs=frozenset({keys.NAV_STATE.suffix, keys.VEHICLE_BATTERY.suffix, keys.NAV_ORIGIN.suffix}),
    watched=frozenset({keys.NAV_STATE.suffix, keys.VEHICLE_BATTERY.suffix}),
    hears=("sim", "estimator"), passive=("sim",))
"""In lockstep the state and origin come in the estimator's bundle, which moves the controller on;
the battery in the sim's (once a second), sent before the estimator's and taken with it. State and
battery are listed, so the budget prices from the same inputs in a replay; the origin is taken
when it comes."""


class ControllerNode(Node):
    """Owns the core and its lock; answers each period or tick, and the mission requests."""

    name = NAME
    member = MEMBER
    live_inputs = (keys.NAV_STATE, keys.VEHICLE_BATTERY, keys.NAV_ORIGIN)
    side_inputs = (keys.VEHICLE_STATUS,)  # pauses a mission

    def __init__(self, core: ControllerCore, state_file: Path | None = None,
                 builds: SolverBuilds | None = None, max_state_age_s: float = 0.5) -> None:
        self.core = core
        self.lock = threading.Lock()
        # The fast solvers being made in the background (None: the core makes its own at once).
        self.builds = builds
        if builds is not None:
            builds.on_done = self.on_solver_done
        self.checkpoints = Checkpoints(state_file)
        self.max_state_age_s = max_state_age_s
        self.stamps = StampGate(NAME, log, StampBounds.live())  # real time: not ahead of now
        self.ratelog = RateLimitedLog(log)  # a step failing every period: a traceback now and then
        self.driver: MemberDriver | LiveDriver | None = None
        self.lockstep = False
        self.live: RealTime | None = None  # real time: the keeper, the stall watch, staleness
        self.out: Outputs | None = None  # real time: the publishers
        self._flying: Flying | None = None  # as of the last step or request (the keeper's)
        self._newest: StateEstimate | None = None  # real time: the newest state heard
        self._states: dict[int, StateEstimate] = {}  # lockstep: the states of recent periods
        self._states_lock = threading.Lock()

    # -- the node (seaway.runtime.node) ---------------------------------------------------------

    def attach(self, driver: MemberDriver | LiveDriver) -> None:
        self.driver = driver
        if isinstance(driver, LiveDriver):
            self.out = out = driver.out
            self.live = RealTime(functools.partial(out.put, keys.THRUST), driver.period_s,
                                 self.max_state_age_s, driver.stop, log)
            self.checkpoints.durable()
        else:
            self.lockstep = True

    def requests(self) -> Mapping[keys.KeySpec, Callable[[Any], Reply]]:
        return {keys.MISSION_SET: self.on_mission, keys.MISSION_COMMAND: self.on_command,
                keys.MISSION_HOME: self.on_home}

    def take(self, key: str, msg: Any, now_ns: int | None) -> None:
        """An input; ``now_ns`` the wall clock in real time (its stamp is bounded here), None in
        lockstep (admitted by the driver)."""
        if isinstance(msg, StateEstimate):
            if now_ns is None:
                self._keep_state(msg)
            else:
                self._newest = msg  # bounded when it is used
        elif isinstance(msg, BatteryState):
            self.on_battery(msg, now_ns)
        elif isinstance(msg, NavOrigin):
            with self.lock:
                self.core.set_origin(GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m))
        elif isinstance(msg, VehicleStatus):
            self.on_vehicle_status(msg, now_ns)

    def restart(self, period: Period) -> None:
        """The sim restarted, or loaded a scenario: a mission in progress starts again from its first
        leg (the vessel is back at its start); one that is over stays over."""
        with self.lock:
            progress = self.core.progress()
            if progress is None or progress[2] not in ("active", "paused"):
                return
            req = progress[0]
            reply = self.core.handle_mission(period.stamp_ns, req, check=False)
        with self._states_lock:
            self._states = {k: v for k, v in self._states.items() if k <= period.stamp_ns}
        log.warning("lockstep episode %d (time back to %.3f s): mission %r restarted: %s",
                    period.episode, period.stamp_ns / 1e9, req.mission_id, reply.reason)
        self.save_checkpoint(force=True)

    def answer(self, at: PeriodAt) -> Answer:
        """Period t_k's answer: the command for the state the estimator's answer lists, or hold
        when there is nothing to fly.

        Without a state (the estimator is not initialised) an active mission gets zero thrust, so
        that time goes on to the next measurements; idle, paused or over, the answer is hold; so it
        is while the mission's solver is still being made (answered again once it is ready)."""
        t = at.period.stamp_ns
        with self._states_lock:  # later states can only be late ones of an earlier episode
            self._states = {k: v for k, v in self._states.items() if k <= t}
            stamps = at.answers["estimator"].published.get(keys.NAV_STATE.suffix, [])
            state = self._states.get(stamps[-1]) if stamps else None
        out: list[tuple[keys.KeySpec, Any]] = []
        with self.lock:  # a mission accepted since the last answer: first of this period's messages
            accepted = self.core.take_accepted(t)
        announce: list[tuple[keys.KeySpec, Any]] = (
            [] if accepted is None else [(keys.MISSION_ACCEPTED, accepted)])
        with self.lock:
            area = self.core.area.message(t)
        announce += [] if area is None else [(keys.AREA_ACTIVE, area)]
        try:
            with self.lock:
                active = self.core.missions.state == "active"
                waiting = self.solver_pending() if state is not None else None
                if waiting is not None:
                    # Its solver is being made: hold (no step, so the run is the one a warm start
                    # gives), and answer this period again once it is ready (on_solver_done).
                    out.append((keys.MISSION_STATUS, self._held_status(t, waiting)))
                    active = False
                elif state is None:
                    if active:
                        out.append((keys.THRUST, self.core.zero_command(t, "no-state")))
                else:
                    cmd, record, status = self.core.step(t, state)
                    active = status.state == "active"
                    if active:
                        out.append((keys.THRUST, cmd))
                    if record is not None:
                        out.append((keys.SOLVE, record))
                    out.append((keys.MISSION_STATUS, status))
                    budget = self.core.take_budget()
                    if budget is not None:
                        out.append((keys.MISSION_ENERGY, budget))
        except Exception:  # a bug must not leave a lockstep sim without a command
            self.ratelog.exception("step", "control step failed; commanding zero thrust")
            with self.lock:
                out = [(keys.THRUST, self.core.zero_command(t, "error"))]
            active = True
        return Answer(announce + out, hold=not active)

    def answered(self) -> None:
        self.save_checkpoint()

    def tick(self, now_ns: int, out: Outputs) -> None:
        """Real time: one control period at ``now_ns``: the newest state if it is new and fresh
        (not ahead of now: ``seaway.runtime.stamps``) is stepped on; none fresh for too long gives
        zero thrust."""
        live = self.live
        assert live is not None
        self.announce(now_ns)
        state = self._newest
        if state is not None and not self.stamps.admit(keys.NAV_STATE.suffix, state.stamp_ns,
                                                       now_ns):
            state = None  # stamped ahead of now: wrong, never acted on (seaway.runtime.stamps)
        due = live.due(state, now_ns)
        if due is not None:
            # The monotonic clock with it: the energy counted over the time since the last step
            # must not take a wall clock's step (NTP, GPS time) for hours of thrust.
            live.run_step(functools.partial(self.step, now_ns, due, time.monotonic_ns()),
                          functools.partial(self._overrun_command, due), self.ratelog)
            return
        stale = live.stale(now_ns)
        if stale is not None:
            out.put(keys.THRUST, self.core.zero_command(stale, "stale-state"))

    def finish(self) -> None:
        """Stopping: in real time zero thrust as the last command; the last checkpoint written."""
        try:
            if self.live is not None:
                self.stop_thrusters(self.live.last_stamp)
        finally:
            self.checkpoints.close()

    # -- requests --------------------------------------------------------------------------------

    def on_mission(self, req: MissionRequest) -> Reply:
        if self.builds is not None:
            # The mission's solver is asked for first, and the mission starts once it is there
            # (a cached one is loaded in a moment) or this wait is over (a compile): started
            # before, its first periods flew on a fallback while the solver was being loaded.
            with self.lock:
                kind = self.core.prepare_for(req)
            if kind is not None:
                self.builds.wait(kind, SOLVER_REPLY_WAIT_S)
        reply = self._serve(f"{keys.MISSION_SET.suffix} {req.mission_id!r}", self.core.handle_mission,
                            req)
        making = self.solver_progress(req.controller) if reply.accepted else ""
        if making:  # the mission is on; say how it is flown until its solver is there
            meanwhile = ("simulated time holds until it is ready" if self.lockstep
                         else "flying with the reference IPOPT meanwhile")
            reply = reply.model_copy(update={"reason": f"{reply.reason}; {making}: {meanwhile}"})
        return reply

    def on_command(self, cmd: MissionCommand) -> Reply:
        return self._serve(f"{keys.MISSION_COMMAND.suffix} {cmd.command}", self.core.handle_command, cmd)

    def on_home(self, req: HomeRequest) -> Reply:
        return self._serve(keys.MISSION_HOME.suffix, self.core.handle_home, req)

    def _serve(self, what: str, handle: Callable[[int, Any], Reply], request: Any) -> Reply:
        """One mission request: the core decides under the lock, the reply is logged, progress saved.

        In lockstep the request is taken at the current period, whose answer is then thought again
        if it was "hold" (nothing to fly until now)."""
        with self.lock:
            reply = handle(self.now_ns(), request)
            self._remember_leg()
        log.info("%s: %s %s", what, "accepted" if reply.accepted else "REFUSED", reply.reason)
        self.save_checkpoint(force=True)
        if self.lockstep and reply.accepted:
            self.driver.rethink()  # type: ignore[union-attr]
        return reply

    def now_ns(self) -> int:
        """Wall time live; the current period in lockstep (the sim does not move without us)."""
        assert self.driver is not None, "the controller's node is not attached to a driver"
        return self.driver.now_ns()

    # -- solvers ---------------------------------------------------------------------------------

    def solver_progress(self, kind: str) -> str:
        """'' when ``kind``'s fast solver is ready (or not made in the background), else where it is."""
        return self.builds.describe(kind) if self.builds is not None else ""

    def solver_pending(self) -> str | None:
        """The active mission's controller while its fast solver is still being made, else None."""
        mission = self.core.missions.mission
        if self.builds is None or mission is None or self.core.missions.state != "active":
            return None
        return mission.controller if self.builds.pending(mission.controller) else None

    def on_solver_done(self, kind: str) -> None:
        """A fast solver is ready (or failed): lockstep answers a period held for it again."""
        if self.lockstep:
            self.driver.rethink()  # type: ignore[union-attr]

    def _held_status(self, t_ns: int, kind: str) -> MissionStatus:
        """The status of an active mission held while its solver is being made (under the lock)."""
        mm, core = self.core.missions, self.core
        assert mm.mission is not None
        return MissionStatus.make(stamp_ns=t_ns, state="active", mission_id=mm.mission.mission_id,
                                  active_leg=mm.active, waypoint_count=len(mm.mission.waypoints_m),
                                  energy_used_j=core.energy_used_j,
                                  reason=f"simulated time holds: {self.solver_progress(kind)}")

    # -- inputs ----------------------------------------------------------------------------------

    def _keep_state(self, state: StateEstimate) -> None:
        """Lockstep: a state, kept by stamp until an estimator's answer names it."""
        with self._states_lock:
            self._states[state.stamp_ns] = state
            if len(self._states) > STATES_KEPT:
                # The first to arrive goes, not the lowest stamp: the first state of a new episode
                # (stamped 0) can arrive before the driver has seen the episode and dropped the old
                # one's states (stamped up to its end), and it was the one dropped. A mission sent
                # after a restart then flew t_0 with "no-state" zero thrust, a period late.
                del self._states[next(iter(self._states))]

    def on_battery(self, msg: BatteryState, now_ns: int | None) -> None:
        """The battery's report: the energy budget counts down from it (``ControllerCore.on_battery``)."""
        if now_ns is not None and not self.stamps.admit(keys.VEHICLE_BATTERY.suffix, msg.stamp_ns,
                                                        now_ns):
            return  # stamped ahead of now: wrong (seaway.runtime.stamps)
        with self.lock:
            self.core.on_battery(msg)

    def on_vehicle_status(self, msg: VehicleStatus, now_ns: int | None) -> None:
        if now_ns is not None and not self.stamps.admit(keys.VEHICLE_STATUS.suffix, msg.stamp_ns,
                                                        now_ns):
            return  # stamped ahead of now: wrong (seaway.runtime.stamps)
        with self.lock:
            paused = self.core.on_vehicle_status(msg)
            self._remember_leg()
        if paused:
            self.save_checkpoint(force=True)

    # -- real time -------------------------------------------------------------------------------

    def step(self, now_ns: int, state: StateEstimate, mono_ns: int | None = None) -> None:
        """Real time: one control step for ``state`` at ``now_ns`` (wall clock) and ``mono_ns``
        (monotonic), its messages published."""
        out = self.out
        assert out is not None
        try:
            with self.lock:
                cmd, record, status = self.core.step(now_ns, state, mono_ns)
                budget = self.core.take_budget()
                making = self.solver_pending()
                self._remember_leg()
            if making is not None and not status.reason:  # flown by the reference meanwhile
                status = status.model_copy(update={
                    "reason": f"flying with the reference IPOPT: {self.solver_progress(making)}"})
        except Exception:  # a bug must not leave the vessel without a command
            self.ratelog.exception("step", "control step failed; commanding zero thrust")
            with self.lock:
                cmd = self.core.zero_command(state.stamp_ns, "error")
            self._step_ended()
            out.put(keys.THRUST, cmd)
            return
        self._step_ended()  # none is sent in its place after the step's own command
        out.put(keys.THRUST, cmd)
        if record is not None:
            out.put(keys.SOLVE, record)
        out.put(keys.MISSION_STATUS, status)
        if budget is not None:
            out.put(keys.MISSION_ENERGY, budget)
        self.save_checkpoint()

    def _step_ended(self) -> None:
        if self.live is not None:
            self.live.keeper.end()

    def _remember_leg(self) -> None:
        """Keep what the keeper's fallback flies (under the lock, which a stuck step holds)."""
        self._flying = flying_of(self.core)

    def _overrun_command(self, state: StateEstimate, stop: bool) -> ThrustCommand | None:
        """The command sent in the place of the step for ``state`` (``RealTime.fallback``); on the
        keeper's thread, without the lock."""
        assert self.live is not None
        return self.live.fallback(state, self._newest, self.now_ns(), self._flying,
                                  self.core.vessel, self.core.config.los, stop)

    def announce(self, now_ns: int) -> None:
        """Real time: the mission just accepted, or the current one again once a second (for a
        recorder or ground station that joins late), on ``mission/accepted``."""
        assert self.out is not None
        with self.lock:
            accepted = self.core.accepted_due(now_ns)
        if accepted is not None:
            self.out.put(keys.MISSION_ACCEPTED, accepted)
        with self.lock:
            area = self.core.area.message(now_ns)
        if area is not None:
            self.out.put(keys.AREA_ACTIVE, area)

    def stop_thrusters(self, stamp_ns: int | None) -> None:
        """Real time, stopping in order: zero thrust now, as the last command.

        Without it the thrusters kept the last command until vehicle_io's watchdog saw the silence
        (``thrust_timeout_s`` later) and cut them with a WARNING, at every Ctrl-C of a mission in
        progress; after a zero command that trip is the expected end (vehicle_io logs it as INFO).
        ``stamp_ns``: the last state's (the command's stamp is its state's), else now."""
        assert self.out is not None
        stamp = stamp_ns if stamp_ns is not None else self.now_ns()
        with self.lock:
            cmd = self.core.zero_command(stamp, "stop")
        self.out.put(keys.THRUST, cmd)
        log.info("stopping: zero thrust commanded")

    # -- checkpoint ------------------------------------------------------------------------------

    def save_checkpoint(self, force: bool = False) -> None:
        """The mission checkpoint, if due (``checkpointing.Checkpoints.save``), on the node's clock."""
        if self.checkpoints.path is not None:
            self.checkpoints.save(self.core, self.lock, self.now_ns(), force)
