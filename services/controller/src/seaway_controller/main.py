"""``seaway-controller``: the controller's configuration, and its node run (``seaway.runtime.node``).

The node (``seaway_controller.node``) says what the controller hears, publishes and answers; this
reads the configuration (``seaway_controller.config``, made by ``seaway.runtime.config``: its
defaults, ``--config FILE``, its flags) and the run (``seaway.runtime.run``: the vessel model, the
control period, which is also the OCP's dt, and the origin), sets up the solvers, the operating area and a
checkpointed mission to resume, and hands the node to the runtime. ``--scenario NAME`` given as a
flag (not through ``--run``) also starts the scenario's mission at once (batch runs without a
launcher).

Solvers (``solver_builds.SolverBuilds``): the service is up, and serves requests, at once. The fast
solver a mission needs (its controller's, and no other) is made when the mission comes, on a
thread of its own: loaded from the cache, or compiled the first time on a machine (seconds to
minutes). Until it is ready, real time flies with the reference IPOPT (line-of-sight guidance while
IPOPT itself is set up, on a thread too: ``solver_builds.StagedSolver``; each of its solves runs in the
control loop and is stopped at the control period) and lockstep answers "hold"; the log says how
far it got.
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
from collections.abc import Sequence

from seaway.area.files import run_area
from seaway.area.model import AreaError
from seaway.contract.config import ConfigError
from seaway.runtime.config import parse_service_args, service_parser
from seaway.runtime.runner import run_node
from seaway.runtime.service import resolve_run, run_service
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_controller import controllers
from seaway_controller.checkpointing import resume
from seaway_controller.config import ControllerConfig, ControllerServiceConfig
from seaway_controller.core import ControllerCore
from seaway_controller.mission import MissionLimits
from seaway_controller.node import NAME, ControllerNode
from seaway_controller.solver_builds import SolverBuilds, StagedSolver
from seaway_controller.solvers import IpoptSolver

log = logging.getLogger(__name__)


def build_parser() -> argparse.ArgumentParser:
    return service_parser(NAME, "Mission manager and CC-EMPC / EO-EMPC / NMPC controller.",
                          ControllerServiceConfig)


def main(argv: Sequence[str] | None = None) -> int:
    args, settings = parse_service_args(build_parser(), argv, ControllerServiceConfig)
    for module in settings.controller_module:  # before the run's scenario or a checkpoint names it
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
    config = ControllerConfig(solver=settings.solver, plan_reuse_steps=settings.plan_reuse_steps,
                              los_steps=settings.los_steps,
                              predict_disturbance=settings.predict_disturbance,
                              dt_s=period_s,
                              # Lockstep waits for every command, so a slow solve is never late,
                              # and a batch run must not depend on how busy the machine was.
                              solve_budget_s=None if run.lockstep else period_s,
                              limits=MissionLimits(max_range_m=settings.max_range_m))
    with run_service(NAME, args, run=run) as ctx:
        # Only the solver a mission needs is made, when the mission comes, in the background: the
        # service is up (and answers requests) at once, also while a first compile takes minutes.
        builds = None
        factory = None
        if settings.solver == "generated":
            builds = SolverBuilds(stopping=ctx.stop)
            # Real time solves the reference on the control loop's thread: bounded by the period.
            reference = (IpoptSolver if run.lockstep
                         else functools.partial(IpoptSolver, time_limit_s=period_s))
            factory = lambda ocp: StagedSolver(ocp, builds, reference,  # noqa: E731
                                               wait=run.lockstep)
        core = ControllerCore(vessel, config, solver_factory=factory)
        log.info("solver %s, made per mission; model %s, control period (OCP dt) %g s, %s clock",
                 settings.solver, run.model_vessel_file, period_s, run.clock)
        if run.origin is not None:
            o = run.origin
            core.set_origin(GeoOrigin.from_degrees(o.lat_deg, o.lon_deg, o.alt_m))
        try:
            run_scenario = scenario or (load_scenario(run.scenario) if run.scenario else None)
            area, source = run_area(run_scenario, settings.area, core.origin)
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
        if settings.state_file is not None:
            resume(core, settings.state_file, ctx.clock.now_ns(), args.run)
        node = ControllerNode(core, settings.state_file, builds, settings.max_state_age_s)
        run_node(ctx, node, period_s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
