"""vehicle_io's node on the runtime's wall-clock driver (``run_node``) on the in-memory bus, against
a scripted autopilot.

The bus side needs no network: requests, thrust commands and telemetry go through a ``MemoryHub``.
The MAVLink side is the real UDP link on loopback to ``seaway_lab.fake_autopilot.FakeAutopilot``.
The thrust path is the one vehicle_io runs on Zenoh's receive thread (``inline``): here it runs in
the publishing thread, so a MANUAL_CONTROL is on its way when ``put`` returns.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, ThrustCommand, VehicleStatus
from seaway.runtime.clock import WallClock
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import ServiceContext
from seaway.vessel.model import load_vessel
from seaway_lab.fake_autopilot import FakeAutopilot
from seaway_vehicle_io.component_metadata import SendFileTransfer
from seaway_vehicle_io.config import SOURCE_SYSTEM, VehicleIoConfig
from seaway_vehicle_io.node import MAX_SLEEP_S, VehicleIoNode
from seaway_vehicle_io.thrust import ThrusterLimits

from tests.conftest import wait_for

VESSEL = "vessel1"


def udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def vio() -> Iterator[tuple[MemoryHub, MemoryBus, int, VehicleIoNode]]:
    """vehicle_io's node run on a thread, listening for the autopilot on a free UDP port."""
    hub, port, stop = MemoryHub(), udp_port(), threading.Event()
    bus = hub.bus(VESSEL)
    limits = ThrusterLimits.from_vessel(load_vessel("paper-boat"))
    node = VehicleIoNode(VehicleIoConfig(mavlink=f"udpin:127.0.0.1:{port}"), limits)
    ctx = ServiceContext(name="vehicle_io", vessel=VESSEL, bus=bus, clock=WallClock(), stop=stop,
                         run=RunDescription(run_id="unit", vessel=VESSEL), agree=False)
    loop = threading.Thread(target=run_node, args=(ctx, node, MAX_SLEEP_S), name="vehicle-io",
                            daemon=True)
    loop.start()
    try:
        yield hub, bus, port, node
    finally:
        stop.set()
        loop.join(5.0)
        bus.close()
    assert not loop.is_alive()


def test_requests_thrust_and_telemetry_through_the_memory_bus(vio) -> None:
    hub, vio_bus, port, _ = vio
    operator = hub.bus(VESSEL)
    status = operator.subscribe(keys.VEHICLE_STATUS, mode="fifo")
    seen: list[VehicleStatus] = []

    def linked() -> VehicleStatus | None:
        seen.extend(status.drain())
        return next((s for s in seen if s.link_ok and s.battery_voltage_v is not None), None)

    with FakeAutopilot(("127.0.0.1", port)) as peer:
        s = wait_for(linked, 15, what="vehicle_io's status with the link up")
        assert (s.autopilot, s.mode, s.armed) == ("px4", "MANUAL", False)

        reply = operator.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                                 timeout_s=5.0)
        assert reply.accepted and reply.detail["result"] == "ACCEPTED" and peer.armed

        # Garbage on the thrust key is counted and dropped; the next command still goes out.
        operator.raw_publisher(keys.THRUST.key(VESSEL)).put(b"\x00garbage")
        t0 = time.monotonic_ns()
        operator.publisher(keys.THRUST).put(ThrustCommand.make(
            stamp_ns=time.time_ns(), thrust_port_n=30.0, thrust_starboard_n=-20.0, source="test"))
        rec = wait_for(lambda: next((r for r in peer.manual_controls_since(t0)
                                     if (r.y, r.z) == (333, 533)), None), 2, what="MANUAL_CONTROL")
        assert (rec.target, rec.x, rec.r, rec.src_system) == (1, 0, 0, SOURCE_SYSTEM)
        assert vio_bus.stats.malformed_by_key == {keys.THRUST.key(VESSEL): 1}
        assert vio_bus.stats.received == 1


def test_an_output_that_cannot_be_packed_is_logged_and_the_loop_goes_on(vio) -> None:
    """The last line of defence behind the core's own checks: a MAVLink output pymavlink cannot
    pack (a component id past one byte) is logged and skipped; the next ones still go out and the
    node's loop keeps running."""
    hub, _, port, node = vio
    operator = hub.bus(VESSEL)
    with FakeAutopilot(("127.0.0.1", port)) as peer:
        wait_for(lambda: node.core.link.ok or None, 15, what="the link up")
        with node.lock:
            assert node._send([SendFileTransfer(1, 300, b"x")]) == []  # does not raise
        t0 = time.monotonic_ns()
        operator.publisher(keys.THRUST).put(ThrustCommand.make(
            stamp_ns=time.time_ns(), thrust_port_n=0.0, thrust_starboard_n=0.0, source="test"))
        wait_for(lambda: peer.manual_controls_since(t0) or None, 2, what="MANUAL_CONTROL after it")
