"""A locked autopilot flapping its HEARTBEAT does not flood the bus with VehicleStatus: vehicle_io
as a real process, real Zenoh, real MAVLink bytes over UDP from a scripted autopilot in a process of
its own (so it does not steal this process's interpreter).

The autopilot is the source vehicle_io locked to (the first HEARTBEAT's socket): its flapping
HEARTBEATs are admitted and followed. Before the pacing (``status_pacing``) each change of "armed"
published a VehicleStatus at once: thousands a second. Now at most one per ``MIN_STATUS_GAP_NS`` goes
out at once, on top of the periodic ones; the last state said is the autopilot's last.

Nothing here asserts a latency; the bound is on statuses per second of vehicle_io's own stamps,
with a generous margin.
"""

from __future__ import annotations

import re

import pytest
from seaway.contract import keys
from seaway.contract.messages import VehicleStatus
from seaway_vehicle_io.status_pacing import MIN_STATUS_GAP_NS

from tests.conftest import PYTHON, wait_for
from tests.system.vehicle_io.test_vehicle_io_system import Watch, alive, start_vio, udp_port

pytestmark = pytest.mark.system

STATUS_RATE_HZ = 2.0  # vehicle_io's default periodic status
FLAP_RATE_PER_S = 5_000  # HEARTBEATs a second, alternating armed and disarmed
FLAP_S = 1.5

# The autopilot: ARGS host port go_file rate_per_s duration_s. PX4 HEARTBEATs (MANUAL), armed, at
# 10 Hz until ``go_file`` exists; then ``rate`` a second for ``duration`` alternating armed and
# disarmed, paced in 1 ms slices, the last one disarmed; prints "flapped N from T0 to T1" (wall
# ns); then disarmed at 10 Hz. It reads what vehicle_io sends only to throw it away.
FLAP_SCRIPT = """
import socket, sys, time
from pathlib import Path
from seaway_vehicle_io.mav import mavlink
host, port, go = sys.argv[1], int(sys.argv[2]), Path(sys.argv[3])
rate, duration = float(sys.argv[4]), float(sys.argv[5])
tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
s.setblocking(False)

def heartbeat(armed):
    msg = mavlink.MAVLink_heartbeat_message(10, 12, 1 | (128 if armed else 0), 1 << 16, 4, 3)
    try:
        s.sendto(msg.pack(tx), (host, port))
    except OSError:
        pass

def drain():
    try:
        while True:
            s.recv(65536)
    except OSError:
        pass

while not go.exists():
    heartbeat(True)
    drain()
    time.sleep(0.1)
sent, t0, w0 = 0, time.monotonic(), time.time_ns()
while (now := time.monotonic()) - t0 < duration:
    due = int((now - t0) * rate)
    while sent < due:
        heartbeat(sent % 2 == 0)
        sent += 1
    drain()
    time.sleep(0.001)
if sent % 2 == 1:  # the last one was armed: end disarmed
    heartbeat(False)
    sent += 1
print(f"flapped {sent} from {w0} to {time.time_ns()}", flush=True)
while True:
    heartbeat(False)
    drain()
    time.sleep(0.1)
"""


def most_in_one_second(stamps: list[int]) -> int:
    """The most stamps [ns] in any 1 s window."""
    stamps = sorted(stamps)
    most, j = 0, 0
    for i, t in enumerate(stamps):
        while stamps[j] <= t - 1_000_000_000:
            j += 1
        most = max(most, i - j + 1)
    return most


def test_a_flapping_autopilot_does_not_flood_the_bus(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}",
                    check_failsafe_params=False, status_rate_hz=STATUS_RATE_HZ)
    go = tmp_path / "go"
    peer = procs.start([PYTHON, "-c", FLAP_SCRIPT, "127.0.0.1", str(port), str(go),
                        str(FLAP_RATE_PER_S), str(FLAP_S)], zenoh_env, name="flapper")
    status = Watch(bus, keys.VEHICLE_STATUS)
    status.wait(lambda s: s.link_ok and s.armed and s.thrust_withheld is None, 20,
                "link up, armed, thrust applied")
    status.clear()
    go.touch()
    flapped = wait_for(lambda: re.search(r"flapped (\d+) from (\d+) to (\d+)", procs.log(peer)),
                       30, what="the autopilot to end its flapping")
    sent, w0, w1 = (int(g) for g in flapped.groups())

    # Settled: the autopilot's steady "disarmed" is said, and a periodic status has followed it.
    def settled() -> VehicleStatus | None:
        status.seen.extend(status.sub.drain())
        done = [s for s in status.seen if s.stamp_ns > w1 and not s.armed]
        return done[-1] if len(done) >= 2 else None

    wait_for(settled, 10, what="the disarmed state said after the flapping")
    during = [s for s in status.seen if w0 <= s.stamp_ns]
    heard = max((s.rates_hz.get("HEARTBEAT", 0.0) for s in during), default=0.0)
    most = most_in_one_second([s.stamp_ns for s in during])
    print(f"{sent} flapping HEARTBEATs in {(w1 - w0) / 1e9:.2f} s (vehicle_io heard up to "
          f"{heard:.0f}/s): {len(during)} VehicleStatus, at most {most} in one second")
    # vehicle_io did hear the flapping (a loaded machine may drop some), and said both states
    assert heard >= 200, f"vehicle_io heard only {heard:.0f} HEARTBEATs/s"
    assert {s.armed for s in during} == {True, False}
    # At most 1 s / gap said at once and the periodic ones, per second: 22; before, thousands.
    bound = 1e9 / MIN_STATUS_GAP_NS + STATUS_RATE_HZ
    assert most <= 1.5 * bound, f"{most} VehicleStatus in one second (bound {bound:.0f})"
    # The last state said is the autopilot's last: disarmed, the link up.
    final = status.seen[-1]
    assert (final.link_ok, final.armed, final.thrust_withheld) == (True, False, "disarmed")
    alive(vio, procs)
    assert "link LOST" not in procs.log(vio)
    # The operator is told the vehicle flaps, once a minute at most (its own logger).
    told = [line for line in procs.log(vio).splitlines()
            if " WARNING seaway.vehicle_io.status_pacing" in line]
    assert len(told) == 1, told
