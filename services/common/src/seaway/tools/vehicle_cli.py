"""``seaway vehicle``: arm, disarm or change the mode of a running vessel's autopilot.

    seaway vehicle arm                       # arm (the autopilot's pre-arm checks apply)
    seaway vehicle disarm [--force]          # --force: even where the autopilot would refuse
    seaway vehicle mode HOLD                 # a mode by Seaway's name (MANUAL, HOLD, ...)
    seaway vehicle status                    # the next vehicle/status message
    seaway vehicle arm --vessel boat2        # another vessel of the stack (a fleet)

Each is the request the ground station's Arm, Disarm and Set mode buttons send (``vehicle/arm``,
``vehicle/mode``), answered by that vessel's vehicle_io once the autopilot has acknowledged it (or
refused, with the autopilot's or vehicle_io's reason: an unknown mode names the known ones).
Prints the reply and exits 0 only if accepted (1 refused or not delivered, 2 a bad command line);
it waits up to ``--timeout`` for vehicle_io, as ``seaway mission`` waits for the controller
(``seaway.tools.request_cli``).
"""

from __future__ import annotations

import argparse
import sys
import time

from seaway.contract import keys
from seaway.contract.messages import ArmRequest, MessageError, ModeRequest
from seaway.tools import request_cli

ACTIONS = ("arm", "disarm", "mode", "status")


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway vehicle", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("action", choices=ACTIONS, help="what to ask of the vessel's autopilot")
    ap.add_argument("mode", nargs="?", default=None, metavar="MODE",
                    help="with 'mode': the mode's name (MANUAL, HOLD, ...; vehicle_io names the "
                         "ones its autopilot has when refusing another)")
    ap.add_argument("--force", action="store_true",
                    help="with arm/disarm: ask the autopilot to skip its checks (MAVLink's forced "
                         "arm/disarm)")
    request_cli.add_request_arguments(ap, "vehicle_io")
    return ap


def _usage_error(args: argparse.Namespace) -> str | None:
    """What is wrong with the command line beyond argparse's own checks, or None."""
    if args.action == "mode" and args.mode is None:
        return "mode: name the mode, e.g. seaway vehicle mode HOLD"
    if args.action != "mode" and args.mode is not None:
        return f"{args.action} takes no argument (got {args.mode!r}); only 'mode' takes a MODE"
    if args.force and args.action not in ("arm", "disarm"):
        return f"--force applies to arm and disarm only, not to {args.action}"
    return None  # a --timeout that is no duration is refused by the parser (argtypes)


def main(argv: list[str]) -> int:
    args = parser().parse_args(argv)
    bad = _usage_error(args)
    if bad:
        print(f"seaway vehicle: {bad}", file=sys.stderr)
        return request_cli.EXIT_USAGE
    if args.action == "status":
        return request_cli.show_next(args, keys.VEHICLE_STATUS)
    now = time.time_ns()
    if args.action == "mode":
        try:
            request = ModeRequest.make(stamp_ns=now, mode=args.mode)
        except MessageError as err:
            print(f"seaway vehicle: mode {args.mode!r}: {err}", file=sys.stderr)
            return request_cli.EXIT_USAGE
        return request_cli.send(args, keys.VEHICLE_MODE, request, f"mode {args.mode}")
    arm = ArmRequest.make(stamp_ns=now, arm=args.action == "arm", force=args.force)
    what = args.action + (" (forced)" if args.force else "")
    return request_cli.send(args, keys.VEHICLE_ARM, arm, what)
