"""``seaway-sim``: the simulator (plant, disturbances, sensors, a PX4-like MAVLink endpoint).

Real time (the run's clock ``wall``): driven over MAVLink on ``--mavlink`` (``udpin:127.0.0.1:14580``).
Lockstep (``lockstep``): sim time, driven by ThrustCommand on the bus: the sim's node
(``seaway_sim.node``) is the clock of ``seaway.runtime.lockstep_clock``.
Both publish sim/truth, sim/disturbance and sim/clock and serve sim/scenario; lockstep also publishes
the battery (vehicle/battery, 1 Hz), which in real time the simulated PX4 reports over MAVLink.

The run description (``--run`` or the run flags) says which scenario to run (default ``lake``), which
vessel file the plant integrates (``plant_vessel_file``, else the model's) and the control period;
with ``--state-file``, a scenario loaded over the bus before a restart is flown instead
(``seaway_sim.kept``), and in real time the vessel is put back where the sim before left it
(``seaway_sim.plant_kept``).
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from seaway.contract.config import ConfigError
from seaway.mavlink.signing import KeyFileError, read_key
from seaway.runtime.config import parse_service_args, service_parser
from seaway.runtime.run import from_earlier_launch
from seaway.runtime.runner import run_node
from seaway.runtime.service import resolve_run, run_service
from seaway.simkit.faults import ThrusterFaults
from seaway.simkit.scenario import Scenario, load_scenario
from seaway.vessel.model import load_vessel

from seaway_sim import kept, plant_kept
from seaway_sim.battery import SimPack
from seaway_sim.config import START_SPACING_M, SimConfig, parse_params
from seaway_sim.core import SimCore
from seaway_sim.mavlink_link import MavlinkLink
from seaway_sim.node import SimNode
from seaway_sim.px4_autopilot import COMPID, Px4Autopilot, Px4Config
from seaway_sim.realtime import Realtime
from seaway_sim.world import world_of

log = logging.getLogger("seaway_sim")

DEFAULT_SCENARIO = "lake"  # the simulator's own default: only it runs a scenario
def build_parser() -> argparse.ArgumentParser:
    return service_parser("sim", "The Seaway simulator: vessel plant, disturbances, sensor noise "
                                 "and a PX4-like MAVLink endpoint (real time), or lockstep on the "
                                 "bus.", SimConfig)


def in_slot(scenario: Scenario, slot: int) -> Scenario:
    """``scenario`` started ``slot`` x ``START_SPACING_M`` east of its start; validated again (its
    operating area must hold the new start). ConfigError naming --start-slot otherwise."""
    if slot == 0:
        return scenario
    start = scenario.start.model_copy(update={"y_m": scenario.start.y_m + slot * START_SPACING_M})
    try:
        return Scenario.model_validate({**scenario.model_dump(), "start": start.model_dump()})
    except ValueError as err:
        raise ConfigError(f"--start-slot {slot}: scenario {scenario.name!r} cannot start "
                          f"{slot * START_SPACING_M:g} m east of its start: {err}") from None


def main(argv: Sequence[str] | None = None) -> int:
    args, cfg = parse_service_args(build_parser(), argv, SimConfig)
    if not args.run and args.scenario is None:
        args.scenario = DEFAULT_SCENARIO
    run = resolve_run(args, "sim", load_scenario)
    if run.scenario is None:
        print(f"seaway-sim: the run {run.run_id} names no scenario to simulate", file=sys.stderr)
        return 2
    try:
        scenario = load_scenario(run.scenario)
        vessel = load_vessel(run.plant_vessel)
        model = load_vessel(scenario.vessel)  # its limits: vehicle I/O's output stage in lockstep
        SimPack.of(scenario, vessel)  # the scenario's [battery] must fit the vessel's pack
        ThrusterFaults(scenario.faults, (-vessel.reverse_max_n, vessel.thrust_max_n))  # stuck thrusts fit
        scenario = in_slot(scenario, cfg.start_slot)
    except ConfigError as err:
        print(f"seaway-sim: {err}", file=sys.stderr)
        return 2
    resumed = stale = None
    if cfg.state_file is not None:
        try:
            resumed = kept.load(cfg.state_file)
            if resumed is not None and from_earlier_launch(resumed.saved_unix_ns, args.run):
                stale, resumed = resumed, None
            if resumed is not None:
                scenario, vessel, model = world_of(resumed.document, str(cfg.state_file), run)
        except (kept.KeptError, ConfigError) as err:
            print(f"seaway-sim: --state-file {cfg.state_file}: {err}\n(it keeps the scenario last "
                  f"loaded over the bus, for a restarted sim; remove it to start with the run's, "
                  f"{run.scenario})", file=sys.stderr)
            return 2
    lockstep, period_s = run.lockstep, run.control_period_s
    try:
        params = parse_params(cfg.px4_params)
        Px4Autopilot(Px4Config(thrust_max_n=1.0, param_overrides=params))  # validates them now
    except (ConfigError, ValueError) as err:
        print(f"seaway-sim: {err}", file=sys.stderr)
        return 2
    try:
        key = read_key(cfg.signing_key_file) if cfg.signing_key_file else None
    except KeyFileError as err:
        print(f"seaway-sim: --signing-key-file: {err}", file=sys.stderr)
        return 2
    link = None
    if lockstep and key is not None:
        log.warning("--signing-key-file ignored: lockstep does not speak MAVLink")
    if not lockstep and cfg.until_s is not None:
        print(f"seaway-sim: --until-s {cfg.until_s:g}: a time limit is for the lockstep clock; in "
              "real time the world runs on the wall clock (stop the run instead)", file=sys.stderr)
        return 2
    if not lockstep:
        try:
            link = MavlinkLink(cfg.mavlink, cfg.sysid, COMPID, signing_key=key)
        except (ValueError, OSError) as err:
            print(f"seaway-sim: --mavlink {cfg.mavlink}: {err}", file=sys.stderr)
            return 2
    with run_service("sim", args, run=run) as ctx:
        boot_ns = time.monotonic_ns()
        core = SimCore(scenario, vessel, epoch_ns=0 if lockstep else time.time_ns())
        node = SimNode(core, lockstep=lockstep, run=run, model=model, state_file=cfg.state_file)
        node.stall_s = cfg.stall_repeat_s
        node.until_s = cfg.until_s
        if stale is not None:
            log.info("--state-file %s: %s was kept before this run started (an earlier launch into "
                     "this folder): the run's %s flies", cfg.state_file, stale.name, run.scenario)
        if resumed is not None:
            log.warning("scenario %s, as loaded over the bus before this sim started (kept in %s), "
                        "not the run's %s: time starts again at 0", scenario.name, cfg.state_file,
                        run.scenario)
        log.info("scenario %s (seed %d), plant vessel %s, model vessel %s, period %g s, %s",
                 scenario.name, scenario.seed, vessel.name, run.model_vessel_file, period_s,
                 "lockstep" if lockstep else "real time, MAVLink signing "
                 + (f"on (key file {cfg.signing_key_file})" if key is not None else "off"))
        if link is None:
            run_node(ctx, node, period_s)
        else:
            autopilot = Px4Autopilot(Px4Config(thrust_max_n=vessel.thrust_max_n, sysid=cfg.sysid,
                                               param_overrides=params))
            keeper = None if cfg.state_file is None else resume_plant(core, cfg.state_file, args.run)
            try:
                node.live = Realtime(node, autopilot, link, cfg.step_s, period_s, boot_ns, keeper)
                run_node(ctx, node, cfg.step_s)
            finally:
                link.close()
    return 0


def resume_plant(core: SimCore, state_file: Path, run_file: str | None) -> plant_kept.PlantKeeper:
    """Real time: put the vessel back where a sim before this one left it, if it kept it for this
    run and scenario (``seaway_sim.plant_kept``); the keeper that keeps it from now on."""
    path = plant_kept.plant_path(state_file)
    try:
        kept = plant_kept.load(path)
    except plant_kept.PlantKeptError as err:
        log.error("%s: %s; the vessel starts at the scenario's start", path, err)
        kept = None
    why = plant_kept.resumable(kept, core, run_file)
    if kept is not None and why is None:
        plant_kept.restore(core, kept)
        u, v, _r, x, y, psi = kept.x
        log.warning("vessel put back where the sim before this one left it (kept in %s): x %.1f m, "
                    "y %.1f m, heading %.2f rad, speed %.2f m/s, propulsion energy %.0f J, pack "
                    "drawn for %.0f s", path, x, y, psi, math.hypot(u, v), kept.energy_j,
                    kept.pack_elapsed_ns / 1e9)
    elif kept is not None:
        log.info("%s not resumed: %s", path, why)
    return plant_kept.PlantKeeper(path)


if __name__ == "__main__":
    raise SystemExit(main())
