"""``seaway mission``: send a mission to a running vessel, or pause, resume or abort it.

    seaway mission deploy/missions/lake-square.toml # a mission file
    seaway mission paper-c1                          # the [mission] of a scenario
    seaway mission pause | resume | abort
    seaway mission status                            # the next mission/status message

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
from seaway.contract.messages import MessageError, MissionCommand
from seaway.simkit.scenario import load_mission
from seaway.tools import request_cli

COMMANDS = ("pause", "resume", "abort")


def main(argv: list[str]) -> int:
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
        request = load_mission(args.what).to_request(time.time_ns())
    except (ConfigError, MessageError) as err:
        print(f"seaway mission: {err}", file=sys.stderr)
        return request_cli.EXIT_USAGE
    what = f"mission {request.mission_id or '(unnamed)'} ({len(request.waypoints)} waypoints)"
    return request_cli.send(args, keys.MISSION_SET, request, what)
