"""``seaway-controller``: the thin loop around ``ControllerCore``.

Inputs: ``nav/state`` (StateEstimate), ``nav/origin`` (NavOrigin), queryables ``mission/set``
(MissionRequest) and ``mission/command`` (MissionCommand), each answered with a Reply.
Outputs: ``ctrl/thrust`` (ThrustCommand, stamped with the state's stamp), ``ctrl/solve``
(SolveRecord, one per solve) and ``mission/status`` (MissionStatus).

Two ways to run:

* real time (default): ticks at ``--rate-hz`` (10 Hz) on the wall clock; each tick uses the newest
  state if a new one arrived; a state older than ``--max-state-age-s`` gives zero thrust;
* ``--lockstep``: exactly one command per received state, whatever the wall clock does, and a
  command for every state (zero when idle), so that a lockstep simulator waiting for the command of
  its tick t_k (the estimator stamps nav/state with t_k) never stalls.

``--scenario NAME`` starts the scenario's mission at once (batch runs) and takes its vessel file and
geodetic origin.
"""

from __future__ import annotations

import argparse
import logging
import math
import threading
import time
from collections.abc import Sequence

from seaway import keys
from seaway.clock import RateLoop
from seaway.frames import GeoOrigin
from seaway.messages import MissionCommand, MissionRequest, NavOrigin, Reply, StateEstimate
from seaway.model import load_vessel
from seaway.scenario import load_scenario
from seaway.service import ServiceContext, base_parser, parse, run_service

from seaway_controller.closed_loop import scenario_mission_request
from seaway_controller.core import ControllerConfig, ControllerCore
from seaway_controller.mission import MissionLimits
from seaway_controller.ocp import CONTROLLER_KINDS
from seaway_controller.solvers import SOLVER_KINDS

log = logging.getLogger("seaway_controller.service")
NAME = "controller"
DEFAULT_VESSEL_FILE = "paper-sim"


def build_parser() -> argparse.ArgumentParser:
    p = base_parser(NAME, "Mission manager and CC-EMPC / EO-EMPC / NMPC controller.")
    p.add_argument("--lockstep", action="store_true",
                   help="one command per received nav/state instead of the wall-clock rate")
    p.add_argument("--scenario", default=None, help="start this scenario's mission at once")
    p.add_argument("--vessel-file", default=None,
                   help=f"vessel parameters (deploy/vessels name or path; default: the scenario's "
                        f"or {DEFAULT_VESSEL_FILE})")
    p.add_argument("--solver", choices=SOLVER_KINDS, default="generated",
                   help="generated: compiled SQP (fast); ipopt: plain IPOPT (reference)")
    p.add_argument("--predict-disturbance", action="store_true",
                   help="predict with the estimator's tau_d instead of tau_d = 0 (the paper's)")
    p.add_argument("--rate-hz", type=float, default=10.0)
    p.add_argument("--max-state-age-s", type=float, default=0.5,
                   help="real time: older states give zero thrust")
    p.add_argument("--plan-reuse-steps", type=int, default=3)
    p.add_argument("--los-steps", type=int, default=600)
    p.add_argument("--max-range-m", type=float, default=5000.0,
                   help="operating area: waypoints within this distance of the origin")
    return p


class ControllerService:
    """Owns the core, its lock and the bus endpoints; the loops are ``run_lockstep``/``run_rate``."""

    def __init__(self, ctx: ServiceContext, core: ControllerCore, lockstep: bool) -> None:
        self.ctx, self.core = ctx, core
        # Lockstep answers every state in order; real time acts on the newest.
        self.states = ctx.bus.subscribe(keys.NAV_STATE, mode="fifo" if lockstep else "latest")
        self.lock = threading.Lock()
        bus = ctx.bus
        self.pub_thrust = bus.publisher(keys.THRUST)
        self.pub_solve = bus.publisher(keys.SOLVE)
        self.pub_status = bus.publisher(keys.MISSION_STATUS)
        bus.queryable(keys.MISSION_SET, self.on_mission)
        bus.queryable(keys.MISSION_COMMAND, self.on_command)
        bus.subscribe(keys.NAV_ORIGIN, callback=self.on_origin)

    def on_mission(self, req: MissionRequest) -> Reply:
        with self.lock:
            reply = self.core.handle_mission(self.ctx.clock.now_ns(), req)
        log.info("mission/set %r: %s %s", req.mission_id,
                 "accepted" if reply.accepted else "REFUSED", reply.reason)
        return reply

    def on_command(self, cmd: MissionCommand) -> Reply:
        with self.lock:
            reply = self.core.handle_command(self.ctx.clock.now_ns(), cmd)
        log.info("mission/command %s: %s %s", cmd.command,
                 "accepted" if reply.accepted else "REFUSED", reply.reason)
        return reply

    def on_origin(self, _key: str, msg: NavOrigin) -> None:
        with self.lock:
            self.core.set_origin(GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m))

    def step(self, now_ns: int, state: StateEstimate) -> None:
        try:
            with self.lock:
                cmd, record, status = self.core.step(now_ns, state)
        except Exception:  # a bug must not leave the vessel (or a lockstep sim) without a command
            log.exception("control step failed; commanding zero thrust")
            with self.lock:
                self.pub_thrust.put(self.core.zero_command(state.stamp_ns, "error"))
            return
        self.pub_thrust.put(cmd)
        if record is not None:
            self.pub_solve.put(record)
        self.pub_status.put(status)

    def run_lockstep(self) -> None:
        sub = self.states
        while not self.ctx.stop.is_set():
            state = sub.get(0.1)
            if state is not None:
                self.step(state.stamp_ns, state)

    def run_rate(self, rate_hz: float, max_state_age_s: float) -> None:
        sub = self.states
        loop = RateLoop(1.0 / rate_hz, self.ctx.clock, self.ctx.stop)
        last_stamp: int | None = None
        stale_reported = False
        while loop.wait():
            now = self.ctx.clock.now_ns()
            state = sub.latest()
            if state is not None and state.stamp_ns != last_stamp:
                last_stamp = state.stamp_ns
                if (now - state.stamp_ns) / 1e9 <= max_state_age_s:
                    stale_reported = False
                    self.step(now, state)
                    continue
            if last_stamp is not None and (now - last_stamp) / 1e9 > max_state_age_s:
                # No fresh state: hold still rather than act on old information.
                if not stale_reported:
                    log.warning("nav/state older than %.2f s: commanding zero thrust",
                                max_state_age_s)
                    stale_reported = True
                self.pub_thrust.put(self.core.zero_command(last_stamp, "stale-state"))


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(build_parser(), argv)
    scenario = load_scenario(args.scenario) if args.scenario else None
    vessel = load_vessel(args.vessel_file or (scenario.vessel if scenario else DEFAULT_VESSEL_FILE))
    config = ControllerConfig(solver=args.solver, plan_reuse_steps=args.plan_reuse_steps,
                              los_steps=args.los_steps,
                              predict_disturbance=args.predict_disturbance,
                              dt_s=1.0 / args.rate_hz,
                              limits=MissionLimits(max_range_m=args.max_range_m))
    core = ControllerCore(vessel, config)
    with run_service(NAME, args) as ctx:
        t0 = time.perf_counter()
        core.prepare(CONTROLLER_KINDS)  # compile or load every solver before serving missions
        log.info("solvers ready (%s) in %.1f s", args.solver, time.perf_counter() - t0)
        if scenario is not None:
            o = scenario.origin
            core.set_origin(GeoOrigin(math.radians(o.lat_deg), math.radians(o.lon_deg), o.alt_m))
            reply = core.handle_mission(ctx.clock.now_ns(), scenario_mission_request(scenario))
            if not reply.accepted:
                log.error("scenario %s mission refused: %s", scenario.name, reply.reason)
                return 2
        svc = ControllerService(ctx, core, args.lockstep)
        ctx.ready()
        if args.lockstep:
            svc.run_lockstep()
        else:
            svc.run_rate(args.rate_hz, args.max_state_age_s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
