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

Authentication (issue 15): the Zenoh part (the end-to-end path and the ``zenoh`` baseline) is
measured with the stack's authentication on (mutual TLS and access control, a temporary
credentials folder: vehicle_io is itself, this process is the harness) and off
(``SEAWAY_CREDENTIALS=none``), in alternating rounds (on, off, on, off...; each round a fresh
vehicle_io on a fresh port), so drift hits both. The headline figures are those with
authentication on, as a stack runs; the ``auth_off`` ones and the ratios on / off (target: within
10 %) follow. The MAVLink side is unsigned in both (MAVLink signing is vehicle_io's own option).
"""

from __future__ import annotations

import argparse
import gc
import os
import random
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import zenoh
from seaway.contract import keys
from seaway.contract.access import HARNESS
from seaway.contract.messages import ThrustCommand
from seaway.runtime import credentials
from seaway.runtime.argtypes import positive_int
from seaway.runtime.bus import Bus
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile
from seaway.vessel.model import load_vessel
from seaway_vehicle_io.px4 import PROFILE
from seaway_vehicle_io.thrust import ThrusterLimits, normalise_pair

from seaway_lab.bench.common import BenchResult, compare_auth, free_port, free_rendezvous
from seaway_lab.fake_autopilot import FakeAutopilot, ManualControlRecord

TARGET_P99_MS = 2.0
WARMUP = 20  # commands per round not timed: the first few warm up the paths
Auth = credentials.Credentials | str  # a credentials folder, or credentials.NONE


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


def _use_fresh_rendezvous() -> None:
    """A free rendezvous port for the next sessions (each round its own: TLS and plain TCP never
    meet on one port, and a closing round never leaks into the next)."""
    os.environ[ENV_RENDEZVOUS] = free_rendezvous()


def _zenoh_baseline(n: int, vessel: str, auth: Auth) -> list[int]:
    """Put -> callback [ns] between two sessions, the callback on Zenoh's receive thread, as
    vehicle_io's thrust subscriber is (``indirect=False``); both sessions are the harness of
    ``auth``."""
    got = threading.Event()
    arrival = [0]

    def on_sample(_sample: zenoh.Sample) -> None:
        arrival[0] = time.monotonic_ns()
        got.set()

    out = []
    _use_fresh_rendezvous()
    with (Bus.open(vessel, identity=HARNESS, credentials=auth) as a,
          Bus.open(vessel, identity=HARNESS, credentials=auth) as b):
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


def _end_to_end(count: int, vessel: str, vessel_file: str, auth: Auth) -> tuple[list[int], int]:
    """One round: a fresh vehicle_io (identity ``vehicle_io`` of ``auth``), ``count`` commands
    timed after the warm-up; the latencies [ns] put -> MANUAL_CONTROL and the commands lost."""
    _use_fresh_rendezvous()
    udp_port = free_port(socket.SOCK_DGRAM)
    limits = ThrusterLimits.from_vessel(load_vessel(vessel_file))
    folder = str(auth.folder) if isinstance(auth, credentials.Credentials) else auth
    proc = subprocess.Popen(
        [sys.executable, "-m", "seaway_vehicle_io.main", "--vessel", vessel,
         "--mavlink", f"udpin:127.0.0.1:{udp_port}", "--vessel-file", vessel_file,
         "--log-level", "WARNING"],
        env={**os.environ, "PYTHONUNBUFFERED": "1", credentials.ENV_CREDENTIALS: folder,
             credentials.ENV_IDENTITY: "vehicle_io"},
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
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
        with Bus.open(vessel, identity=HARNESS, credentials=auth) as bus:
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
            for i in range(count + WARMUP):
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
                    if i >= WARMUP:
                        latencies.append(arrival[0] - t0)
                elif i >= WARMUP:
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
    return latencies, lost


def _split(total: int, parts: int) -> list[int]:
    """``total`` in ``parts`` near-equal shares that add up to it."""
    return [total // parts + (1 if k < total % parts else 0) for k in range(parts)]


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench io", description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=positive_int, default=2000,
                    help="commands to time with authentication on, and as many off (default 2000)")
    ap.add_argument("--baseline-count", type=positive_int, default=1000, help="per authentication setting")
    ap.add_argument("--rounds", type=positive_int, default=2,
                    help="rounds per authentication setting, alternating on and off (default 2)")
    ap.add_argument("--vessel-file", default="paper-boat",
                    help="vessel file (name or path) for the thrust mapping (default paper-boat)")
    args = ap.parse_args(argv)
    rounds = args.rounds
    os.environ.pop(ENV_CONFIG, None)
    vessel = "bench-io"

    result = BenchResult("io", "vehicle_io: ThrustCommand put on Zenoh -> MANUAL_CONTROL on the "
                               "autopilot's UDP socket (vehicle_io as a subprocess)")
    e2e_ns: dict[bool, list[int]] = {True: [], False: []}
    zenoh_ns: dict[bool, list[int]] = {True: [], False: []}
    lost = {True: 0, False: 0}
    with tempfile.TemporaryDirectory(prefix="seaway-bench-io-") as tmp:
        made = credentials.create(Path(tmp) / "credentials", harness=True)
        settings: dict[bool, Auth] = {True: made, False: credentials.NONE}
        for count, base_count in zip(_split(args.count, rounds), _split(args.baseline_count, rounds),
                                     strict=True):
            for on in (True, False):  # alternate, so drift in the machine's load hits both
                latencies, n_lost = _end_to_end(count, vessel, args.vessel_file, settings[on])
                e2e_ns[on] += latencies
                lost[on] += n_lost
                gc.collect()
                gc.disable()  # as for the main measurement
                try:
                    zenoh_ns[on] += _zenoh_baseline(base_count, vessel, settings[on])
                finally:
                    gc.enable()
    gc.collect()
    gc.disable()
    try:
        udp_ns = _udp_baseline(args.baseline_count)
    finally:
        gc.enable()
    e2e, e2e_off = _ms(e2e_ns[True]), _ms(e2e_ns[False])
    zen, zen_off = _ms(zenoh_ns[True]), _ms(zenoh_ns[False])
    p99 = percentile(e2e, 99)
    result.add("e2e_median_ms", median(e2e), note="auth on")
    result.add("e2e_p99_ms", p99, target=f"< {TARGET_P99_MS:g}", ok=p99 < TARGET_P99_MS)
    result.add("e2e_max_ms", max(e2e) if e2e else float("nan"))
    result.add("commands_timed", len(e2e))
    result.add("commands_lost", lost[True], target="0", ok=lost[True] == 0,
               note="no MANUAL_CONTROL within 250 ms")
    result.add("baseline_zenoh_median_ms", median(zen),
               note="put -> callback, two sessions, loopback, auth on")
    result.add("baseline_zenoh_p99_ms", percentile(zen, 99))
    result.add("baseline_udp_median_ms", median(_ms(udp_ns)), note="one datagram, loopback")
    result.add("baseline_udp_p99_ms", percentile(_ms(udp_ns), 99))
    result.add("vehicle_io_added_median_ms", median(e2e) - median(zen) - median(_ms(udp_ns)),
               note="e2e minus both baselines")
    on_fig, off_fig = ({"e2e_median_ms": median(v), "e2e_p99_ms": percentile(v, 99),
                        "baseline_zenoh_median_ms": median(b),
                        "baseline_zenoh_p99_ms": percentile(b, 99)}
                       for v, b in ((e2e, zen), (e2e_off, zen_off)))
    for name, value in off_fig.items():
        result.add(name.replace("_ms", "_auth_off_ms"), value)
    result.add("commands_timed_auth_off", len(e2e_off))
    result.add("commands_lost_auth_off", lost[False], target="0", ok=lost[False] == 0)
    compare_auth(result, on_fig, off_fig, lambda k: f"auth_ratio_{k.removesuffix('_ms')}")
    result.meta.update({"cpus": os.cpu_count(), "load_avg_1m": round(os.getloadavg()[0], 2),
                        "vessel_file": args.vessel_file, "rounds_per_auth_setting": rounds,
                        "python": sys.version.split()[0]})
    return result
