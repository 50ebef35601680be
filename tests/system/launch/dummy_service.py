"""A stand-in process for launcher tests: declares a health token and runs until told otherwise.

--exit-after S --code C   exit with code C after S seconds (a crash, or a clean exit)
--ignore-sigint           ignore SIGINT (the launcher must escalate to SIGKILL)
--ready-after S           declare the health token only after S seconds
--marker FILE             append this process's pid to FILE (the test checks none survive)
--publish-thrust HZ       publish zero ctrl/thrust commands at HZ (what a controller must publish)
--quiet-after S           stop publishing after S seconds, but keep running (a hung loop)
--quiet-vessel V          with --quiet-after: only if this process's vessel is V (one of a fleet's)
--drop-token-after S      withdraw the health token after S seconds, but keep running
--ready-once FILE         declare the health token on the first start only (FILE marks it): a
                          later start never does (a restart stuck before it is ready)
--times FILE              append "<service> start|up <unix time>" to FILE when it starts and when it
                          declares its token (start-order tests)
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.runtime.bus import Bus
from seaway.runtime.service import install_stop_signals, on_signals

ap = argparse.ArgumentParser()
ap.add_argument("--service", required=True)
ap.add_argument("--vessel", default=os.environ.get("SEAWAY_VESSEL", "vessel1"))
ap.add_argument("--exit-after", type=float, default=None)
ap.add_argument("--code", type=int, default=0)
ap.add_argument("--ignore-sigint", action="store_true")
ap.add_argument("--ready-after", type=float, default=0.0)
ap.add_argument("--marker", default=None)
ap.add_argument("--publish-thrust", type=float, default=None)
ap.add_argument("--quiet-after", type=float, default=None)
ap.add_argument("--quiet-vessel", default=None)
ap.add_argument("--drop-token-after", type=float, default=None)
ap.add_argument("--times", default=None)
ap.add_argument("--ready-once", default=None)
args = ap.parse_args()
if args.quiet_vessel is not None and args.quiet_vessel != args.vessel:
    args.quiet_after = None

stop = threading.Event()


def note_time(what: str) -> None:
    if args.times:
        with open(args.times, "a") as f:
            f.write(f"{args.service} {what} {time.time()}\n")


note_time("start")


# The services' own stop signals (seaway.runtime.service): a Python handler setting ``stop`` ran on
# the main thread between two bytecodes, also while that thread held ``stop``'s lock inside
# ``stop.wait`` (20 times a second here), and then waited on that lock for good: a launcher's test
# found this dummy alive 10 s after its SIGTERM (CI 2026-11-24, here 2026-11-28).
if args.ignore_sigint:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    on_signals((signal.SIGTERM,), lambda _signum: stop.set())
else:
    install_stop_signals(stop)
if args.marker:
    with open(args.marker, "a") as f:
        f.write(f"{os.getpid()}\n")
bus = Bus.open(args.vessel)
time.sleep(args.ready_after)
if args.ready_once:
    if os.path.exists(args.ready_once):
        print(f"{args.service} started again: never ready", flush=True)
        stop.wait()
        sys.exit(0)
    open(args.ready_once, "w").close()
bus.declare_alive(args.service)
note_time("up")
print(f"{args.service} up pid {os.getpid()}", flush=True)
t0 = time.monotonic()
thrust = bus.publisher(keys.THRUST) if args.publish_thrust else None
period_s = 1.0 / args.publish_thrust if args.publish_thrust else 0.05
while not stop.wait(period_s):
    up_s = time.monotonic() - t0
    if args.exit_after is not None and up_s > args.exit_after:
        print(f"{args.service} exiting with {args.code}", flush=True)
        bus.close()
        sys.exit(args.code)
    if thrust is not None and (args.quiet_after is None or up_s < args.quiet_after):
        thrust.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=0.0,
                                      thrust_starboard_n=0.0, source="dummy"))
    if args.drop_token_after is not None and up_s > args.drop_token_after and bus._tokens:
        bus._tokens.pop().undeclare()
        print(f"{args.service} withdrew its health token", flush=True)
bus.close()
print(f"{args.service} stopped cleanly", flush=True)
