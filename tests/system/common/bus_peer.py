"""A test peer for the bus system test: a real process on a real Zenoh session.

``responder``: subscribes to ctrl/thrust in order and prints each message as a JSON line; serves
vehicle/arm (accepts arm, refuses disarm with a reason). ``talker``: publishes ThrustCommand at 50 Hz
with increasing seq and asks vehicle/arm once a second, printing the replies. Both run until SIGTERM.
"""

from __future__ import annotations

import json
import sys
import time

from seaway.contract import keys
from seaway.contract.messages import ArmRequest, Reply, ThrustCommand
from seaway.runtime.service import base_parser, run_service


def responder(ctx) -> None:
    def on_arm(req: ArmRequest) -> Reply:
        if req.arm:
            return Reply.accept(time.time_ns(), "armed")
        return Reply.refuse(time.time_ns(), "disarm refused by test responder")

    ctx.bus.queryable(keys.VEHICLE_ARM, on_arm)
    sub = ctx.bus.subscribe(keys.THRUST, mode="fifo")
    ctx.ready()
    print("READY", flush=True)
    while not ctx.stop.is_set():
        msg = sub.get(0.05)
        if msg is not None:
            print(json.dumps({"seq": msg.seq, "port": msg.thrust_port_n,
                              "malformed": ctx.bus.stats.malformed}), flush=True)


def talker(ctx) -> None:
    pub = ctx.bus.publisher(keys.THRUST)
    seq = 0
    last_ask = 0.0
    print("READY", flush=True)
    while not ctx.stop.is_set():
        seq += 1
        pub.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=float(seq),
                                   thrust_starboard_n=0.0, seq=seq))
        if time.monotonic() - last_ask > 1.0:
            last_ask = time.monotonic()
            reply = ctx.bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                                    timeout_s=1.0)
            print(json.dumps({"reply": reply.accepted, "reason": reply.reason}), flush=True)
        ctx.stop.wait(0.02)


if __name__ == "__main__":
    parser = base_parser("test_peer", "bus test peer")
    parser.add_argument("role", choices=["responder", "talker"])
    args = parser.parse_args()
    with run_service("launcher", args, identity="harness") as ctx:
        (responder if args.role == "responder" else talker)(ctx)
    sys.exit(0)
