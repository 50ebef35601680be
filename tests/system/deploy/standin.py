"""Stand-in processes for the boat/shore deployment tests: real processes on real Zenoh sessions.

Every line printed is one JSON object with ``t`` = CLOCK_MONOTONIC seconds (one clock for every
network namespace on the machine, so the test can line events up with the moment it cut the link).

``boat-control``  the onboard loop: publishes ctrl/thrust at ``--rate-hz`` with seq 1, 2, 3, ...
                  (from when a subscriber, the recorder, is known);
                  serves vehicle/arm (accepts) and sim/scenario (accepts; the shore may not ask it);
                  health token ``controller``.
``boat-recorder`` counts everything under ``seaway/**`` on the boat: prints ``{"key", "seq"}`` per
                  sample (seq from the JSON payload, if any); health token ``recorder``.
``shore-watch``   the shore: prints every sample under ``seaway/**`` like the recorder, and every
                  ``--probe-s`` seconds tries what the boat router must allow or refuse: a put on
                  ctrl/thrust (seq >= 1e9, refused), a put on shore/heartbeat (allowed), a
                  vehicle/arm request (allowed) and a sim/scenario request (refused), printing each
                  reply (``--no-requests``: only the puts). No health token (the boat must not see
                  one from the shore). mission/status samples also carry ``state``, ``energy_used_j``.
"""

from __future__ import annotations

import faulthandler
import json
import signal
import threading
import time

from seaway.contract import keys
from seaway.contract.messages import ArmRequest, Reply, ScenarioRequest, ThrustCommand
from seaway.runtime.bus import RawSample
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
    ctx.bus.queryable(keys.VEHICLE_ARM, lambda req: Reply.accept(time.time_ns(), "armed by boat"))
    ctx.bus.queryable(keys.SIM_SCENARIO, lambda req: Reply.accept(time.time_ns(), "scenario set"))
    pub = ctx.bus.publisher(keys.THRUST)
    # Publish from the first command on only once the recorder's subscription is known here, so the
    # recording can be checked for "every seq from 1" (what happens before discovery is not the test).
    deadline = time.monotonic() + 10.0
    while not pub._pub.matching_status.matching and time.monotonic() < deadline:
        if ctx.stop.wait(0.02):
            return
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
    ctx.stop.wait()


def shore_watch(ctx, probe_s: float, requests: bool) -> None:
    watch_all(ctx)
    thrust = ctx.bus.publisher(keys.THRUST)
    heartbeat_key = f"{keys.ROOT}/{ctx.vessel}/shore/heartbeat"
    emit(event="ready")
    i = 0
    while not ctx.stop.wait(probe_s):
        i += 1
        thrust.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=99.0,
                                      thrust_starboard_n=99.0, source="shore", seq=FORBIDDEN_SEQ0 + i))
        ctx.bus.session.put(heartbeat_key, json.dumps({"seq": i}))
        if not requests:
            continue
        arm = ctx.bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                              timeout_s=probe_s / 2)
        emit(probe=i, request="vehicle/arm", accepted=arm.accepted, reason=arm.reason)
        sc = ctx.bus.request(keys.SIM_SCENARIO, ScenarioRequest.make(stamp_ns=time.time_ns()),
                             timeout_s=probe_s / 2)
        emit(probe=i, request="sim/scenario", accepted=sc.accepted, reason=sc.reason)


def main() -> None:
    faulthandler.register(signal.SIGUSR1)  # a test that finds us stuck asks where
    parser = base_parser("standin", "deployment test stand-in")
    parser.add_argument("role", choices=["boat-control", "boat-recorder", "shore-watch"])
    parser.add_argument("--rate-hz", type=float, default=50.0)
    parser.add_argument("--probe-s", type=float, default=1.0)
    parser.add_argument("--no-requests", action="store_true",
                        help="shore-watch: no vehicle/arm and sim/scenario probes (a real vehicle_io)")
    args = parser.parse_args()
    health = {"boat-control": "controller", "boat-recorder": "recorder"}.get(args.role)
    with run_service(health or "launcher", args) as ctx:
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
