"""What Seaway believes about ArduPilot Rover's own firmware (issue #63): a mission starts only
once the autopilot is healthy; its battery failsafe reaches the mission with its cause, the energy
budget takes the autopilot's lower figure, and resume is refused while the failsafe is latched.

vehicle_io, the estimator and the controller run against Rover SITL (``autopilot_stack``), the
boat modelled by the vessel file identified from it; the test watches the firmware on SERIAL1.
"""

from __future__ import annotations

import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import HOLD_REASON_TEXT
from seaway.vessel.model import load_vessel

from tests.conftest import wait_for
from tests.system.vehicle_io.autopilot_stack import Watch, start_stack
from tests.system.vehicle_io.test_ardupilot_sitl import EKF_READY_TIMEOUT_S, Sitl, needs_sitl

pytestmark = [pytest.mark.system, pytest.mark.slow]

VESSEL = "ardupilot-sitl-motorboat"
EKF_POS_HORIZ_ABS = 16
TASK_POWER_W = 5.0
MISSION = "truth"
HOME = "28.18,112.94,30"  # where the SITL fixture starts the boat


@pytest.fixture
def sitl(tmp_path):
    s = Sitl(tmp_path)
    try:
        yield s
    finally:
        s.kill()


def nonzero(cmd) -> bool:
    return (cmd.thrust_port_n, cmd.thrust_starboard_n) != (0.0, 0.0)


@needs_sitl
@pytest.mark.timeout(600)
def test_a_mission_sent_at_start_waits_for_a_healthy_autopilot(zenoh_env, procs, bus, tmp_path,
                                                               sitl):
    """Sent as the firmware boots, the mission waits, saying for what, and starts by itself once
    ArduPilot is armed and healthy: no thrust before its EKF reports an absolute (GNSS) position."""
    stack = start_stack(procs, zenoh_env, tmp_path, sitl.vio_url, "ardupilot", VESSEL, HOME)
    obs = sitl.observe()
    w = Watch(bus)
    # As soon as vehicle_io speaks (a controller that heard no vehicle yet starts at once, as in
    # lockstep): it says no link or disarmed until the firmware is up.
    w.first(keys.VEHICLE_STATUS, lambda s: True, 60, "vehicle_io's first status")
    time.sleep(1.0)
    reply = w.send_mission(MISSION, 40.0, TASK_POWER_W)
    assert reply.accepted and reply.detail["state"] == "waiting", reply
    w.first(keys.VEHICLE_STATUS, lambda s: s.link_ok and s.mode == "MANUAL", 120, "MANUAL")
    t_armed = w.arm_until_accepted(EKF_READY_TIMEOUT_S)
    t_active, _ = w.mission_in(MISSION, "active", 120)
    t_thrust, _ = w.first(keys.THRUST, lambda c: c.source == "cc-empc" and nonzero(c), 60,
                          "the first thrust of the mission")
    gps = [wait_for(lambda: next((t for t, flags in list(obs.ekf_flags)
                                  if flags & EKF_POS_HORIZ_ABS), None), 120, interval_s=0.2,
                    what="ArduPilot's EKF reporting an absolute position")]
    waits = [m.reason for _, m in w.of(keys.MISSION_STATUS) if m.state == "waiting"]
    said = sorted({r.split(";")[0] for r in waits})
    print(f"armed {t_armed:.1f}, EKF using GNSS {gps[0]:.1f}, mission active {t_active:.1f}, "
          f"first thrust {t_thrust:.1f}; waited for: {said}")
    assert t_thrust > gps[0], "thrust before ArduPilot's EKF used GNSS"
    unhealthy = [s for t, s in w.of(keys.VEHICLE_STATUS) if t >= t_armed
                 and s.thrust_withheld == "autopilot_unhealthy"]
    if t_armed < gps[0]:  # armed before it used GNSS: it waited, saying so
        assert unhealthy and any("not healthy" in r for r in waits), said
    for p in stack.values():
        assert p.poll() is None, procs.log(p)[-3000:]


@needs_sitl
@pytest.mark.timeout(600)
def test_the_battery_failsafe_pauses_with_its_cause_and_resume_waits_for_it(zenoh_env, procs, bus,
                                                                           tmp_path, sitl):
    """Under way, the pack sags to 11.8 V while ArduPilot's own count still says 98 %: the energy
    budget takes the voltage's lower figure and says so. At 11.0 V, under BATT_LOW_VOLT 11.5 V,
    ArduPilot's battery failsafe puts it in HOLD: the mission pauses naming the battery. Taken back
    to MANUAL, the thrust applies again, but resume is refused while the failsafe is latched (till
    ArduPilot reboots), saying which."""
    pack = load_vessel(VESSEL).battery
    assert pack is not None
    stack = start_stack(procs, zenoh_env, tmp_path, sitl.vio_url, "ardupilot", VESSEL, HOME)
    obs = sitl.observe()
    w = Watch(bus)
    w.first(keys.VEHICLE_STATUS, lambda s: s.link_ok and s.mode == "MANUAL", 120, "MANUAL")
    w.arm_until_accepted(EKF_READY_TIMEOUT_S)
    reply = w.send_mission(MISSION, 300.0, TASK_POWER_W)
    assert reply.accepted, reply
    w.mission_in(MISSION, "active", 120)
    for name, value in (("BATT_LOW_TIMER", 1.0), ("BATT_LOW_VOLT", 11.5), ("BATT_FS_LOW_ACT", 2.0),
                        ("SIM_BATT_VOLTAGE", 11.8)):
        obs.set_param(name, value)
    _, sagged = w.first(keys.MISSION_ENERGY, lambda b: b.battery_source == "voltage", 30,
                        "the budget taking the voltage's figure")
    battery = w.latest(keys.VEHICLE_BATTERY)
    by_volts = (11.8 - pack.empty_v) / (pack.full_v - pack.empty_v) * pack.energy_j
    print(f"autopilot: {battery.remaining_frac} at {battery.voltage_v} V; budget "
          f"{sagged.battery_remaining_j:.0f} J ({sagged.battery_source}), by volts {by_volts:.0f} J")
    assert battery.remaining_frac > 0.9  # ArduPilot's own count: blind to the voltage
    assert sagged.battery_remaining_j == pytest.approx(by_volts, rel=0.02)
    assert "takes the voltage estimate" in procs.log(stack["controller"])

    obs.set_param("SIM_BATT_VOLTAGE", 11.0)
    w.mission_in(MISSION, "paused", 30)
    # The mode change comes first, the autopilot's words for it a moment after: the reason says them
    _, paused = w.first(keys.MISSION_STATUS, lambda m: m.state == "paused" and "battery" in m.reason,
                        10, "the pause naming the battery")
    print(f"paused: {paused.reason}")
    assert HOLD_REASON_TEXT["battery"] in paused.reason, paused.reason
    assert w.set_mode("MANUAL").accepted
    w.first(keys.VEHICLE_STATUS, lambda s: s.mode == "MANUAL" and s.thrust_withheld is None, 15,
            "the thrust applied again in MANUAL")
    refused = w.command("resume")
    print(f"resume: {refused.reason}")
    assert not refused.accepted and "latched" in refused.reason, refused
    assert HOLD_REASON_TEXT["battery"] in refused.reason, refused
    assert w.latest(keys.MISSION_STATUS).state == "paused"
    for p in stack.values():
        assert p.poll() is None, procs.log(p)[-3000:]
