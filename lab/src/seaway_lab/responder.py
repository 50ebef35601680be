"""An instant lockstep responder: answers every sim/clock tick with a constant ThrustCommand.

``python -m seaway_lab.responder --port-n 3 --starboard-n 2`` stands in for the estimator and the
controller when only the sim's own speed or determinism is measured (``seaway bench sim``, the
system tests): on each lockstep ``ClockTick(t_k)`` it publishes ``ThrustCommand(stamp_ns=t_k)`` at
once, from Zenoh's delivery thread, without computing anything.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence

from seaway.contract import keys
from seaway.contract.messages import ClockTick, ThrustCommand
from seaway.runtime.service import base_parser, parse, run_service

log = logging.getLogger("seaway_lab.responder")


def main(argv: Sequence[str] | None = None) -> int:
    p = base_parser("sim_responder", "answer each lockstep clock tick with a constant thrust command")
    p.add_argument("--port-n", type=float, default=0.0, help="T1, port thrust [N]")
    p.add_argument("--starboard-n", type=float, default=0.0, help="T2, starboard thrust [N]")
    args = parse(p, argv)
    # It stands in for the controller: that is the identity allowed to publish ctrl/thrust.
    with run_service("sim-responder", args, identity="controller") as ctx:
        pub = ctx.bus.publisher(keys.THRUST)
        seq = 0
        lock = threading.Lock()

        def on_tick(_key: str, tick: ClockTick) -> None:
            nonlocal seq
            if not tick.lockstep:
                return
            with lock:
                seq += 1
                pub.put(ThrustCommand(stamp_ns=tick.stamp_ns, thrust_port_n=args.port_n,
                                      thrust_starboard_n=args.starboard_n, source="responder",
                                      seq=seq))

        ctx.bus.subscribe(keys.SIM_CLOCK, callback=on_tick)
        print("READY", flush=True)
        ctx.stop.wait()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
