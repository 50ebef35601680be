"""What the operator commands that send one request share (``seaway mission``, ``seaway vehicle``):
their common options, waiting for the service that answers, and printing its reply.

A new Zenoh session meets the stack's mesh over a second or so: a request sent at once can leave
before this session knows where the service's queryable is, and then nobody answers it. So the
request waits, up to ``--timeout``, for the answering service's health token, and is sent again
while it ends unanswered at once (no queryable matched it yet); one that reached nobody is safe to
send again, one that ran its whole time may have reached the service and is not. What happened is
said: no service seen, service seen but its queryable never reached, or no answer in time.

Exit codes, the same for every such command: 0 the request was accepted (or the status read), 1
refused or not delivered, 2 a bad command line (argparse's own code too).
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from dataclasses import dataclass

from seaway.contract import keys
from seaway.contract.messages import Message, MessageError, Reply
from seaway.runtime.argtypes import positive_float
from seaway.runtime.bus import Bus
from seaway.runtime.service import DEFAULT_VESSEL, add_zenoh_config_option
from seaway.tools import vessel_choice

RETRY_PAUSE_S = 0.2
"""Between two attempts whose query found no queryable (the mesh is still forming)."""
EARLY_S = 0.05
"""A query that ends this much before its timeout ended unanswered by itself: nobody had it."""
DEFAULT_TIMEOUT_S = 5.0
"""How long a command waits for the service and its reply, in all, unless ``--timeout`` says."""

EXIT_ACCEPTED, EXIT_REFUSED, EXIT_USAGE = 0, 1, 2


@dataclass(frozen=True)
class Outcome:
    """What became of a request: the reply if one came, else why none did."""

    reply: Reply | None
    why: str = ""
    attempts: int = 0


def add_request_arguments(ap: argparse.ArgumentParser, waits_for: str) -> None:
    """``--vessel`` (``vessel_choice``: in a fleet, name one), ``--timeout`` (for ``waits_for``, the
    answering service) and ``--zenoh-config``."""
    vessel_choice.add_option(ap)
    ap.add_argument("--timeout", type=positive_float, default=DEFAULT_TIMEOUT_S, metavar="S",
                    help=f"seconds to wait for the {waits_for} and its reply, in all (default "
                         f"{DEFAULT_TIMEOUT_S:g})")
    add_zenoh_config_option(ap)


def _wait_for_token(bus: Bus, service: str, deadline: float, vessel: str | None = None) -> bool:
    """Whether ``service``'s health token (of ``vessel``, default the bus's) was seen before
    ``deadline`` (monotonic s)."""
    seen = threading.Event()

    def on_health(name: str, alive: bool) -> None:
        if name == service and alive:
            seen.set()

    watch = bus.watch_health(on_health, vessel)
    try:
        return seen.wait(max(0.0, deadline - time.monotonic()))
    finally:
        watch.undeclare()


def request_when_served(bus: Bus, spec: keys.KeySpec, request: Message, timeout_s: float,
                        vessel: str | None = None) -> Outcome:
    """Send ``request`` on ``spec`` of ``vessel`` (default the bus's) once its producer is there,
    within ``timeout_s`` in all.

    Waits for the producer's health token, then sends; a query that ends unanswered well before
    its timeout found no queryable (this session does not know the route yet) and is sent again
    after ``RETRY_PAUSE_S``; a query that runs out its time is not (it may have been delivered).
    """
    deadline = time.monotonic() + timeout_s
    key = bus.key(spec, vessel)
    if not _wait_for_token(bus, spec.producer, deadline, vessel):
        return Outcome(None, f"no {spec.producer} on vessel {vessel or bus.vessel}: its health "
                             "token did not "
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


def show(what: str, out: Outcome) -> int:
    """Print what became of the request ``what`` (accepted on stdout, else on stderr) and return
    the command's exit code."""
    reply = out.reply
    if reply is None:
        print(f"{what}: not delivered: {out.why}", file=sys.stderr)
        return EXIT_REFUSED
    if reply.accepted:
        print(f"{what}: accepted{': ' + reply.reason if reply.reason else ''}")
        return EXIT_ACCEPTED
    print(f"{what}: REFUSED: {reply.reason}", file=sys.stderr)
    return EXIT_REFUSED


def send(args: argparse.Namespace, spec: keys.KeySpec, request: Message, what: str) -> int:
    """Open the bus, choose the vessel (``args.vessel``, ``vessel_choice``), send ``request`` on
    ``spec`` when its service is there, print the outcome as ``what`` and return the exit code."""
    with Bus.open(args.vessel or DEFAULT_VESSEL, args.zenoh_config) as bus:
        vessel = vessel_choice.resolve(bus, args.vessel, _prog(spec))
        if vessel is None:
            return EXIT_USAGE
        out = request_when_served(bus, spec, request, args.timeout, vessel)
    return show(what, out)


def _prog(spec: keys.KeySpec) -> str:
    """The command that speaks to ``spec``'s producer, for its messages."""
    return "seaway mission" if spec.producer == "controller" else "seaway vehicle"


def show_next(args: argparse.Namespace, spec: keys.KeySpec) -> int:
    """Print the next ``spec`` message of the vessel (``args.vessel``, ``vessel_choice``) as JSON
    (exit 0), or say that none came within ``--timeout`` (exit 1)."""
    with Bus.open(args.vessel or DEFAULT_VESSEL, args.zenoh_config) as bus:
        vessel = vessel_choice.resolve(bus, args.vessel, _prog(spec))
        if vessel is None:
            return EXIT_USAGE
        msg = bus.subscribe(spec, vessel=vessel).get(args.timeout)
    if msg is None:
        print(f"no {spec.suffix} from vessel {vessel} within {args.timeout:g} s", file=sys.stderr)
        return EXIT_REFUSED
    print(msg.model_dump_json(indent=2))
    return EXIT_ACCEPTED
