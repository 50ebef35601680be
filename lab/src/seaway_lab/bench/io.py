"""``seaway bench io``: ThrustCommand on Zenoh -> MANUAL_CONTROL on the UDP socket, end to end.

vehicle_io runs as a real subprocess (``udpin`` on a free loopback port). This process plays the
autopilot with ``FakeAutopilot`` (armed, heartbeats, a UDP socket receiving what vehicle_io sends)
and publishes ThrustCommands on Zenoh. For each command we take the monotonic time just before
``put`` and the arrival time of the first MANUAL_CONTROL that carries that command's axes (each
command differs from the previous one, so it cannot be confused with the 20 Hz stream repeating
the old value). Commands go one at a time, with a few milliseconds between them.

Baselines, measured in the same run on the same machine:

* ``zenoh``: put -> subscriber callback between two Zenoh sessions of this process (loopback TCP,
  the same transport the two processes use, the callback on Zenoh's thread as in vehicle_io);
* ``udp``: one datagram between two loopback sockets of this process.

What vehicle_io itself adds is roughly the end-to-end figure minus the two baselines (decode,
watchdog, mapping, MAVLink packing, and the wake-up of its Zenoh callback thread).
"""

from __future__ import annotations

import argparse
import gc
import os
import random
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Sequence

import zenoh
from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.runtime.bus import Bus
from seaway.vessel.metrics import median, percentile
from seaway.vessel.model import load_vessel
from seaway_vehicle_io.px4 import PROFILE
from seaway_vehicle_io.thrust import ThrusterLimits, normalise_pair

from seaway_lab.bench.common import BenchResult
from seaway_lab.fake_autopilot import FakeAutopilot, ManualControlRecord

TARGET_P99_MS = 2.0


def _free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ms(values_ns: Sequence[int]) -> list[float]:
    return [v / 1e6 for v in values_ns]


def _udp_baseline(n: int) -> list[int]:
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    got = threading.Event()
    arrival = [0]

    def receive() -> None:
        rx.settimeout(1.0)
        for _ in range(n):
            try:
                rx.recv(64)
            except TimeoutError:
                return
            arrival[0] = time.monotonic_ns()
            got.set()

    t = threading.Thread(target=receive, daemon=True)
    t.start()
    out = []
    payload = bytes(23)  # the size of a MAVLink 2 MANUAL_CONTROL
    for _ in range(n):
        got.clear()
        t0 = time.monotonic_ns()
        tx.sendto(payload, rx.getsockname())
        if got.wait(0.5):
            out.append(arrival[0] - t0)
        time.sleep(random.uniform(0.0005, 0.002))
    t.join(1.0)
    rx.close()
    tx.close()
    return out


def _zenoh_baseline(n: int, vessel: str) -> list[int]:
    """Put -> callback between two sessions, the callback on Zenoh's receive thread, as
    vehicle_io's thrust subscriber is (``indirect=False``)."""
    got = threading.Event()
    arrival = [0]

    def on_sample(_sample: zenoh.Sample) -> None:
        arrival[0] = time.monotonic_ns()
        got.set()

    out = []
    with Bus.open(vessel) as a, Bus.open(vessel) as b:
        key = keys.THRUST.key(f"{vessel}-baseline")
        b.session.declare_subscriber(key, zenoh.handlers.Callback(on_sample, indirect=False))
        pub = a.publisher(keys.THRUST, vessel=f"{vessel}-baseline")
        time.sleep(1.0)  # let the two sessions find each other
        for i in range(n):
            got.clear()
            msg = ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=float(i % 50),
                                     thrust_starboard_n=1.0, seq=i)
            t0 = time.monotonic_ns()
            pub.put(msg)
            if got.wait(0.5):
                out.append(arrival[0] - t0)
            time.sleep(random.uniform(0.0005, 0.002))
    return out


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench io", description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=2000, help="commands to time (default 2000)")
    ap.add_argument("--baseline-count", type=int, default=1000)
    ap.add_argument("--vessel-file", default="paper-boat")
    args = ap.parse_args(argv)

    zenoh_port, udp_port = _free_port(socket.SOCK_STREAM), _free_port(socket.SOCK_DGRAM)
    os.environ["SEAWAY_ZENOH_RENDEZVOUS"] = f"tcp/127.0.0.1:{zenoh_port}"
    os.environ.pop("SEAWAY_ZENOH_CONFIG", None)
    vessel = "bench-io"
    limits = ThrusterLimits.from_vessel(load_vessel(args.vessel_file))

    result = BenchResult("io", "vehicle_io: ThrustCommand put on Zenoh -> MANUAL_CONTROL on the "
                               "autopilot's UDP socket (vehicle_io as a subprocess)")
    proc = subprocess.Popen(
        [sys.executable, "-m", "seaway_vehicle_io.main", "--vessel", vessel,
         "--mavlink", f"udpin:127.0.0.1:{udp_port}", "--vessel-file", args.vessel_file,
         "--log-level", "WARNING"],
        env={**os.environ, "PYTHONUNBUFFERED": "1"}, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, start_new_session=True)
    expected: list[tuple[int, int]] = [(0, 0)]
    arrival = [0]
    matched = threading.Event()

    def on_mc(rec: ManualControlRecord) -> None:
        if (rec.y, rec.z) == expected[0] and not matched.is_set():
            arrival[0] = rec.arrival_mono_ns
            matched.set()

    latencies: list[int] = []
    lost = 0
    peer = FakeAutopilot(("127.0.0.1", udp_port), armed=True, telemetry=False)
    peer.on_manual_control = on_mc
    try:
        peer.start()
        with Bus.open(vessel) as bus:
            pub = bus.publisher(keys.THRUST)
            deadline = time.monotonic() + 30.0
            while not peer.manual_controls and time.monotonic() < deadline:
                if proc.poll() is not None:
                    raise RuntimeError(f"vehicle_io exited: {proc.stderr.read().decode()[-2000:]}")
                time.sleep(0.05)
            if not peer.manual_controls:
                raise RuntimeError("vehicle_io never streamed MANUAL_CONTROL to the bench peer")
            time.sleep(1.0)  # Zenoh discovery between the bench and vehicle_io
            # The bench's own garbage collector must not stamp its pauses onto vehicle_io.
            gc.collect()
            gc.freeze()
            gc.disable()
            for i in range(args.count + 20):
                t_n = 12.0 + (i % 40) * 1.4  # consecutive commands always differ
                cmd = ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=t_n,
                                         thrust_starboard_n=t_n, seq=i, source="bench")
                axes = PROFILE.manual_control(*normalise_pair(t_n, t_n, limits,
                                                              PROFILE.quantisation_guard))
                expected[0] = (axes.y, axes.z)
                matched.clear()
                t0 = time.monotonic_ns()
                pub.put(cmd)
                if matched.wait(0.25):
                    if i >= 20:  # the first few warm up the paths
                        latencies.append(arrival[0] - t0)
                elif i >= 20:
                    lost += 1
                time.sleep(random.uniform(0.001, 0.004))
    finally:
        gc.enable()
        peer.stop()
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)

    gc.collect()
    gc.disable()  # as for the main measurement
    try:
        zenoh_ns = _zenoh_baseline(args.baseline_count, vessel)
        udp_ns = _udp_baseline(args.baseline_count)
    finally:
        gc.enable()
    e2e = _ms(latencies)
    p99 = percentile(e2e, 99)
    result.add("e2e_median_ms", median(e2e))
    result.add("e2e_p99_ms", p99, target=f"< {TARGET_P99_MS:g}", ok=p99 < TARGET_P99_MS)
    result.add("e2e_max_ms", max(e2e) if e2e else float("nan"))
    result.add("commands_timed", len(e2e))
    result.add("commands_lost", lost, target="0", ok=lost == 0,
               note="no MANUAL_CONTROL within 250 ms")
    result.add("baseline_zenoh_median_ms", median(_ms(zenoh_ns)),
               note="put -> callback, two sessions, loopback")
    result.add("baseline_zenoh_p99_ms", percentile(_ms(zenoh_ns), 99))
    result.add("baseline_udp_median_ms", median(_ms(udp_ns)), note="one datagram, loopback")
    result.add("baseline_udp_p99_ms", percentile(_ms(udp_ns), 99))
    result.add("vehicle_io_added_median_ms",
               median(e2e) - median(_ms(zenoh_ns)) - median(_ms(udp_ns)),
               note="e2e minus both baselines")
    result.meta.update({"cpus": os.cpu_count(), "load_avg_1m": round(os.getloadavg()[0], 2),
                        "vessel_file": args.vessel_file, "python": sys.version.split()[0]})
    return result
