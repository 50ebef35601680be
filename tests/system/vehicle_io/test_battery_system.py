"""The battery in the loop in real time (issue 17 item 1): the simulator's PX4 reports its pack over
MAVLink (SYS_STATUS, BATTERY_STATUS), and vehicle_io, the only MAVLink speaker, publishes it on
vehicle/battery in SI units, completed from the vessel file. Real processes, real UDP, real Zenoh."""

from __future__ import annotations

import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import BatteryState
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel

from tests.conftest import wait_for
from tests.system.vehicle_io.test_vehicle_io_system import (
    alive,
    needs_sim,
    start_sim,
    start_vio,
    udp_port,
)

pytestmark = pytest.mark.system


@needs_sim
def test_the_sims_pack_reaches_the_bus_through_vehicle_io(zenoh_env, procs, bus, tmp_path):
    """Idle (disarmed), the pack feeds only the hotel load, the lake mission's task power: vehicle_io's
    current is that power over the voltage it measures, and the energy drawn grows at that power."""
    lake = load_scenario("lake")
    hotel_w = lake.hotel_power_w
    pack = load_vessel(lake.plant_vessel_file).battery
    assert pack is not None and hotel_w > 100.0  # 250 W: a clear signal at 10 mA / 100 J resolution
    port = udp_port()
    start_sim(procs, zenoh_env, port)  # the lake scenario, the sim's default
    batteries = bus.subscribe(keys.VEHICLE_BATTERY, mode="fifo")
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}")
    seen: list[BatteryState] = []

    def first(pred):
        seen.extend(batteries.drain())
        return next((b for b in seen if pred(b)), None)

    a = wait_for(lambda: first(lambda b: b.consumed_j is not None and b.consumed_j > 0), 30,
                 what="vehicle_io's first BatteryState with the energy drawn")
    b = wait_for(lambda: first(lambda b: b.consumed_j is not None
                               and b.stamp_ns >= a.stamp_ns + 5_000_000_000), 15,
                 what="a BatteryState 5 s later")
    alive(vio, procs)
    for m in (a, b):
        assert m.source == "autopilot" and abs(m.stamp_ns - time.time_ns()) < 30e9
        assert pack.empty_v <= m.voltage_v <= pack.full_v
        assert m.current_a == pytest.approx(hotel_w / m.voltage_v, abs=0.02)  # cA, truncated
        assert m.power_w == pytest.approx(m.voltage_v * m.current_a)
        assert m.remaining_j == pytest.approx(m.remaining_frac * pack.energy_j)
        assert (m.capacity_j, m.reserve_j) == (pack.energy_j, pack.reserve_energy_j)
    # The hotel load drains it between the two. Stamps are receipt times (+-0.3 s of jitter), and a
    # report sent on SYS_STATUS carries the energy count of the last BATTERY_STATUS (1 s older at
    # most: the sim sends both at 1 Hz); the count itself is in 100 J steps.
    dt_s = (b.stamp_ns - a.stamp_ns) / 1e9
    slack_j = hotel_w * (0.3 + 1.0) + 100.0
    assert abs(b.consumed_j - a.consumed_j - hotel_w * dt_s) <= slack_j
    print(f"{dt_s:.2f} s apart: {b.consumed_j - a.consumed_j:.0f} J drawn at "
          f"{b.voltage_v:.3f} V, {b.current_a:.2f} A; remaining {b.remaining_frac:.0%}")
