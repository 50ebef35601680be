"""The battery in the loop (issue 17 item 1) as real processes: a lockstep sim publishes its pack on
vehicle/battery once a second of simulated time, listed in its PeriodDone answer, drained exactly by
its own propulsion integral plus the hotel power; in real time the simulated PX4 reports the same
pack over MAVLink."""

from __future__ import annotations

import json
import signal
import threading
from pathlib import Path

import pytest
from seaway.contract import bundle, keys
from seaway.contract.messages import BatteryState, PeriodDone, SimTruth
from seaway.contract.units import NS_PER_S
from seaway.runtime.bus import Bus
from seaway.vessel.model import load_vessel

from tests.conftest import REPO, wait_for
from tests.system.sim.test_sim_lockstep import VESSEL, start_lockstep, start_responder

pytestmark = pytest.mark.system

INITIAL_J = 300_000.0
HOTEL_W = 40.0
PERIODS = 150


def battery_scenario(tmp: Path) -> Path:
    """The lake (the responder's 30 N / 20 N move paper-boat) with a part-charged pack and a
    hotel load of its own."""
    text = (REPO / "deploy" / "scenarios" / "lake.toml").read_text()
    path = tmp / "lake-battery.toml"
    path.write_text(text + f"\n[battery]\ninitial_energy_j = {INITIAL_J}\n"
                           f"hotel_power_w = {HOTEL_W}\n")
    return path


class Seen:
    """sim/truth, vehicle/battery and the sim's answers, decoded, by stamp."""

    def __init__(self, bus: Bus) -> None:
        self.truth: dict[int, SimTruth] = {}
        self.battery: dict[int, BatteryState] = {}
        self.answers: list[PeriodDone] = []
        self._lock = threading.Lock()
        bus.subscribe_raw(f"seaway/{VESSEL}/**", self._on)

    def _on(self, sample) -> None:
        # The sim's bundle stands for the samples it carries (seaway.contract.bundle).
        parts = (bundle.unpack(sample.key, sample.payload) if sample.encoding == bundle.ENCODING
                 else [(sample.key, sample.payload, sample.encoding)])
        for key, payload, _encoding in parts:
            suffix = key.split("/", 2)[2]
            kind = {keys.SIM_TRUTH.suffix: SimTruth, keys.VEHICLE_BATTERY.suffix: BatteryState,
                    keys.LOCKSTEP_SIM.suffix: PeriodDone}.get(suffix)
            if kind is None:
                continue
            msg = kind.model_validate(json.loads(payload))
            with self._lock:
                if kind is SimTruth:
                    self.truth[msg.stamp_ns] = msg
                elif kind is BatteryState:
                    self.battery[msg.stamp_ns] = msg
                else:
                    self.answers.append(msg)


def test_lockstep_sim_publishes_its_battery_every_second_to_the_joule(procs, zenoh_env, tmp_path):
    scenario = battery_scenario(tmp_path)
    with Bus.open(VESSEL) as bus:
        seen = Seen(bus)
        sim = start_lockstep(procs, zenoh_env, "sim", "--scenario", str(scenario),
                             "--stall-repeat-s", "0.3")
        resp = start_responder(procs, zenoh_env, "responder")
        wait_for(lambda: len(seen.truth) > PERIODS + 2, 60, what=f"{PERIODS} lockstep periods")
        procs.stop(sim, signal.SIGTERM)
        procs.stop(resp, signal.SIGTERM)
    pack = load_vessel("paper-boat").battery
    assert pack is not None

    # the answer of each whole second (battery.REPORT_HZ) lists its battery report, stamped t_k,
    # beside the truth; the others list none
    answers = [a for a in seen.answers if a.stamp_ns > 0]
    assert len({a.stamp_ns for a in answers}) >= PERIODS
    for a in answers:
        due = a.stamp_ns % 1_000_000_000 == 0
        assert a.published.get(keys.VEHICLE_BATTERY.suffix) == ([a.stamp_ns] if due else None), a.published
        assert a.published[keys.SIM_TRUTH.suffix] == [a.stamp_ns]
    stamps = sorted(t for t in seen.truth if t > 0)
    assert stamps[:PERIODS] == [k * 100_000_000 for k in range(1, PERIODS + 1)]
    reported = sorted(t for t in seen.battery if t > 0)
    assert reported == [t for t in stamps if t % 1_000_000_000 == 0] and len(reported) >= 14

    # remaining = initial - (the sim's own propulsion integral + hotel x t), to the joule
    for t in reported:
        truth, b = seen.truth[t], seen.battery[t]
        drawn = truth.energy_j + HOTEL_W * t / NS_PER_S
        assert b.source == "sim"
        assert b.consumed_j == pytest.approx(drawn, rel=1e-9)
        assert b.remaining_j == pytest.approx(INITIAL_J - drawn, rel=1e-9)
        assert b.remaining_frac == pytest.approx((INITIAL_J - drawn) / pack.energy_j, rel=1e-9)
        assert (b.capacity_j, b.reserve_j) == (pack.energy_j, pack.reserve_energy_j)
        assert pack.empty_v < b.voltage_v < pack.full_v
        assert b.power_w > HOTEL_W  # the thrusters draw too (30 N / 20 N)
        assert b.current_a == pytest.approx(b.power_w / b.voltage_v, rel=1e-9)
    last = seen.truth[stamps[-1]]
    assert last.energy_j > 100.0  # the propulsion share is real, not just the hotel load
    print(f"t = {stamps[-1] / NS_PER_S:.1f} s: propulsion {last.energy_j:.1f} J, hotel "
          f"{HOTEL_W * stamps[-1] / NS_PER_S:.1f} J, "
          f"remaining {seen.battery[reported[-1]].remaining_j:.1f} J")
