"""``seaway-controller``: the controller's configuration, and its node run (``seaway.runtime.node``).

The node (``seaway_controller.node``) says what the controller hears, publishes and answers; this
reads the command line and the run (``seaway.runtime.run``: the vessel model, the control period,
which is also the OCP's dt, and the origin), sets up the solvers, the operating area and a
checkpointed mission to resume, and hands the node to the runtime. ``--scenario NAME`` given as a
flag (not through ``--run``) also starts the scenario's mission at once (batch runs without a
launcher).

Solvers (``solvers.SolverBuilds``): the service is up, and serves requests, at once. The fast
solver a mission needs (its controller's, and no other) is made when the mission comes, on a
thread of its own: loaded from the cache, or compiled the first time on a machine (seconds to
minutes). Until it is ready, real time flies with the reference IPOPT (line-of-sight guidance while
IPOPT itself is set up, on a thread too: ``solvers.StagedSolver``; each of its solves runs in the
control loop and is stopped at the control period) and lockstep answers "hold"; the log says how
far it got.
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from seaway.area.files import run_area
from seaway.area.model import AreaError
from seaway.contract.config import ConfigError
from seaway.runtime.argtypes import positive_float, whole_number
from seaway.runtime.node import run_node
from seaway.runtime.service import base_parser, parse, resolve_run, run_service
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_controller import controllers
from seaway_controller.checkpointing import resume
from seaway_controller.core import ControllerConfig, ControllerCore
from seaway_controller.mission import MissionLimits
from seaway_controller.node import NAME, ControllerNode
from seaway_controller.solvers import SOLVER_KINDS, IpoptSolver, SolverBuilds, StagedSolver

log = logging.getLogger(__name__)


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
        node = ControllerNode(core, args.state_file, builds, args.max_state_age_s)
        run_node(ctx, node, period_s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
