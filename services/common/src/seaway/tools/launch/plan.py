"""What a launch runs: its vessels, each vessel's folder and run description, and its processes'
commands with their placeholders filled in (``seaway launch``, ``seaway.tools.launch.main``).

Paths are the run folder's (``<run_dir>`` for one vessel, ``<run_dir>/<vessel>`` for several); the
run description's units are its own (``seaway.runtime.run``: seconds, WGS84 origin).
"""

from __future__ import annotations

import argparse
import os
import socket
from pathlib import Path

from seaway.contract.config import ConfigError, deploy_path
from seaway.runtime import run as runs
from seaway.runtime.service import DEFAULT_VESSEL, ENV_VESSEL
from seaway.simkit.scenario import load_scenario
from seaway.tools.launch import recording_source
from seaway.tools.launch.profile import Instance, Profile, substitute
from seaway.tools.launch.supervisor import Supervised


def launch_vessels(args: argparse.Namespace, profile: Profile) -> list[str]:
    """The vessels this launch runs: a fleet profile's (``--vessels``, else its list), else the one
    of ``--vessel`` (else ``$SEAWAY_VESSEL``, else the default). ConfigError for the option that
    does not fit the profile."""
    if profile.vessels is None:
        if args.vessels is not None:
            raise ConfigError(f"--vessels: profile {profile.name} runs one vessel (--vessel); "
                              "--vessels is for a fleet profile (one that lists 'vessels', e.g. "
                              "fleet)")
        return [args.vessel or os.environ.get(ENV_VESSEL) or DEFAULT_VESSEL]
    if args.vessel is not None:
        raise ConfigError(f"--vessel: profile {profile.name} runs the vessels it lists "
                          f"({', '.join(profile.vessels)}); choose them with --vessels V1,V2")
    return list(args.vessels or profile.vessels)


def vessel_dir(run_dir: Path, vessel: str, vessels: list[str]) -> Path:
    """A vessel's folder in the run folder: the run folder itself for a launch of one vessel,
    ``<run_dir>/<vessel>`` for several (its run.json, mission.json, recording, report, events)."""
    return run_dir if len(vessels) == 1 else run_dir / vessel


def tiles_for(tiles: str | None) -> str | None:
    """The ground station's tiles as its process needs them: a URL as it is, a file or folder as an
    absolute path (the ground station checks it, and refuses what it cannot serve)."""
    if not tiles or tiles.startswith(("http://", "https://")):
        return tiles or None
    return str(Path(tiles).expanduser().resolve())


def free_udp_ports(n: int) -> list[int]:
    """``n`` distinct UDP ports free on loopback now (``{mavlink_port}``: each simulated
    autopilot of a fleet listens on its own)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(s)
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def supervised(plan: list[Instance], vessels: list[str], run_dir: Path,
               common: dict[str, str]) -> list[Supervised]:
    """The processes of ``plan`` with their commands' placeholders filled in: ``common`` (the
    launch's) and each one's vessel's ``{vessel}``, ``{run}``, ``{vessel_dir}``,
    ``{mavlink_port}`` (a free UDP port per vessel) and ``{vessel_index}`` (its place in
    ``vessels``, from 0). ConfigError for an unknown placeholder."""
    ports = dict(zip(vessels, free_udp_ports(len(vessels)), strict=True))
    out = []
    for inst in plan:
        folder = vessel_dir(run_dir, inst.vessel, vessels)
        values = {**common, "vessel": inst.vessel, "run": str(folder / recording_source.RUN_FILE),
                  "vessel_dir": str(folder if inst.per_vessel or len(vessels) == 1 else run_dir),
                  "mavlink_port": str(ports[inst.vessel]),
                  "vessel_index": str(vessels.index(inst.vessel))}
        out.append(Supervised(inst.spec, substitute(inst.spec.command, values), inst.vessel,
                              folder if inst.per_vessel else None))
    return out


def profile_path(name_or_path: str) -> Path:
    """The profile file the launcher runs (what ``{profile}`` stands for in a command)."""
    p = Path(name_or_path)
    return p if p.suffix in (".toml", ".json") else deploy_path("profiles", f"{name_or_path}.toml")


def resolve_run(args: argparse.Namespace, profile: Profile, scenario: str,
                run_id: str, vessel: str | None = None) -> runs.RunDescription:
    """The run description of ``vessel`` (default: the launch's one vessel), resolved once here
    and handed to its processes as ``--run``; a fleet's vessels differ only in their name.

    A simulated run takes the model and plant vessel files, origin and dead zone from the scenario;
    the profile's ``vessel_file`` replaces the model, and ``origin_from_scenario = false`` (a boat)
    leaves the origin to the estimator's first GNSS fix. A profile without our simulator (the
    autopilot's own SITL) has no plant vessel file; a replay (``--recording``) of our simulator's
    run is described as that run was. ConfigError on a bad scenario or value.
    """
    vessel = vessel or launch_vessels(args, profile)[0]
    return runs.describe(vessel=vessel, run_id=run_id, clock=profile.clock,
                         scenario=load_scenario(scenario) if scenario else None,
                         scenario_ref=scenario or None,
                         origin_from_scenario=profile.origin_from_scenario,
                         model_vessel_file=profile.vessel_file,
                         # A replay's sensors were made by our simulator on the scenario's hull
                         # (its dead zone, which the estimator predicts with), as in the recording.
                         simulated=(any(p.service == "sim" for p in profile.processes)
                                    or args.recording is not None),
                         control_period_s=args.control_period_s, where="launch")
