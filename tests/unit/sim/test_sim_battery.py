"""The simulated pack (issue 17 item 1): the plant vessel's [battery], drained by the propulsion energy
the plant integrates plus the scenario's hotel power, refilled by a load; its lockstep report and its
PX4-like MAVLink fields. Pure: no bus, no clock."""

from __future__ import annotations

import math

import pytest
from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.units import NS_PER_S
from seaway.simkit.scenario import ScenarioBattery, load_scenario
from seaway.vessel.battery import BatteryParams
from seaway.vessel.model import load_vessel
from seaway_sim.battery import NOMINAL_PACK, SimPack, report_due, report_due_at
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config
from seaway_sim.px4_telemetry import battery_fields

PERIOD_NS = 100_000_000
HOTEL_W = 20.0
THRUST_N = (6.0, 4.0)


def core_with(hotel_w: float | None = HOTEL_W, initial_j: float | None = None,
              scenario: str = "paper-c1") -> SimCore:
    sc = load_scenario(scenario)
    sc = sc.model_copy(update={"battery": ScenarioBattery(initial_energy_j=initial_j,
                                                          hotel_power_w=hotel_w)})
    return SimCore(sc, load_vessel(sc.plant_vessel_file))


def test_the_pack_drains_by_propulsion_plus_hotel_power_to_the_joule() -> None:
    core = core_with(initial_j=400_000.0)
    pack = load_vessel("paper-sim").battery
    assert pack is not None and core.pack.params == pack  # the plant vessel file's [battery]
    for _ in range(50):
        core.advance(THRUST_N, PERIOD_NS)
    truth, b = core.truth(), core.battery()
    t_s = core.t_ns / NS_PER_S
    drawn = truth.energy_j + HOTEL_W * t_s
    assert truth.energy_j > 0.4 * HOTEL_W * t_s  # the thrusters' share is not negligible here
    assert b.stamp_ns == truth.stamp_ns and b.source == "sim"
    assert b.consumed_j == pytest.approx(drawn, rel=1e-12)
    assert b.remaining_j == pytest.approx(400_000.0 - drawn, rel=1e-12)
    assert b.remaining_frac == pytest.approx(b.remaining_j / pack.energy_j, rel=1e-12)
    assert (b.capacity_j, b.reserve_j) == (pack.energy_j, pack.reserve_energy_j)
    power = core.propulsion_power_w() + HOTEL_W
    assert core.propulsion_power_w() > 0
    assert b.power_w == pytest.approx(power, rel=1e-12)
    assert b.current_a == pytest.approx(power / b.voltage_v, rel=1e-12)
    # the voltage falls linearly from full to empty with the fraction left
    assert b.voltage_v == pytest.approx(
        pack.empty_v + (pack.full_v - pack.empty_v) * b.remaining_frac, rel=1e-12)


def test_defaults_full_pack_hotel_from_the_mission_and_the_nominal_pack() -> None:
    core = core_with(hotel_w=None)
    assert core.pack.initial_j == core.pack.params.energy_j  # full
    assert core.pack.hotel_power_w == core.scenario.mission.task_power_w  # T^w
    b = core.battery()
    assert (b.remaining_frac, b.consumed_j) == (1.0, 0.0)
    assert b.voltage_v == core.pack.params.full_v
    no_mission = core.scenario.model_copy(update={"mission": None, "battery": ScenarioBattery()})
    assert SimPack.of(no_mission, core.vessel).hotel_power_w == 0.0
    bare = core.vessel.model_copy(update={"battery": None})
    assert SimPack.of(core.scenario, bare).params is NOMINAL_PACK
    assert NOMINAL_PACK.energy_j == pytest.approx(10.0 * 14.8 * 3600.0)  # 10 A h at 14.8 V


def test_a_load_refills_the_pack_and_the_hotel_load_counts_from_it() -> None:
    core = core_with()
    for _ in range(30):
        core.advance(THRUST_N, PERIOD_NS)
    drained = core.battery().remaining_j
    assert drained < core.pack.initial_j
    core.load(core.scenario, core.vessel)  # real time: time goes on
    assert core.t_ns == 30 * PERIOD_NS
    assert core.battery().remaining_j == core.pack.initial_j
    core.advance((0.0, 0.0), PERIOD_NS)  # only the hotel load: one period of it, not 3.1 s
    assert core.battery().consumed_j == pytest.approx(HOTEL_W * 0.1, rel=1e-12)
    core.load(core.scenario, core.vessel, restart_time=True)  # lockstep: a new episode at t = 0
    assert core.battery().remaining_j == core.pack.initial_j


def test_an_empty_pack_stays_at_zero_and_the_empty_voltage() -> None:
    core = core_with(hotel_w=5000.0, initial_j=100.0)
    core.advance((0.0, 0.0), PERIOD_NS)  # 500 J drawn from 100 J
    b = core.battery()
    assert (b.remaining_j, b.remaining_frac) == (0.0, 0.0)
    assert b.consumed_j == pytest.approx(500.0)
    assert b.voltage_v == core.pack.params.empty_v


def test_a_scenario_cannot_start_with_more_than_the_pack_holds() -> None:
    core = core_with()
    capacity = core.pack.params.energy_j
    too_much = core.scenario.model_copy(update={"battery": ScenarioBattery(
        initial_energy_j=capacity + 1.0)})
    with pytest.raises(ConfigError, match=r"initial_energy_j .* allowed: \[0, 532800\] J"):
        SimPack.of(too_much, core.vessel)
    before = (core.scenario, core.pack, core.t_ns)
    with pytest.raises(ConfigError):
        core.load(too_much, core.vessel)
    assert (core.scenario, core.pack, core.t_ns) == before  # nothing changed


def test_a_scenario_request_whose_battery_does_not_fit_is_refused() -> None:
    sc = load_scenario("paper-c1")
    app = SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=True)
    from seaway.contract.messages import ScenarioRequest

    doc = sc.model_dump(mode="json", exclude_none=True)
    doc["battery"] = {"initial_energy_j": 1e9}
    reply = app.handle_scenario(ScenarioRequest(stamp_ns=0, action="load", scenario=doc))
    assert not reply.accepted and "initial_energy_j" in reply.reason
    assert app.episode == 0


def test_lockstep_lists_the_battery_before_the_clock_when_due_and_real_time_does_not() -> None:
    sc = load_scenario("paper-c1")
    lockstep = SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=True)
    kinds = [spec for spec, _ in lockstep.truth_outputs(None, battery=True)]
    assert kinds == [keys.SIM_TRUTH, keys.SIM_DISTURBANCE, keys.VEHICLE_BATTERY, keys.SIM_CLOCK]
    assert [spec for spec, _ in lockstep.truth_outputs(None)] == [
        keys.SIM_TRUTH, keys.SIM_DISTURBANCE, keys.SIM_CLOCK]
    real = SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=False)
    assert keys.VEHICLE_BATTERY not in [spec for spec, _ in real.truth_outputs(1.0, battery=True)]


def test_a_lockstep_period_reports_the_pack_at_t0_and_at_each_whole_second() -> None:
    period = 100_000_000
    due = [k for k in range(0, 31) if report_due_at(k * period, period)]
    assert due == [0, 10, 20, 30]
    # A period that is not a divisor of the second: the period that holds the whole second.
    assert [k for k in range(0, 15) if report_due_at(k * 150_000_000, 150_000_000)] == [0, 7, 14]
    assert report_due(999_999_999, 1_000_000_000) and not report_due(1_000_000_000, 1_999_999_999)


def test_mavlink_fields_as_px4_fills_them() -> None:
    pack = SimPack(NOMINAL_PACK, NOMINAL_PACK.energy_j, hotel_power_w=0.0)
    half = pack.reading(NOMINAL_PACK.energy_j / 2, 0, 148.0)
    ap = Px4Autopilot(Px4Config(thrust_max_n=10.0))
    bs, ss = ap.battery_status(half), ap.sys_status(0, half, True, 0)
    mid_mv = (16.8 + 13.2) / 2 * 1000
    assert abs(bs.voltages[0] - mid_mv) <= 1 and list(bs.voltages[1:]) == [65535] * 9
    assert ss.voltage_battery == bs.voltages[0]
    assert bs.current_battery == ss.current_battery == math.floor(148.0 / (mid_mv / 1000) * 100)
    assert bs.battery_remaining == ss.battery_remaining == 50
    assert abs(bs.current_consumed - 5000) <= 1  # half of 10 A h
    assert bs.energy_consumed == math.floor(NOMINAL_PACK.energy_j / 2 / 100)  # hJ
    assert (bs.id, bs.battery_function, bs.type, bs.temperature) == (0, 1, 1, 32767)
    # remaining: rounded up as PX4's ceilf; every other figure truncated (at most one unit low)
    nearly_full = pack.reading(1.0, 0, 0.0)
    f = battery_fields(nearly_full)
    assert f.remaining_pct == 100 and f.consumed_hj == 0 and f.consumed_mah == 0
    assert f.voltage_mv <= nearly_full.voltage_v * 1000 < f.voltage_mv + 1


def test_battery_params_of_capacity_and_voltage() -> None:
    p = BatteryParams(capacity_ah=2.0, nominal_voltage_v=12.0)
    assert p.energy_j == pytest.approx(2.0 * 12.0 * 3600.0)
    r = SimPack(p, p.energy_j, 0.0).reading(p.joules_from_mah(1000.0), 0, 0.0)
    assert r.consumed_mah == pytest.approx(1000.0)  # mA h at the nominal voltage, both ways
