"""``seaway-controller``: the thin loop around ``ControllerCore``.

Inputs: ``nav/state`` (StateEstimate), ``nav/origin`` (NavOrigin), ``vehicle/battery``
(BatteryState), ``vehicle/status`` (VehicleStatus), queryables ``mission/set`` (MissionRequest) and
``mission/command`` (MissionCommand), each answered with a Reply. In lockstep the state and origin
come in the estimator's bundle, the battery in the sim's (``seaway.contract.bundle``), and the
outputs go in the controller's own.
Outputs: ``ctrl/thrust`` (ThrustCommand, stamped with the state's stamp), ``ctrl/solve``
(SolveRecord, one per solve), ``mission/status`` (MissionStatus) and ``mission/accepted``
(MissionAccepted: the mission accepted, in local NED; real time: at once and every second, lockstep:
in the answer of the period that follows the acceptance).

Two ways to run:

* real time (the run's clock ``wall``): ticks every control period of the run on the wall clock;
  each tick uses the newest state if a new one arrived; a state older than ``--max-state-age-s``
  gives zero thrust; a step that overruns gets a command sent in its place, once a period
  (``keeper.ThrustKeeper``);
* lockstep (``seaway.runtime.lockstep``): one answer per period of the sim, once the estimator's
  bundle (its answer and the state) is in: the command for that state (zero thrust if the estimator
  has no state yet), or "hold" when there is nothing to fly (no mission, paused, over), which stops
  simulated time until a mission request makes the controller answer the period again. A new
  episode (the sim restarted or loaded a scenario) restarts a mission in progress from its first leg.

The vessel model, the control period (which is also the OCP's dt) and the origin come from the run
(``seaway.runtime.run``). ``--scenario NAME`` given as a flag (not through ``--run``) also starts
the scenario's mission at once (batch runs without a launcher).

Solvers (``solvers.SolverBuilds``): the service is up, and serves requests, at once. The fast
solver a mission needs (its controller's, and no other) is made when the mission comes, on a
thread of its own: loaded from the cache, or compiled the first time on a machine (seconds to
minutes); the mission starts once it is ready, or after ``SOLVER_REPLY_WAIT_S`` (a compile). Until
it is ready, real time flies with the reference IPOPT (line-of-sight guidance
while IPOPT itself is set up, on a thread too: ``solvers.StagedSolver``; each of its solves runs in
the control loop and is stopped at the control period) and lockstep answers "hold"
(simulated time waits, so the run is the one a warm start gives); the mission/set reply and
``MissionStatus.reason`` say so, and the log says how far it got.

``--state-file PATH`` keeps a mission checkpoint (``checkpoint.py``): written whenever the mission's
progress changes and once a second of the service's own clock (simulated time in lockstep, where a
wall second can be a hundred periods), read at start, so that a controller restarted mid-mission (the
launcher restarts a crashed one) resumes the same mission at the same leg, with its energy count
and its energy budget's decision (a return home goes on as one), instead of idling. A checkpoint
saved before the run started (an earlier launch into the same run folder, ``seaway launch
--run-dir``) is not resumed. Real time writes it durably (fsync) on a thread of
its own (``seaway.runtime.atomic.LatestWriter``: the control loop never waits for the disk), and the
last one before the process ends; lockstep writes it in the answer's turn, not durably.
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from seaway.area.files import run_area
from seaway.area.model import AreaError
from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import (
    MAX_REASON_CHARS,
    BatteryState,
    HomeRequest,
    MissionCommand,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    PeriodDone,
    Reply,
    StateEstimate,
    ThrustCommand,
    VehicleStatus,
)
from seaway.runtime import atomic
from seaway.runtime.argtypes import positive_float, whole_number
from seaway.runtime.clock import RateLoop
from seaway.runtime.lockstep import Member, Period
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.run import from_earlier_launch
from seaway.runtime.service import ServiceContext, base_parser, parse, resolve_run, run_service
from seaway.runtime.stallwatch import StallWatch
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_controller import checkpoint, controllers
from seaway_controller.core import BudgetDecision, ControllerConfig, ControllerCore
from seaway_controller.keeper import ThrustKeeper, overrun_command
from seaway_controller.mission import MissionLimits
from seaway_controller.solvers import SOLVER_KINDS, IpoptSolver, SolverBuilds, StagedSolver

log = logging.getLogger("seaway_controller.service")
NAME = "controller"
CHECKPOINT_PERIOD_NS = 1_000_000_000
"""An unchanged mission is re-saved this often (for its energy count), on the service's clock:
wall time live, simulated time in lockstep. What a restart can lose is the energy of this long."""
CHECKPOINT_CLOSE_S = 5.0
"""How long a stopping controller waits for its last checkpoint to be written (real time) [s]."""


STEP_STALL_S = 1.0
"""Real time: a control step still running after this long is logged with the loop's stack
(``seaway.runtime.stallwatch``) [s]: past vehicle_io's thrust watchdog, well before the launcher's
liveness restarts a controller silent on ``ctrl/thrust``, so the log says where it hung."""


SOLVER_REPLY_WAIT_S = 2.0
"""How long a mission waits for its solver before it starts: enough to load a cached one, so that
only a compile still under way is flown on the fallbacks and worth a word in the reply [s]."""


def build_parser() -> argparse.ArgumentParser:
    p = base_parser(NAME, "Mission manager and CC-EMPC / EO-EMPC / NMPC controller.")
    p.add_argument("--solver", choices=SOLVER_KINDS, default="generated",
                   help="generated: compiled SQP (fast); ipopt: plain IPOPT (reference)")
    p.add_argument("--predict-disturbance", action="store_true",
                   help="predict with the estimator's tau_d instead of tau_d = 0 (the paper's)")
    p.add_argument("--max-state-age-s", type=positive_float, default=0.5,
                   help="real time: older states give zero thrust")
    p.add_argument("--plan-reuse-steps", type=whole_number(0), default=3,
                   help="fallback 1: periods of failed solves flown on the last good plan (default 3)")
    p.add_argument("--los-steps", type=whole_number(0), default=600,
                   help="fallback 2: periods of line-of-sight guidance after that, before zero thrust "
                        "(default 600)")
    p.add_argument("--state-file", type=Path, default=None,
                   help="mission checkpoint: resume from it at start, keep it up to date")
    p.add_argument("--max-range-m", type=positive_float, default=5000.0,
                   help="operating area: waypoints within this distance of the origin")
    p.add_argument("--controller-module", action="append", default=[], metavar="FILE|MODULE",
                   help="a controller of one's own: a .py file or an importable module that "
                        "registers it (seaway_controller.controllers.load_module); repeatable")
    p.add_argument("--area", type=Path, default=None,
                   help="the operating area to enforce (.toml [area], .plan geoFence, .geojson); "
                        "default: the run's scenario's [area], else none")
    return p


class ControllerService:
    """Owns the core, its lock and the bus endpoints; the loops are ``run_lockstep``/``run_rate``."""

    def __init__(self, ctx: ServiceContext, core: ControllerCore, lockstep: bool,
                 state_file: Path | None = None, builds: SolverBuilds | None = None) -> None:
        self.ctx, self.core = ctx, core
        self.state_file = state_file
        # The fast solvers being made in the background (None: the core makes its own at once).
        self.builds = builds
        if builds is not None:
            builds.on_done = self.on_solver_done
        self._saved: tuple | None = None  # (mission id, leg, state, decision) last written
        self._saved_at_ns: int | None = None  # when, on the service's clock
        # Real time writes it durably, on a thread of its own: an fsync can take a second beside
        # another process's large write (seaway.runtime.atomic.LatestWriter), and the control loop
        # must not wait for it. Lockstep writes it here, not durably (checkpoint.save says why).
        self._writer = (atomic.LatestWriter(state_file, self._checkpoint_failed, "checkpoint")
                        if state_file is not None and not lockstep else None)
        self.lock = threading.Lock()
        # Before any subscription: a callback can run on the bus's thread the moment its
        # subscription exists, before this constructor returns, and uses these.
        self.stamps = StampGate(NAME, log, StampBounds.live())  # real time: states not ahead of now
        self.ratelog = RateLimitedLog(log)  # a step failing every period: a traceback now and then
        # Real time: a step stuck for long is logged with where it is, before a restart ends it.
        self.watch = StallWatch(log, "control loop", STEP_STALL_S, ctx.stop)
        # Real time: a step that overruns gets a command sent in its place (keeper.py), on time.
        self.keeper: ThrustKeeper | None = None  # made by run_rate, which knows the period
        self._flying: tuple | None = None  # (leg, speed hint, seq) as of the last step or request
        bus = ctx.bus
        self.member: Member | None = None
        self._states: dict[int, StateEstimate] = {}  # lockstep: the states of recent periods by stamp
        self._rethink = False  # lockstep: a mission request came while the current answer was hold
        self._answered: PeriodDone | None = None  # lockstep: the last answer given
        self._restarts: list[Period] = []  # lockstep: new episodes not yet acted on
        self._step_lock = threading.Lock()  # lockstep: one answer at a time (bus thread or loop)
        if lockstep:
            # The state and origin come in the estimator's bundle, which moves the controller on;
            # the battery in the sim's (once a second), sent before the estimator's and taken with
            # it. State and battery are listed, so the budget prices from the same inputs in a
            # replay; the origin is taken when it comes.
            self.member = Member(bus, NAME, watched={keys.NAV_STATE.suffix,
                                                     keys.VEHICLE_BATTERY.suffix},
                                 inputs={keys.NAV_STATE.suffix, keys.VEHICLE_BATTERY.suffix,
                                         keys.NAV_ORIGIN.suffix},
                                 hears=("sim", "estimator"), passive=("sim",))
            self.member.deliver = self._on_input
        else:  # real time acts on the newest state
            self.states = bus.subscribe(keys.NAV_STATE, mode="latest")
            bus.subscribe(keys.VEHICLE_BATTERY, callback=self.on_battery)
            bus.subscribe(keys.NAV_ORIGIN, callback=self.on_origin)
        self.pub_thrust = bus.publisher(keys.THRUST)
        self.pub_solve = bus.publisher(keys.SOLVE)
        self.pub_status = bus.publisher(keys.MISSION_STATUS)
        self.pub_accepted = bus.publisher(keys.MISSION_ACCEPTED)
        self.pub_energy = bus.publisher(keys.MISSION_ENERGY)
        self.pub_area = bus.publisher(keys.AREA_ACTIVE)
        bus.queryable(keys.MISSION_SET, self.on_mission)
        bus.queryable(keys.MISSION_COMMAND, self.on_command)
        bus.queryable(keys.MISSION_HOME, self.on_home)
        bus.subscribe(keys.VEHICLE_STATUS, callback=self.on_vehicle_status)  # pauses a mission

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
            meanwhile = ("simulated time holds until it is ready" if self.member is not None
                         else "flying with the reference IPOPT meanwhile")
            reply = reply.model_copy(update={"reason": f"{reply.reason}; {making}: {meanwhile}"})
        return reply

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
        if self.member is not None:
            with self.member.changed:
                self._rethink = True
                self.member.version += 1
                self.member.changed.notify_all()

    def on_command(self, cmd: MissionCommand) -> Reply:
        return self._serve(f"{keys.MISSION_COMMAND.suffix} {cmd.command}", self.core.handle_command, cmd)

    def on_home(self, req: HomeRequest) -> Reply:
        return self._serve(keys.MISSION_HOME.suffix, self.core.handle_home, req)

    def _serve(self, what: str, handle: Callable[[int, Any], Reply], request: Any) -> Reply:
        """One mission request: the core decides under the lock, the reply is logged, progress saved.

        In lockstep the request is taken at the current period, whose answer is then thought again
        if it was "hold" (nothing to fly until now)."""
        with self.lock:
            reply = handle(self._now_ns(), request)
            self._remember_leg()
        log.info("%s: %s %s", what, "accepted" if reply.accepted else "REFUSED", reply.reason)
        self.save_checkpoint(force=True)
        if self.member is not None and reply.accepted:
            with self.member.changed:
                self._rethink = True
                self.member.version += 1
                self.member.changed.notify_all()
        return reply

    def _now_ns(self) -> int:
        """Wall time live; the current period in lockstep (the sim does not move without us)."""
        if self.member is None:
            return self.ctx.clock.now_ns()
        period = self.member.ledger.period
        return period.stamp_ns if period is not None else 0

    def save_checkpoint(self, force: bool = False) -> None:
        """Write the checkpoint if the progress changed, or ``CHECKPOINT_PERIOD_NS`` passed on the
        service's clock (for the energy count; time going back is a new episode: saved too)."""
        if self.state_file is None:
            return
        with self.lock:
            progress = self.core.progress()
        if progress is None:
            return
        req, leg, state, energy = progress
        with self.lock:
            decision = self.core.decision()
            hold = self.core.missions.hold_point
        key = (req.mission_id, leg, state, decision, hold)
        now_ns = self._now_ns()
        last = self._saved_at_ns
        due = last is None or not 0 <= now_ns - last < CHECKPOINT_PERIOD_NS
        if not force and key == self._saved and not due:
            return
        cp = checkpoint.MissionCheckpoint(
            request=req.model_dump(mode="json"), active_leg=leg, state=state,  # type: ignore[arg-type]
            energy_used_j=energy, saved_unix_ns=time.time_ns(), returning=decision.returning,
            decision=decision.decision, decided_ns=decision.decided_ns,
            decision_reason=decision.reason[:MAX_REASON_CHARS],
            hold_x_m=None if hold is None else hold[0], hold_y_m=None if hold is None else hold[1])
        if self._writer is not None:
            self._writer.submit(checkpoint.encode(cp))
        else:
            try:
                checkpoint.save(self.state_file, cp, durable=False)
            except OSError as err:
                self._checkpoint_failed(err)
                return
        self._saved, self._saved_at_ns = key, now_ns

    def _checkpoint_failed(self, err: OSError) -> None:
        # The vessel keeps being controlled; only a restart would suffer.
        log.error("cannot write the mission checkpoint %s: %s", self.state_file, err)

    def close(self) -> None:
        """The last checkpoint given, written before the process ends."""
        if self._writer is not None and not self._writer.close(CHECKPOINT_CLOSE_S):
            log.error("the mission checkpoint %s was not written within %g s of the stop",
                      self.state_file, CHECKPOINT_CLOSE_S)

    def on_vehicle_status(self, _key: str, msg: VehicleStatus) -> None:
        if self.member is None and not self.stamps.admit(keys.VEHICLE_STATUS.suffix, msg.stamp_ns,
                                                         self.ctx.clock.now_ns()):
            return  # stamped ahead of now: wrong (seaway.runtime.stamps)
        with self.lock:
            paused = self.core.on_vehicle_status(msg)
            self._remember_leg()
        if paused:
            self.save_checkpoint(force=True)

    def on_battery(self, _key: str, msg: BatteryState) -> None:
        """The battery's report: the energy budget counts down from it (``ControllerCore.on_battery``)."""
        member = self.member
        if member is None:
            if not self.stamps.admit(keys.VEHICLE_BATTERY.suffix, msg.stamp_ns,
                                     self.ctx.clock.now_ns()):
                return  # stamped ahead of now: wrong (seaway.runtime.stamps)
            with self.lock:
                self.core.on_battery(msg)
            return
        if not member.admit(keys.VEHICLE_BATTERY.suffix, msg.stamp_ns):
            return
        with self.lock:
            self.core.on_battery(msg)
        member.saw(keys.VEHICLE_BATTERY.suffix, msg.stamp_ns)

    def on_origin(self, _key: str, msg: NavOrigin) -> None:
        with self.lock:
            self.core.set_origin(GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m))

    def step(self, now_ns: int, state: StateEstimate) -> None:
        try:
            with self.lock:
                cmd, record, status = self.core.step(now_ns, state)
                budget = self.core.take_budget()
                making = self.solver_pending()
                self._remember_leg()
            if making is not None and not status.reason:  # flown by the reference meanwhile
                status = status.model_copy(update={
                    "reason": f"flying with the reference IPOPT: {self.solver_progress(making)}"})
        except Exception:  # a bug must not leave the vessel (or a lockstep sim) without a command
            self.ratelog.exception("step", "control step failed; commanding zero thrust")
            with self.lock:
                cmd = self.core.zero_command(state.stamp_ns, "error")
            self._step_ended()
            self.pub_thrust.put(cmd)
            return
        self._step_ended()  # none is sent in its place after the step's own command
        self.pub_thrust.put(cmd)
        if record is not None:
            self.pub_solve.put(record)
        self.pub_status.put(status)
        if budget is not None:
            self.pub_energy.put(budget)
        self.save_checkpoint()

    def _remember_leg(self) -> None:
        """Keep what the keeper's fallback flies (under the lock, which a stuck step holds): the
        active mission's leg and speed hint, and the last command's sequence number."""
        mm = self.core.missions
        flying = mm.state == "active" and mm.mission is not None
        self._flying = ((mm.leg(), mm.mission.speed_hint_mps if mm.mission else None, self.core.seq)
                        if flying else (None, None, self.core.seq))

    def _overrun_command(self, state: StateEstimate, max_state_age_s: float,
                         stop: bool) -> ThrustCommand | None:
        """Real time: the command ``ThrustKeeper`` sends in the place of the step for ``state``
        (``keeper.overrun_command``): line-of-sight guidance on the leg flown at the last step,
        from the newest state heard (not ahead of now, not older than ``max_state_age_s`` [s]:
        else zero thrust); ``stop``: zero thrust. Runs on the keeper's thread, without the lock."""
        leg, hint, seq = self._flying or (None, None, 0)
        newest, now = self.states.latest(), self.ctx.clock.now_ns()
        if newest is not None and state.stamp_ns <= newest.stamp_ns <= now:
            state = newest
        stale = (now - state.stamp_ns) / 1e9 > max_state_age_s
        return overrun_command(state, leg, self.core.vessel, self.core.config.los, hint, seq,
                               stop=stop or stale)

    def _step_ended(self) -> None:
        if self.keeper is not None:
            self.keeper.end()

    # -- lockstep (seaway.runtime.lockstep) ------------------------------------------------------

    def _on_input(self, key: str, msg: Any) -> None:
        """An input from a bundle (``Member.deliver``): the state, the battery or the origin."""
        if isinstance(msg, StateEstimate):
            self._on_state(key, msg)
        elif isinstance(msg, BatteryState):
            self.on_battery(key, msg)
        elif isinstance(msg, NavOrigin):
            self.on_origin(key, msg)

    def _on_state(self, _key: str, state: StateEstimate) -> None:
        member = self.member
        assert member is not None
        if not member.admit(keys.NAV_STATE.suffix, state.stamp_ns):
            return  # beyond any period to come soon: counted and logged by the member
        with member.changed:
            self._states[state.stamp_ns] = state
            if len(self._states) > 16:
                # The first to arrive goes, not the lowest stamp: the first state of a new episode
                # (stamped 0) can arrive before this loop has seen the episode and dropped the old
                # one's states (stamped up to its end), and it was the one dropped. A mission sent
                # after a restart then flew t_0 with "no-state" zero thrust, a period late.
                del self._states[next(iter(self._states))]
        member.saw(keys.NAV_STATE.suffix, state.stamp_ns)

    def run_lockstep(self) -> None:
        """Answer each period once the estimator has (with the state it lists, if any): on the
        bus's thread as the estimator's bundle is taken (``Member.on_ready``), else from this loop
        (a mission request, a solver made, a passive bundle that came late)."""
        member = self.member
        assert member is not None
        member.on_restart = lambda _before, now: self._restarts.append(now)
        member.on_ready = self.lockstep_step
        version = 0
        while not self.ctx.stop.is_set():
            version = member.wait(version, 0.1)
            self.lockstep_step()

    def lockstep_step(self) -> None:
        """Answer the current period if it can be and has not been (or was held and a mission came
        since); one caller at a time."""
        member = self.member
        assert member is not None
        with self._step_lock:
            with member.changed:
                period = member.ledger.period
                est = member.ledger.answer("estimator")
                complete = member.ledger.complete(est) and member.ledger.complete(
                    member.ledger.answer("sim"))
                restart = bool(self._restarts)
                self._restarts.clear()
                rethink = self._rethink
            if restart and period is not None:
                self.new_episode(period)
                self._answered = None
            if est is None or not complete or period is None:
                # Not now; a mission or a solver that came meanwhile is still to be thought of when
                # the period can be answered (consumed here, a hold answered just before stood for
                # good: a repeat only repeats it, and a run of the default suite stalled at t = 0).
                return
            answered = self._answered
            if answered is not None and Period.of(answered) == period and not (
                    answered.hold and rethink):
                if not answered.hold:
                    with member.changed:
                        self._rethink = False  # the period is flown: nothing held to think again
                return
            with member.changed:
                self._rethink = False  # answered now, with whatever came
            with member.changed:  # later states can only be late ones of an earlier episode
                self._states = {k: v for k, v in self._states.items() if k <= period.stamp_ns}
            stamps = est.published.get(keys.NAV_STATE.suffix, [])
            state = self._states.get(stamps[-1]) if stamps else None
            self._answered = self.answer_period(member, period, est.period_ns, state)

    def answer_period(self, member: Member, period: Period, period_ns: int,
                      state: StateEstimate | None) -> PeriodDone:
        """Period t_k's answer: the command for the state, or hold when there is nothing to fly.

        Without a state (the estimator is not initialised) an active mission gets zero thrust, so
        that time goes on to the next measurements; idle, paused or over, the answer is hold; so it
        is while the mission's solver is still being made (answered again once it is ready)."""
        t = period.stamp_ns
        member.working(period)
        out: list[tuple[keys.KeySpec, Any]] = []
        with self.lock:  # a mission accepted since the last answer: first of this period's messages
            accepted = self.core.take_accepted(t)
        announce = [] if accepted is None else [(keys.MISSION_ACCEPTED, accepted)]
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
        done = member.answer(period, period_ns, announce + out, hold=not active)
        self.save_checkpoint()
        return done

    def _held_status(self, t_ns: int, kind: str) -> MissionStatus:
        """The status of an active mission held while its solver is being made (under the lock)."""
        mm, core = self.core.missions, self.core
        assert mm.mission is not None
        return MissionStatus.make(stamp_ns=t_ns, state="active", mission_id=mm.mission.mission_id,
                                  active_leg=mm.active, waypoint_count=len(mm.mission.waypoints_m),
                                  energy_used_j=core.energy_used_j,
                                  reason=f"simulated time holds: {self.solver_progress(kind)}")

    def new_episode(self, period: Period) -> None:
        """The sim restarted, or loaded a scenario: a mission in progress starts again from its first
        leg (the vessel is back at its start); one that is over stays over."""
        with self.lock:
            progress = self.core.progress()
            if progress is None or progress[2] not in ("active", "paused"):
                return
            req = progress[0]
            reply = self.core.handle_mission(period.stamp_ns, req, check=False)
        with self.member.changed:  # type: ignore[union-attr]
            self._states = {k: v for k, v in self._states.items() if k <= period.stamp_ns}
        log.warning("lockstep episode %d (time back to %.3f s): mission %r restarted: %s",
                    period.episode, period.stamp_ns / 1e9, req.mission_id, reply.reason)
        self.save_checkpoint(force=True)

    def run_rate(self, rate_hz: float, max_state_age_s: float) -> None:
        sub = self.states
        loop = RateLoop(1.0 / rate_hz, self.ctx.clock, self.ctx.stop)
        self.keeper = ThrustKeeper(self.pub_thrust.put, 1.0 / rate_hz, log, self.ctx.stop)
        last_stamp: int | None = None
        stale_reported = False
        while loop.wait():
            now = self.ctx.clock.now_ns()
            self.announce(now)
            state = sub.latest()
            if state is not None and not self.stamps.admit(keys.NAV_STATE.suffix, state.stamp_ns, now):
                state = None  # stamped ahead of now: wrong, never acted on (seaway.runtime.stamps)
            if state is not None and state.stamp_ns != last_stamp:
                last_stamp = state.stamp_ns
                if (now - state.stamp_ns) / 1e9 <= max_state_age_s:
                    stale_reported = False
                    t0 = time.perf_counter()
                    self.watch.begin()
                    self.keeper.begin(functools.partial(self._overrun_command, state,
                                                        max_state_age_s))
                    try:
                        self.step(now, state)
                    finally:
                        self.keeper.end()
                        self.watch.end()
                    warn_slow_step(self.ratelog, time.perf_counter() - t0, 1.0 / rate_hz)
                    continue
            if last_stamp is not None and (now - last_stamp) / 1e9 > max_state_age_s:
                # No fresh state: hold still rather than act on old information.
                if not stale_reported:
                    log.warning("%s older than %.2f s: commanding zero thrust",
                                keys.NAV_STATE.suffix, max_state_age_s)
                    stale_reported = True
                self.pub_thrust.put(self.core.zero_command(last_stamp, "stale-state"))
        self.stop_thrusters(last_stamp)

    def stop_thrusters(self, stamp_ns: int | None) -> None:
        """Real time, stopping in order: zero thrust now, as the last command.

        Without it the thrusters kept the last command until vehicle_io's watchdog saw the silence
        (``thrust_timeout_s`` later) and cut them with a WARNING, at every Ctrl-C of a mission in
        progress; after a zero command that trip is the expected end (vehicle_io logs it as INFO).
        ``stamp_ns``: the last state's (the command's stamp is its state's), else now."""
        stamp = stamp_ns if stamp_ns is not None else self.ctx.clock.now_ns()
        with self.lock:
            cmd = self.core.zero_command(stamp, "stop")
        self.pub_thrust.put(cmd)
        log.info("stopping: zero thrust commanded")

    def announce(self, now_ns: int) -> None:
        """Real time: the mission just accepted, or the current one again once a second (for a
        recorder or ground station that joins late), on ``mission/accepted``."""
        with self.lock:
            accepted = self.core.accepted_due(now_ns)
        if accepted is not None:
            self.pub_accepted.put(accepted)
        with self.lock:
            area = self.core.area.message(now_ns)
        if area is not None:
            self.pub_area.put(area)


def warn_slow_step(ratelog: RateLimitedLog, took_s: float, period_s: float) -> bool:
    """Real time: a WARNING (rate-limited) when one control step took ``took_s`` [s], longer than
    the control period ``period_s`` [s], so that a late or missing command names its cause in the
    log. True if the step was slow."""
    if took_s <= period_s:
        return False
    ratelog.warning("slow-step", "a control step took %.3f s, longer than the control period "
                    "(%.3f s): the thrust command came late; the solve records (%s) say "
                    "which solver ran", took_s, period_s, keys.SOLVE.suffix)
    return True


def resume(core: ControllerCore, path: Path, now_ns: int, run_file: str | Path | None = None
           ) -> None:
    """Resume the checkpointed mission, if there is one in progress and it was saved in this run
    (not before ``run_file`` was written: ``seaway.runtime.run.from_earlier_launch``); never fatal."""
    try:
        cp = checkpoint.load(path)
        if cp is None:
            return
        if from_earlier_launch(cp.saved_unix_ns, run_file):
            log.info("checkpoint %s: mission %s was saved before this run started (an earlier "
                     "launch into this folder); starting idle", path,
                     cp.request.get("mission_id", "?"))
            return
        # A finished mission is taken up again only to go on holding station at its end.
        holding = cp.state == "complete" and cp.hold_point is not None
        if cp.state not in ("waiting", "active", "paused") and not holding:
            log.info("checkpoint %s: mission %s was %s; starting idle", path,
                     cp.request.get("mission_id", "?"), cp.state)
            return
        req = cp.mission_request()
    except checkpoint.CheckpointError as err:
        log.error("ignoring the mission checkpoint: %s", err)
        return
    decision = BudgetDecision(cp.returning, cp.decision, cp.decided_ns, cp.decision_reason)
    reply = core.restore(now_ns, req, cp.active_leg, cp.state, cp.energy_used_j, decision,
                         cp.hold_point)
    if reply.accepted:
        log.warning("resumed mission %r from %s at leg %d (%s), %.1f J used before the restart; "
                    "energy budget: %s%s", req.mission_id, path, cp.active_leg, cp.state,
                    cp.energy_used_j, cp.decision, " (returning home)" if cp.returning else "")
    else:
        log.error("could not resume mission %r from %s: %s", req.mission_id, path, reply.reason)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(build_parser(), argv)
    for module in args.controller_module:  # before the run's scenario or a checkpoint names it
        try:
            log.info("controller module %s: registered %s", module,
                     ", ".join(controllers.load_module(module)))
        except controllers.ControllerModuleError as err:
            print(f"seaway-controller: --controller-module: {err}", file=sys.stderr)
            return 2
    run = resolve_run(args, NAME, load_scenario)
    # A scenario named by flag (a batch run without a launcher) also starts its mission at once.
    scenario = load_scenario(args.scenario) if args.scenario and not args.run else None
    try:
        vessel = load_vessel(run.model_vessel_file)
    except ConfigError as err:
        print(f"seaway-controller: {err}", file=sys.stderr)
        return 2
    period_s = run.control_period_s
    config = ControllerConfig(solver=args.solver, plan_reuse_steps=args.plan_reuse_steps,
                              los_steps=args.los_steps,
                              predict_disturbance=args.predict_disturbance,
                              dt_s=period_s,
                              # Lockstep waits for every command, so a slow solve is never late,
                              # and a batch run must not depend on how busy the machine was.
                              solve_budget_s=None if run.lockstep else period_s,
                              limits=MissionLimits(max_range_m=args.max_range_m))
    with run_service(NAME, args, run=run) as ctx:
        # Only the solver a mission needs is made, when the mission comes, in the background: the
        # service is up (and answers requests) at once, also while a first compile takes minutes.
        builds = None
        factory = None
        if args.solver == "generated":
            builds = SolverBuilds(stopping=ctx.stop)
            # Real time solves the reference on the control loop's thread: bounded by the period.
            reference = (IpoptSolver if run.lockstep
                         else functools.partial(IpoptSolver, time_limit_s=period_s))
            factory = lambda ocp: StagedSolver(ocp, builds, reference,  # noqa: E731
                                               wait=run.lockstep)
        core = ControllerCore(vessel, config, solver_factory=factory)
        log.info("solver %s, made per mission; model %s, control period (OCP dt) %g s, %s clock",
                 args.solver, run.model_vessel_file, period_s, run.clock)
        if run.origin is not None:
            o = run.origin
            core.set_origin(GeoOrigin.from_degrees(o.lat_deg, o.lon_deg, o.alt_m))
        try:
            run_scenario = scenario or (load_scenario(run.scenario) if run.scenario else None)
            area, source = run_area(run_scenario, args.area, core.origin)
        except (AreaError, ConfigError) as err:
            print(f"seaway-controller: --area: {err}", file=sys.stderr)
            return 2
        if run_scenario is not None:
            core.battery_at_start_j = run_scenario.battery.start_j(vessel.battery)
        if area is not None:
            core.area.set_area(area, source, None if run.lockstep else ctx.clock.now_ns())
            log.info("operating area from %s enforced", source)
        if scenario is not None:
            if scenario.mission is None:
                log.error("scenario %s has no [mission] to start", scenario.name)
                return 2
            reply = core.handle_mission(ctx.clock.now_ns(),
                                        scenario.mission.to_request(0, mission_id=scenario.name))
            if not reply.accepted:
                log.error("scenario %s mission refused: %s", scenario.name, reply.reason)
                return 2
        if args.state_file is not None:
            resume(core, args.state_file, ctx.clock.now_ns(), args.run)
        svc = ControllerService(ctx, core, run.lockstep, args.state_file, builds)
        ctx.ready()
        if svc.member is not None:
            svc.member.join()
        try:
            if run.lockstep:
                svc.run_lockstep()
            else:
                svc.run_rate(1.0 / period_s, args.max_state_age_s)
        finally:
            svc.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
