"""``seaway mission``: send a mission to a running vessel, or pause, resume or abort it.

    seaway mission deploy/missions/lake-square.toml # a mission file
    seaway mission paper-c1                          # the [mission] of a scenario
    seaway mission pause | resume | abort
    seaway mission status                            # the next mission/status message
    seaway mission check FILE|SCENARIO [--json]      # the check before a mission (mission_check_cli)
    seaway mission home here | NORTH_M,EAST_M | LAT,LON --deg   # set the vessel's home

A scenario is checked whole, as the simulator loads it (its tables, its model and plant vessel
files), and only its ``[mission]`` is sent: a note on stderr names what of it is not (the running
stack's vessel, world and battery apply, whatever the scenario says).

Prints the controller's reply (accepted, or refused with the reason) and exits 0 only if accepted
(1 refused or not delivered, 2 a bad command line). The request waits, up to ``--timeout``, for the
controller (``seaway.tools.request_cli``: a new session needs a moment to find its queryable) and
says what happened when no reply came: no controller seen, its queryable never reached, or no
answer in time.
"""

from __future__ import annotations

import argparse
import sys
import time

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import HomeRequest, MessageError, MissionCommand, Waypoint
from seaway.contract.missions import MissionSpec
from seaway.simkit.scenario import Scenario, load_mission_source
from seaway.tools import request_cli
from seaway.vessel.model import check_vessel_files

COMMANDS = ("pause", "resume", "abort")
SENT_OF_SCENARIO = frozenset({"name", "description", "mission"})
"""A scenario's fields that go into the request (the rest is the simulator's business)."""


def read_mission(what: str) -> tuple[MissionSpec, str | None]:
    """The mission ``what`` names (a mission file, a scenario's name or file) and, for a scenario,
    a note naming what of it is not sent. ConfigError when anything read is invalid: a scenario's
    vessel files are loaded as the simulator loads them."""
    spec, scenario = load_mission_source(what)
    if scenario is None:
        return spec, None
    try:
        check_vessel_files(model=scenario.vessel, plant=scenario.plant_vessel)
    except ConfigError as err:
        raise ConfigError(f"scenario {scenario.name!r}: {err}") from None
    return spec, _ignored_note(scenario)


def _ignored_note(scenario: Scenario) -> str:
    ignored = sorted(scenario.model_fields_set - SENT_OF_SCENARIO)
    return (f"using only [mission] of scenario {scenario.name!r}: its {', '.join(ignored)} are not "
            "sent; the running stack's vessel, world and battery apply")


def home_request(where: str, degrees: bool) -> HomeRequest:
    """The request for ``seaway mission home WHERE``: ``here``, or two numbers ``A,B`` (north and
    east [m], or with ``degrees`` latitude and longitude [deg]). ConfigError naming what is
    wrong."""
    if where == "here":
        return HomeRequest.make(stamp_ns=time.time_ns(), home="here")
    parts = where.split(",")
    try:
        a, b = (float(p) for p in parts)
    except ValueError:
        raise ConfigError(f"home {where!r}: give 'here', or two numbers NORTH_M,EAST_M (with --deg: "
                          "LAT,LON in degrees)") from None
    wp = dict(lat_deg=a, lon_deg=b) if degrees else dict(x_m=a, y_m=b)
    try:
        return HomeRequest.make(stamp_ns=time.time_ns(), home=Waypoint(**wp))
    except (MessageError, ValueError) as err:
        raise ConfigError(f"home {where!r}: {err}") from None


def home_main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway mission home",
                                 description="Set the vessel's home: where a return goes, and the "
                                 "home of every mission that gives none (until set: where it was "
                                 "armed). It must lie in the operating area.")
    ap.add_argument("where", help="'here' (where the vessel is now), or NORTH_M,EAST_M in the run's "
                    "local frame, or LAT,LON with --deg")
    ap.add_argument("--deg", action="store_true", help="WHERE is latitude,longitude [deg]")
    request_cli.add_request_arguments(ap, "controller")
    args = ap.parse_args(argv)
    try:
        req = home_request(args.where, args.deg)
    except ConfigError as err:
        print(f"seaway mission home: {err}", file=sys.stderr)
        return request_cli.EXIT_USAGE
    return request_cli.send(args, keys.MISSION_HOME, req, f"home {args.where}")


def main(argv: list[str]) -> int:
    if argv[:1] == ["check"]:  # the check before a mission, at the desk
        from seaway.tools import mission_check_cli

        return mission_check_cli.main(argv[1:])
    if argv[:1] == ["home"]:
        return home_main(argv[1:])
    ap = argparse.ArgumentParser(prog="seaway mission", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", help="mission file, scenario name, or pause|resume|abort|status")
    request_cli.add_request_arguments(ap, "controller")
    args = ap.parse_args(argv)  # a --timeout that is no duration is refused here (exit 2)
    if args.what == "status":
        return request_cli.show_next(args, keys.MISSION_STATUS)
    if args.what in COMMANDS:
        cmd = MissionCommand.make(stamp_ns=time.time_ns(), command=args.what)
        return request_cli.send(args, keys.MISSION_COMMAND, cmd, args.what)
    try:
        spec, note = read_mission(args.what)
        request = spec.to_request(time.time_ns())
    except (ConfigError, MessageError) as err:
        print(f"seaway mission: {err}", file=sys.stderr)
        return request_cli.EXIT_USAGE
    if note is not None:
        print(f"seaway mission: {note}", file=sys.stderr)
    what = f"mission {request.mission_id or '(unnamed)'} ({len(request.waypoints)} waypoints)"
    return request_cli.send(args, keys.MISSION_SET, request, what)
