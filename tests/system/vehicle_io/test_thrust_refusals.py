"""Absurd ThrustCommands never reach the autopilot: vehicle_io as a real process, real Zenoh, real
MAVLink bytes to a scripted autopilot that records every MANUAL_CONTROL it receives.

A command stamped an hour ahead or behind (a forged or broken sender with the controller's
identity), or asking for 1e9 N, is refused, counted in ``vehicle/status.refused_thrust`` and
logged; the thrusters stay where the last good command (or the watchdog) left them.
"""

from __future__ import annotations

import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway_lab.fake_autopilot import FakeAutopilot

from tests.conftest import wait_for
from tests.system.vehicle_io.test_vehicle_io_system import (
    PERIOD_S,
    Watch,
    alive,
    start_vio,
    thrust,
    udp_port,
)

pytestmark = pytest.mark.system

HOUR_NS = 3600 * 1_000_000_000
NEUTRAL = (0, 500)  # PX4 MANUAL_CONTROL (y, z)


def test_absurd_thrust_and_stamps_produce_no_thruster_output(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    with FakeAutopilot(("127.0.0.1", port), armed=True) as peer:
        status.wait(lambda s: s.link_ok and s.armed, 15, "link, armed")
        pub = bus.publisher(keys.THRUST)

        def absurd() -> ThrustCommand:
            return ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=1e9,
                                      thrust_starboard_n=1e9, source="x")

        # Zenoh may drop the first puts of a publisher declared just now, before its route to
        # vehicle_io is made: one absurd command is repeated until vehicle_io counts it, and the
        # burst is counted from there.
        def counted():
            pub.put(absurd())
            time.sleep(0.2)
            status.seen.extend(status.sub.drain())
            return next((m for m in reversed(status.seen) if m.refused_thrust), None)

        base = dict(wait_for(counted, 15, what="a first absurd command counted").refused_thrust)
        time.sleep(1.0)  # any repeat still on its way is counted in the base
        status.seen.extend(status.sub.drain())
        base = dict(status.seen[-1].refused_thrust) if status.seen else base
        t0 = time.monotonic_ns()
        sent = 0
        for k in range(45):  # +-10 N stamped an hour ahead or behind, and 1e9 N, at 20 Hz
            now = time.time_ns()
            stamp, t1, t2 = [
                (now + HOUR_NS, 10.0, -10.0),
                (now - HOUR_NS, -10.0, 10.0),
                (now, 1e9, 1e9),
            ][k % 3]
            pub.put(ThrustCommand.make(stamp_ns=stamp, thrust_port_n=t1, thrust_starboard_n=t2, source="x"))
            sent += 1
            time.sleep(PERIOD_S)
        recs = peer.manual_controls_since(t0)
        assert len(recs) >= 20  # the stream went on the whole time
        assert all((r.y, r.z) == NEUTRAL for r in recs), {(r.y, r.z) for r in recs}

        def burst(s) -> dict[str, int]:  # refusals counted since the base
            return {k: v - base.get(k, 0) for k, v in s.refused_thrust.items() if v != base.get(k, 0)}

        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            status.seen.extend(status.sub.drain())
            if status.seen and sum(burst(status.seen[-1]).values()) >= sent:
                break
            time.sleep(0.05)
        last = status.seen[-1]
        assert burst(last) == {"stamp_ahead": 15, "stamp_behind": 15, "absurd": 15}, (base, last)
        # a good command after them goes out at once: the link and the stream are unharmed
        t1_ns = time.monotonic_ns()
        pub.put(thrust(30.0, 30.0))
        wait_for(
            lambda: any((r.y, r.z) == (0, 700) for r in peer.manual_controls_since(t1_ns)),
            2,
            what="the good command's MANUAL_CONTROL",
        )
    alive(vio, procs)
    log = procs.log(vio)
    assert "refused a ThrustCommand" in log and "ctrl/thrust" in log
