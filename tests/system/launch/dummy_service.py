"""A stand-in process for launcher tests: declares a health token and runs until told otherwise.

--exit-after S --code C   exit with code C after S seconds (a crash, or a clean exit)
--ignore-sigint           ignore SIGINT (the launcher must escalate to SIGKILL)
--ready-after S           declare the health token only after S seconds
--marker FILE             append this process's pid to FILE (the test checks none survive)
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time

from seaway.runtime.bus import Bus

ap = argparse.ArgumentParser()
ap.add_argument("--service", required=True)
ap.add_argument("--vessel", default=os.environ.get("SEAWAY_VESSEL", "vessel1"))
ap.add_argument("--exit-after", type=float, default=None)
ap.add_argument("--code", type=int, default=0)
ap.add_argument("--ignore-sigint", action="store_true")
ap.add_argument("--ready-after", type=float, default=0.0)
ap.add_argument("--marker", default=None)
args = ap.parse_args()

stop = threading.Event()
if args.ignore_sigint:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
else:
    signal.signal(signal.SIGINT, lambda *_: stop.set())
signal.signal(signal.SIGTERM, lambda *_: stop.set())
if args.marker:
    with open(args.marker, "a") as f:
        f.write(f"{os.getpid()}\n")
bus = Bus.open(args.vessel)
time.sleep(args.ready_after)
bus.declare_alive(args.service)
print(f"{args.service} up pid {os.getpid()}", flush=True)
t0 = time.monotonic()
while not stop.wait(0.05):
    if args.exit_after is not None and time.monotonic() - t0 > args.exit_after:
        print(f"{args.service} exiting with {args.code}", flush=True)
        bus.close()
        sys.exit(args.code)
bus.close()
print(f"{args.service} stopped cleanly", flush=True)
