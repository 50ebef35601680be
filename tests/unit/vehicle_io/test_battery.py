"""vehicle_io's battery (issue 17 item 1): SYS_STATUS and BATTERY_STATUS -> BatteryState in SI units,
completed from the vessel file's [battery]; absurd fields refused; the core publishes on each battery
message. Real MAVLink messages (packed and parsed), time passed in."""

from __future__ import annotations

from types import SimpleNamespace as Ns

import pytest
from seaway.contract.messages import BatteryState
from seaway.vessel.battery import BatteryParams
from seaway.vessel.model import load_vessel
from seaway_sim.battery import SimPack
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.conversions import (
    BatteryReading,
    FieldError,
    battery_from_battery_status,
    battery_from_sys_status,
    battery_state,
)
from seaway_vehicle_io.core import VehicleIoCore
from seaway_vehicle_io.mav import mavlink

from tests.unit.vehicle_io.test_core import LIM, MS, at, heartbeat, published, wire

U16 = 65535
PACK = load_vessel("paper-boat").battery  # 10 A h at 14.8 V, a fifth in reserve
assert PACK is not None


def sys_status(mv: int = 15_000, ca: int = 420, pct: int = 50) -> object:
    return wire(mavlink.MAVLink_sys_status_message(0, 0, 0, 0, mv, ca, pct, 0, 0, 0, 0, 0, 0))


def battery_status(mv: int = 15_000, ca: int = 420, mah: int = 5000, hj: int = 2664,
                   pct: int = 50, battery_id: int = 0) -> object:
    return wire(mavlink.MAVLink_battery_status_message(
        battery_id, 0, 0, 32767, [mv] + [U16] * 9, ca, mah, hj, pct))


# -- the round trip: the simulated PX4's fields back to SI units --------------------------------


@pytest.mark.parametrize("drawn_frac", [0.0, 0.013, 0.37, 0.5, 0.999])
def test_the_sims_px4_fields_come_back_in_si_units(drawn_frac):
    """What the sim sends for its pack, through the wire and vehicle_io's conversion: every figure
    within the MAVLink unit it was truncated to (1 mV, 10 mA, 100 J, 1 mA h, 1 %)."""
    sim_pack = SimPack(PACK, PACK.energy_j, hotel_power_w=30.0)
    truth = sim_pack.reading(PACK.energy_j * drawn_frac, 0, 95.0)  # 95 W thrust + 30 W hotel
    ap = Px4Autopilot(Px4Config(thrust_max_n=75.0))
    reading = BatteryReading().merged(battery_from_sys_status(wire(ap.sys_status(0, truth, True, 0))))
    reading = reading.merged(battery_from_battery_status(wire(ap.battery_status(truth))))
    got = battery_state(reading, PACK, stamp_ns=7)
    assert got.source == "autopilot" and got.stamp_ns == 7
    assert 0 <= truth.voltage_v - got.voltage_v < 1e-3 + 1e-9
    assert 0 <= truth.current_a - got.current_a < 1e-2 + 1e-9
    assert got.power_w == pytest.approx(got.voltage_v * got.current_a)
    assert 0 <= truth.consumed_j - got.consumed_j < 100.0 + 1e-6  # the hJ resolution
    assert 0 <= got.remaining_frac - truth.remaining_frac < 0.01 + 1e-9  # PX4 rounds up
    assert got.remaining_j == pytest.approx(got.remaining_frac * PACK.energy_j)
    assert abs(got.remaining_j - truth.remaining_j) <= 0.01 * PACK.energy_j
    assert (got.capacity_j, got.reserve_j) == (PACK.energy_j, PACK.reserve_energy_j)


# -- remaining energy both ways, energy drawn both ways -------------------------------------------


def test_remaining_from_the_autopilots_fraction_else_from_the_energy_drawn():
    with_frac = battery_state(BatteryReading(remaining_frac=0.4, consumed_j=1000.0), PACK, 0)
    assert with_frac.remaining_j == pytest.approx(0.4 * PACK.energy_j)  # the fraction wins
    no_frac = battery_state(BatteryReading(consumed_j=100_000.0), PACK, 0)
    assert no_frac.remaining_j == pytest.approx(PACK.energy_j - 100_000.0)
    assert no_frac.remaining_frac == pytest.approx(no_frac.remaining_j / PACK.energy_j)
    overdrawn = battery_state(BatteryReading(consumed_j=2 * PACK.energy_j), PACK, 0)
    assert (overdrawn.remaining_j, overdrawn.remaining_frac) == (0.0, 0.0)


def test_energy_drawn_from_hj_else_from_mah_at_the_nominal_voltage():
    both = battery_from_battery_status(battery_status(mah=1000, hj=123))
    assert battery_state(both, PACK, 0).consumed_j == pytest.approx(12_300.0)  # hJ preferred
    mah_only = battery_from_battery_status(battery_status(mah=1000, hj=-1, pct=-1))
    b = battery_state(mah_only, PACK, 0)
    assert b.consumed_j == pytest.approx(1000 * 3.6 * PACK.nominal_voltage_v)
    assert b.remaining_j == pytest.approx(PACK.energy_j - b.consumed_j)


def test_without_a_battery_section_only_the_measured_figures():
    r = battery_from_battery_status(battery_status(mv=12_600, ca=250, mah=1000, hj=-1, pct=80))
    b = battery_state(r, None, 0)
    assert (b.voltage_v, b.current_a, b.remaining_frac) == (pytest.approx(12.6),
                                                            pytest.approx(2.5), 0.8)
    assert b.power_w == pytest.approx(31.5)
    assert b.consumed_j is None  # mA h alone: no nominal voltage to turn it into joules
    assert (b.remaining_j, b.capacity_j, b.reserve_j) == (None, None, None)


def test_unknown_fields_stay_unknown_and_no_power_without_both():
    r = battery_from_sys_status(sys_status(mv=U16, ca=-1, pct=-1))
    assert r == BatteryReading()
    b = battery_state(battery_from_sys_status(sys_status(ca=-1)), PACK, 0)
    assert b.voltage_v == pytest.approx(15.0) and b.current_a is None and b.power_w is None
    charging = battery_from_sys_status(sys_status(ca=-250))
    assert charging.current_a == pytest.approx(-2.5)  # below -1: charging, allowed


# -- refused ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("convert", "fields", "field"), [
    (battery_from_sys_status, dict(voltage_battery=-5, current_battery=0, battery_remaining=50),
     "voltage_battery"),
    (battery_from_sys_status, dict(voltage_battery=15_000, current_battery=0,
                                   battery_remaining=101), "battery_remaining"),
    (battery_from_sys_status, dict(voltage_battery=15_000, current_battery=40_000,
                                   battery_remaining=50), "current_battery"),
    (battery_from_battery_status, dict(voltages=[-1] + [U16] * 9, current_battery=0,
                                       current_consumed=0, energy_consumed=0,
                                       battery_remaining=50), "voltages[0]"),
    (battery_from_battery_status, dict(voltages=[15_000] + [U16] * 9, current_battery=0,
                                       current_consumed=-7, energy_consumed=0,
                                       battery_remaining=50), "current_consumed"),
    (battery_from_battery_status, dict(voltages=[15_000] + [U16] * 9, current_battery=0,
                                       current_consumed=0, energy_consumed=float("nan"),
                                       battery_remaining=50), "energy_consumed"),
    (battery_from_battery_status, dict(voltages=[15_000] + [U16] * 9, current_battery=0,
                                       current_consumed=0, energy_consumed=0,
                                       battery_remaining=120), "battery_remaining"),
])
def test_absurd_fields_are_refused_naming_the_field(convert, fields, field):
    with pytest.raises(FieldError) as err:
        convert(Ns(**fields))
    assert err.value.field == field


# -- the core ---------------------------------------------------------------------------------------


def connected(battery: BatteryParams | None = PACK) -> VehicleIoCore:
    core = VehicleIoCore(VehicleIoConfig(check_failsafe_params=False), LIM, at(0), battery=battery)
    core.on_mavlink(heartbeat(), at(1 * MS))
    assert core.link.ok
    return core


def test_the_core_publishes_on_each_battery_message_merging_the_two():
    core = connected()
    (first,) = published(core.on_mavlink(sys_status(mv=15_100, ca=500, pct=51), at(100 * MS)),
                         BatteryState)
    assert first.stamp_ns == at(100 * MS).wall_ns  # at receipt: neither message has a boot time
    assert (first.voltage_v, first.current_a, first.consumed_j) == (
        pytest.approx(15.1), pytest.approx(5.0), None)
    (second,) = published(core.on_mavlink(battery_status(hj=2500, pct=50), at(200 * MS)),
                          BatteryState)
    assert second.consumed_j == pytest.approx(250_000.0)
    assert second.remaining_j == pytest.approx(0.5 * PACK.energy_j)
    (third,) = published(core.on_mavlink(sys_status(mv=15_050, ca=-1, pct=49), at(1100 * MS)),
                         BatteryState)
    # SYS_STATUS has no energy count and this one no current: the last known are kept
    assert third.consumed_j == pytest.approx(250_000.0) and third.current_a == pytest.approx(4.2)
    assert third.remaining_frac == pytest.approx(0.49)
    # VehicleStatus keeps its battery fields from the same readings
    status = core.status(at(1200 * MS))
    assert (status.battery_voltage_v, status.battery_remaining_frac) == (pytest.approx(15.05),
                                                                         pytest.approx(0.49))


def test_a_second_battery_is_not_the_propulsion_pack():
    core = connected()
    assert not published(core.on_mavlink(battery_status(battery_id=1), at(100 * MS)), BatteryState)


def test_an_absurd_battery_message_is_dropped_counted_and_the_next_one_goes_out():
    core = connected()
    dropped = core.dropped
    outs = core.on_mavlink(sys_status(pct=100), at(50 * MS))
    assert published(outs, BatteryState)
    bad = wire(mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 15_000, 420, 101, 0, 0, 0, 0, 0, 0))
    assert published(core.on_mavlink(bad, at(100 * MS)), BatteryState) == []
    assert core.dropped == dropped + 1
    assert core.battery.remaining_frac == 1.0  # the absurd value did not get in
    (b,) = published(core.on_mavlink(sys_status(pct=99), at(1100 * MS)), BatteryState)
    assert b.remaining_frac == pytest.approx(0.99)


def test_without_a_pack_the_core_publishes_the_measured_figures_only():
    core = connected(battery=None)
    (b,) = published(core.on_mavlink(battery_status(), at(100 * MS)), BatteryState)
    assert b.voltage_v == pytest.approx(15.0) and b.remaining_frac == pytest.approx(0.5)
    assert (b.remaining_j, b.capacity_j, b.reserve_j) == (None, None, None)


def test_a_link_loss_forgets_the_battery():
    core = connected()
    core.on_mavlink(battery_status(), at(100 * MS))
    core.tick(at(10_000 * MS))  # no HEARTBEAT for 10 s: lost
    assert not core.link.ok and core.battery == BatteryReading()


# -- the autopilot's own low/critical flags ----------------------------------------------------------


def battery_status_charge(state: int, mv: int = 11_000) -> object:
    """BATTERY_STATUS with its MAVLink 2 charge_state (MAV_BATTERY_CHARGE_STATE)."""
    return wire(mavlink.MAVLink_battery_status_message(
        0, 0, 0, 32767, [mv] + [U16] * 9, 420, 5000, 2664, 98, charge_state=state))


@pytest.mark.parametrize(("state", "level"), [
    (0, None), (1, "ok"), (2, "low"), (3, "critical"), (4, "emergency"), (5, "failed"),
    (6, "unhealthy"), (7, "charging"), (42, None),
])
def test_every_charge_state_is_named(state, level):
    assert battery_from_battery_status(battery_status_charge(state)).level == level


def test_the_autopilots_low_flag_reaches_the_battery_message_beside_a_remaining_it_contradicts():
    """At 11.0 V the autopilot said low while its remaining read 98 %: both go out, so the energy
    budget can take the lower."""
    core = connected()
    (b,) = published(core.on_mavlink(battery_status_charge(2), at(100 * MS)), BatteryState)
    assert b.autopilot_level == "low" and b.remaining_frac == pytest.approx(0.98)
    assert b.voltage_v == pytest.approx(11.0)


def test_ardupilots_battery_text_raises_the_level_and_latches():
    core = connected()
    core.on_mavlink(battery_status_charge(1), at(100 * MS))
    text = b"Battery 1 is low 11.00V used 500 mAh"
    (b,) = published(core.on_mavlink(wire(mavlink.MAVLink_statustext_message(4, text, 0, 0)),
                                     at(200 * MS)), BatteryState)
    assert b.autopilot_level == "low" and "is low" in b.autopilot_level_detail
    (b,) = published(core.on_mavlink(battery_status_charge(1), at(300 * MS)), BatteryState)
    assert b.autopilot_level == "low"  # ArduPilot's battery failsafe holds until reboot
    (b,) = published(core.on_mavlink(battery_status_charge(3), at(400 * MS)), BatteryState)
    assert b.autopilot_level == "critical"  # the worse of the two
    assert core.status(at(400 * MS)).hold_reason == "battery"
