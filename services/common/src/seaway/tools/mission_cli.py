"""``seaway mission``: send a mission to a running vessel, or pause, resume or abort it.

    seaway mission deploy/missions/square.toml      # a mission file
    seaway mission paper-c1                          # the [mission] of a scenario
    seaway mission pause | resume | abort
    seaway mission status                            # the next mission/status message

Prints the controller's reply (accepted, or refused with the reason) and exits 0 only if accepted.
"""

from __future__ import annotations

import argparse
import sys
import time

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import MissionCommand, Reply
from seaway.runtime.bus import Bus
from seaway.runtime.service import DEFAULT_VESSEL, ENV_VESSEL
from seaway.simkit.scenario import load_mission

COMMANDS = ("pause", "resume", "abort")


def main(argv: list[str]) -> int:
    import os

    ap = argparse.ArgumentParser(prog="seaway mission", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", help="mission file, scenario name, or pause|resume|abort|status")
    ap.add_argument("--vessel", default=os.environ.get(ENV_VESSEL, DEFAULT_VESSEL))
    ap.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for the reply")
    ap.add_argument("--zenoh-config", default=None)
    args = ap.parse_args(argv)

    request = None
    if args.what not in (*COMMANDS, "status"):
        try:
            request = load_mission(args.what).to_request(time.time_ns())
        except ConfigError as err:
            print(f"seaway mission: {err}", file=sys.stderr)
            return 2
    with Bus.open(args.vessel, args.zenoh_config) as bus:
        if args.what == "status":
            sub = bus.subscribe(keys.MISSION_STATUS)
            msg = sub.get(args.timeout)
            if msg is None:
                print(f"no {keys.MISSION_STATUS.suffix} from vessel {args.vessel} within "
                      f"{args.timeout:g} s",
                      file=sys.stderr)
                return 1
            print(msg.model_dump_json(indent=2))
            return 0
        reply: Reply
        if request is not None:
            reply = bus.request(keys.MISSION_SET, request, timeout_s=args.timeout)
            what = f"mission {request.mission_id or '(unnamed)'} ({len(request.waypoints)} waypoints)"
        else:
            cmd = MissionCommand.make(stamp_ns=time.time_ns(), command=args.what)
            reply = bus.request(keys.MISSION_COMMAND, cmd, timeout_s=args.timeout)
            what = args.what
    if reply.accepted:
        print(f"{what}: accepted{': ' + reply.reason if reply.reason else ''}")
        return 0
    print(f"{what}: REFUSED: {reply.reason}", file=sys.stderr)
    return 1
