"""Telemetry time through GNSS dropouts: the real simulator, real MAVLink bytes, real vehicle_io.

A GNSS dropout used to end with the simulated PX4 sending its last fix again, stamped 5 s back;
vehicle_io took that one message for an autopilot reboot, reset its boot-time offset 5 s wrong and
refused every message after it for good. Here a scenario with frequent dropouts runs for some
seconds and every sensor stream must keep flowing through vehicle_io, stamped near its arrival.
"""

from __future__ import annotations

import itertools
import time

import pytest
from seaway.contract import keys

from tests.conftest import BIN, REPO
from tests.system.vehicle_io.test_vehicle_io_system import SIM, Watch, needs_sim, udp_port

pytestmark = pytest.mark.system

VIO = BIN / "seaway-vehicle-io"
LAKE = REPO / "deploy" / "scenarios" / "lake.toml"
RUN_S = 10.0  # seeded dropouts (below) put several in the first seconds of sim time


def dropout_scenario(tmp_path) -> str:
    """The lake scenario with a GNSS dropout of 1.5 s every 2 s or so (Poisson, seeded)."""
    text = LAKE.read_text().replace(
        "[sensors]\n", "[sensors]\ngnss_dropout_rate_per_s = 0.5\ngnss_dropout_duration_s = 1.5\n"
    )
    path = tmp_path / "lake-dropouts.toml"
    path.write_text(text)
    return str(path)


@needs_sim
def test_sensor_streams_survive_gnss_dropouts(zenoh_env, procs, bus, tmp_path):
    scenario = dropout_scenario(tmp_path)
    port = udp_port()
    procs.start(
        [str(SIM), "--mavlink", f"udpin:127.0.0.1:{port}", "--scenario", scenario], zenoh_env, name="sim"
    )
    cfg = tmp_path / "vio.toml"
    cfg.write_text(f'mavlink = "udpout:127.0.0.1:{port}"\n')
    vio = procs.start([str(VIO), "--config", str(cfg), "--scenario", scenario], zenoh_env, name="vio")
    status = Watch(bus, keys.VEHICLE_STATUS)
    status.wait(lambda s: s.link_ok, 15, "vehicle_io to see the sim's heartbeat")
    gnss, att = Watch(bus, keys.GNSS), Watch(bus, keys.ATTITUDE)
    arrivals: dict[str, list[tuple[float, int]]] = {"gnss": [], "att": []}
    end = time.monotonic() + RUN_S
    while time.monotonic() < end:
        now_wall = time.time_ns()
        for name, w in (("gnss", gnss), ("att", att)):
            arrivals[name] += [(time.monotonic(), m.stamp_ns - now_wall) for m in w.sub.drain()]
        time.sleep(0.02)
    assert vio.poll() is None, procs.log(vio)[-3000:]

    def gaps(name: str) -> list[float]:
        t = [a for a, _ in arrivals[name]]
        return [b - a for a, b in itertools.pairwise(t)]

    # Dropouts happened (fixes paused over a second) and fixes came back after each one.
    assert max(gaps("gnss")) > 1.0, "no GNSS dropout in the run: the test proves nothing"
    assert arrivals["gnss"][-1][0] > end - 1.5 - 1.0
    # Attitude never paused (20 Hz: a gap of 1 s would be a refused stream), to the end.
    assert max(gaps("att")) < 1.0
    assert arrivals["att"][-1][0] > end - 0.5
    # Every stamp is near its arrival: no message was stamped seconds off.
    for name in arrivals:
        assert all(-1e9 < d <= 0.1e9 for _, d in arrivals[name]), name
    final = status.wait(lambda s: True, 3, "a status")
    assert final.dropped_messages == 0
