"""Stand-in processes for the boat/shore deployment tests: real processes on real Zenoh sessions.

Every line printed is one JSON object with ``t`` = CLOCK_MONOTONIC seconds (one clock for every
network namespace on the machine, so the test can line events up with the moment it cut the link).

Each is one identity of its side (``$SEAWAY_CREDENTIALS`` names the side's folder, made by
``seaway credentials create DIR --deployment``), so the side's access rules apply to it as to the
service it stands in for.

``boat-control``  the onboard loop, identity ``controller``: publishes ctrl/thrust at ``--rate-hz``
                  with seq 1, 2, 3, ... (from when a subscriber, the recorder, is known); serves
                  mission/command (accepts) and prints ``{"served": "mission/command"}`` for each
                  request it answers; health token ``controller``.
``boat-recorder`` identity ``recorder``: counts everything under ``seaway/**`` on the boat: prints
                  ``{"key", "seq"}`` per sample (seq from the JSON payload, if any); health token
                  ``recorder``.
``shore-watch``   the shore, identity ``operator``: prints every sample under ``seaway/**`` like the
                  recorder, and every ``--probe-s`` seconds tries what the chain must refuse or carry:
                  a put on ctrl/thrust (seq >= 1e9: the shore never publishes a boat key) and a
                  mission/command request (an operator's: answered by the boat), printing each reply
                  (``--no-requests``: only the put). No health token (the boat must not see one from
                  the shore). mission/status samples also carry ``state``, ``energy_used_j``.
"""

from __future__ import annotations

import faulthandler
import json
import signal
import threading
import time

from seaway.contract import keys
from seaway.contract.messages import MissionCommand, Reply, ThrustCommand
from seaway.runtime.bus_raw import RawSample
from seaway.runtime.service import base_parser, run_service

FORBIDDEN_SEQ0 = 1_000_000_000
_print_lock = threading.Lock()


def emit(**fields: object) -> None:
    line = json.dumps({"t": time.monotonic(), **fields})
    with _print_lock:
        print(line, flush=True)


def _fields(payload: bytes) -> dict:
    """``seq`` (if any), and for mission/status its ``state`` and ``energy_used_j``."""
    try:
        doc = json.loads(payload)
    except ValueError:
        return {"seq": None}
    if not isinstance(doc, dict):
        return {"seq": None}
    seq = doc.get("seq")
    out = {"seq": seq if isinstance(seq, int) else None}
    if "state" in doc and "active_leg" in doc:
        out |= {"state": doc["state"], "energy_used_j": doc.get("energy_used_j")}
    return out


def watch_all(ctx) -> None:
    def on_sample(sample: RawSample) -> None:
        emit(key=sample.key, **_fields(sample.payload))

    ctx.bus.subscribe_raw(f"{keys.ROOT}/**", on_sample)


def boat_control(ctx, rate_hz: float) -> None:
    def on_command(req: MissionCommand) -> Reply:
        emit(served=keys.MISSION_COMMAND.suffix, command=req.command)
        return Reply.accept(time.time_ns(), f"{req.command} by the boat")

    ctx.bus.queryable(keys.MISSION_COMMAND, on_command)
    pub = ctx.bus.publisher(keys.THRUST)
    # Publish from the first command on only once the recorder is linked to us directly, so the
    # recording can be checked for "every seq from 1" (what happens before discovery is not the
    # test). Its subscription is known earlier through the router, but on the boat what the router
    # relays is the shore's and a put from it is refused: the recorder's health token, which only
    # its own direct link may carry, says the direct link (and the subscription declared on it
    # before the token) is there. (A real-time publisher is zenoh-ext's advanced one, which keeps
    # a cache and has no matching status to ask.)
    deadline = time.monotonic() + 20.0
    while "recorder" not in ctx.bus.alive_services(timeout_s=0.5):
        if ctx.stop.wait(0.05) or time.monotonic() > deadline:
            break
    emit(event="ready")
    period = 1.0 / rate_hz
    seq = 0
    next_t = time.monotonic()
    while not ctx.stop.is_set():
        seq += 1
        pub.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=1.0, thrust_starboard_n=1.0,
                                   source="standin", seq=seq))
        next_t += period
        ctx.stop.wait(max(0.0, next_t - time.monotonic()))
    emit(event="stopped", published=seq)


def boat_recorder(ctx) -> None:
    watch_all(ctx)
    emit(event="ready")
    while not ctx.stop.wait(0.25):  # not one blocking wait: a signal may land on another thread
        pass


def shore_watch(ctx, probe_s: float, requests: bool) -> None:
    watch_all(ctx)
    thrust = ctx.bus.publisher(keys.THRUST)
    emit(event="ready")
    i = 0
    while not ctx.stop.wait(probe_s):
        i += 1
        thrust.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=99.0,
                                      thrust_starboard_n=99.0, source="shore", seq=FORBIDDEN_SEQ0 + i))
        if not requests:
            continue
        reply = ctx.bus.request(keys.MISSION_COMMAND,
                                MissionCommand.make(stamp_ns=time.time_ns(), command="resume"),
                                timeout_s=probe_s)
        emit(probe=i, request=keys.MISSION_COMMAND.suffix, accepted=reply.accepted, reason=reply.reason)


def main() -> None:
    faulthandler.register(signal.SIGUSR1)  # a test that finds us stuck asks where
    parser = base_parser("standin", "deployment test stand-in")
    parser.add_argument("role", choices=["boat-control", "boat-recorder", "shore-watch"])
    parser.add_argument("--rate-hz", type=float, default=50.0)
    parser.add_argument("--probe-s", type=float, default=1.0)
    parser.add_argument("--no-requests", action="store_true",
                        help="shore-watch: no mission/command probes (a real controller)")
    args = parser.parse_args()
    health = {"boat-control": "controller", "boat-recorder": "recorder"}.get(args.role)
    # shore-watch: the launcher's part (no health token, no run agreement), the operator's identity
    with run_service(health or "launcher", args, identity=health or "operator") as ctx:
        if health is not None:
            ctx.ready()  # (its roles declare what they need before their loops)
        if args.role == "boat-control":
            boat_control(ctx, args.rate_hz)
        elif args.role == "boat-recorder":
            boat_recorder(ctx)
        else:
            shore_watch(ctx, args.probe_s, not args.no_requests)


if __name__ == "__main__":
    main()
