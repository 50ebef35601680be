"""``seaway mission``: send a mission to a running vessel, or pause, resume or abort it.

    seaway mission deploy/missions/square.toml      # a mission file
    seaway mission paper-c1                          # the [mission] of a scenario
    seaway mission pause | resume | abort
    seaway mission status                            # the next mission/status message

Prints the controller's reply (accepted, or refused with the reason) and exits 0 only if accepted.

A new Zenoh session meets the stack's mesh over a second or so: a request sent at once can leave
before this session knows where the controller's queryable is, and then nobody answers it. So the
request waits, up to ``--timeout``, for the controller's health token, and is sent again while it
ends unanswered at once (no queryable matched it yet); one that reached nobody is safe to send
again, one that ran its whole time may have reached the controller and is not. What happened is
said: no controller seen, controller seen but its queryable never reached, or no answer in time.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from dataclasses import dataclass

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import Message, MessageError, MissionCommand, Reply
from seaway.runtime.bus import Bus
from seaway.runtime.service import DEFAULT_VESSEL, ENV_VESSEL
from seaway.simkit.scenario import load_mission

COMMANDS = ("pause", "resume", "abort")
RETRY_PAUSE_S = 0.2
"""Between two attempts whose query found no queryable (the mesh is still forming)."""
EARLY_S = 0.05
"""A query that ends this much before its timeout ended unanswered by itself: nobody had it."""


@dataclass(frozen=True)
class Outcome:
    """What became of a request: the reply if one came, else why none did."""

    reply: Reply | None
    why: str = ""
    attempts: int = 0


def _wait_for_token(bus: Bus, service: str, deadline: float) -> bool:
    """Whether ``service``'s health token was seen before ``deadline`` (monotonic s)."""
    seen = threading.Event()

    def on_health(name: str, alive: bool) -> None:
        if name == service and alive:
            seen.set()

    watch = bus.watch_health(on_health)
    try:
        return seen.wait(max(0.0, deadline - time.monotonic()))
    finally:
        watch.undeclare()


def request_when_served(bus: Bus, spec: keys.KeySpec, request: Message, timeout_s: float) -> Outcome:
    """Send ``request`` on ``spec`` once its producer is there, within ``timeout_s`` in all.

    Waits for the producer's health token, then sends; a query that ends unanswered well before
    its timeout found no queryable (this session does not know the route yet) and is sent again
    after ``RETRY_PAUSE_S``; a query that runs out its time is not (it may have been delivered).
    """
    deadline = time.monotonic() + timeout_s
    key = bus.key(spec)
    if not _wait_for_token(bus, spec.producer, deadline):
        return Outcome(None, f"no {spec.producer} on vessel {bus.vessel}: its health token did not "
                             f"appear within {timeout_s:g} s (is the stack running, on this "
                             "rendezvous, with this vessel name?)")
    payload = request.encode()
    attempts = 0
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return Outcome(None, f"the {spec.producer} is alive, but no query on {key} reached its "
                                 f"queryable within {timeout_s:g} s ({attempts} attempt(s))", attempts)
        attempts += 1
        t0 = time.monotonic()
        for r in bus.query_raw(key, payload, remaining):
            if r.error is not None:
                return Outcome(Reply.refuse(time.time_ns(), f"error reply from {key}: {r.error}"),
                               attempts=attempts)
            try:
                return Outcome(Reply.decode(r.payload), attempts=attempts)
            except MessageError as err:
                return Outcome(Reply.refuse(time.time_ns(), f"malformed reply from {key}: {err}"),
                               attempts=attempts)
        if time.monotonic() - t0 >= remaining - EARLY_S:
            return Outcome(None, f"the {spec.producer} did not answer on {key} within "
                                 f"{timeout_s:g} s", attempts)
        time.sleep(min(RETRY_PAUSE_S, max(0.0, deadline - time.monotonic())))


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="seaway mission", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", help="mission file, scenario name, or pause|resume|abort|status")
    ap.add_argument("--vessel", default=os.environ.get(ENV_VESSEL, DEFAULT_VESSEL))
    ap.add_argument("--timeout", type=float, default=5.0,
                    help="seconds to wait for the controller and its reply, in all (default 5)")
    ap.add_argument("--zenoh-config", default=None)
    args = ap.parse_args(argv)
    if not args.timeout > 0:
        print(f"seaway mission: --timeout {args.timeout:g}: must be > 0 s", file=sys.stderr)
        return 2

    request = None
    if args.what not in (*COMMANDS, "status"):
        try:
            request = load_mission(args.what).to_request(time.time_ns())
        except (ConfigError, MessageError) as err:
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
        if request is not None:
            out = request_when_served(bus, keys.MISSION_SET, request, args.timeout)
            what = f"mission {request.mission_id or '(unnamed)'} ({len(request.waypoints)} waypoints)"
        else:
            cmd = MissionCommand.make(stamp_ns=time.time_ns(), command=args.what)
            out = request_when_served(bus, keys.MISSION_COMMAND, cmd, args.timeout)
            what = args.what
    reply = out.reply
    if reply is None:
        print(f"{what}: not delivered: {out.why}", file=sys.stderr)
        return 1
    if reply.accepted:
        print(f"{what}: accepted{': ' + reply.reason if reply.reason else ''}")
        return 0
    print(f"{what}: REFUSED: {reply.reason}", file=sys.stderr)
    return 1
