"""vehicle_io against PX4's own firmware: PX4 SITL, SIH differential rover (airframe 10046), #19.

The firmware is the build in ``../shared/sitl/px4`` (``px4_sitl.py`` says how it is started and
observed). vehicle_io talks to PX4's onboard link, with its default configuration for PX4; the test
watches the firmware on the SIH link: the motor outputs PX4's control allocation produces
(HIL_ACTUATOR_CONTROLS, Motor1 = right, Motor2 = left, in [-1, 1]), the simulated yaw rate
(HIL_STATE_QUATERNION) and the HEARTBEAT's mode.

Skipped, saying why, only when the firmware binary is absent.
"""

from __future__ import annotations

import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, ModeRequest, ThrustCommand
from seaway.runtime.bus import Bus
from seaway_vehicle_io.px4 import MODES

from tests.conftest import BIN, Procs, wait_for
from tests.system.vehicle_io.px4_sitl import Px4Sitl, boat_params, needs_px4
from tests.system.vehicle_io.test_ardupilot_sitl import StatusWatch, hold_thrust, thrust_forwarded

pytestmark = pytest.mark.system

VIO = BIN / "seaway-vehicle-io"
REQUEST_TIMEOUT_S = 8.0  # an arm reply waits up to 1.5 s for PX4's arming-check report
ODID_MISSING = "Open Drone ID system missing"  # PX4's own text (event check_open_drone_id_missing)
THRUST_MAX_N = 75.0  # paper-boat (the lake scenario's vessel)


def custom_mode(name: str) -> int:
    main, sub = MODES[name]
    return main << 16 | sub << 24


@pytest.fixture
def px4(tmp_path):
    # The boat's parameters (px4-boat.params: no throttle slew), the failsafe ones left at PX4's
    # defaults. COM_ARM_ODID 2: PX4 refuses to arm without an Open Drone ID module, which SITL has
    # not: a refusal the test controls (the EKF's own "No heading reference" lasts only ~2 s).
    s = Px4Sitl(tmp_path, params={**boat_params(), "COM_ARM_ODID": 2})
    try:
        yield s
    finally:
        s.kill()


def start_vio(procs: Procs, env: dict[str, str], tmp: Path, url: str) -> subprocess.Popen:
    path = tmp / f"vio-{len(procs.procs)}.toml"
    path.write_text(f'mavlink = "{url}"\nautopilot = "px4"\n')
    return procs.start([str(VIO), "--config", str(path), "--scenario", "lake"], env,
                       name=f"vio-{len(procs.procs)}")


def request(bus: Bus, key: str, msg):
    return bus.request(key, msg, timeout_s=REQUEST_TIMEOUT_S)


def arm(bus: Bus):
    return request(bus, keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True))


def set_mode(bus: Bus, mode: str):
    return request(bus, keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode=mode))


def alive(p: subprocess.Popen, procs: Procs, px4: Px4Sitl) -> None:
    assert p.poll() is None, f"vehicle_io exited ({p.returncode}):\n{procs.log(p)[-3000:]}"
    assert px4.proc.poll() is None, f"PX4 exited:\n{px4.log()[-3000:]}"


def armed_in_manual(bus: Bus, procs: Procs, vio, px4: Px4Sitl) -> tuple[float, object]:
    """MANUAL, then arm: refused with PX4's reason while COM_ARM_ODID demands an ODID module,
    accepted once it does not. Returns (seconds from allowing to armed, the refusal)."""
    assert set_mode(bus, "MANUAL").accepted
    refused = arm(bus)
    alive(vio, procs, px4)
    px4.observer.set_param("COM_ARM_ODID", 0)
    t0 = time.monotonic()
    reply = arm(bus)
    while not reply.accepted:
        assert time.monotonic() - t0 < 60, f"never armed; last: {reply.reason}"
        time.sleep(1.0)
        reply = arm(bus)
    return time.monotonic() - t0, refused


@needs_px4
def test_link_verdict_rates_and_arming_reason(zenoh_env, procs, bus, tmp_path, px4):
    """The start-up verdict within 5 s of the link, with the telemetry at the requested rates and
    the failsafe PX4's defaults really give (COM_RC_LOSS_T 0.5 s, NAV_RCL_ACT 2: Hold, then Return
    after COM_FAIL_ACT_T); PX4's events metadata fetched over MAVLink FTP; an arm refused with
    PX4's own reasons (decoded from its EVENTs: the denial and the failing check), then accepted."""
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
    t_link, _ = status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60,
                            "vehicle_io's link to PX4")
    t_verdict, verdict = status.wait(
        lambda s: s.autopilot_loss_failsafe is not None and s.telemetry_rates_short is not None,
        30, "the start-up verdict")
    alive(vio, procs, px4)
    print(f"verdict {t_verdict - t_link:.2f} s after the link: {verdict.autopilot_loss_failsafe_summary}")
    assert t_verdict - t_link <= 5.0
    assert verdict.telemetry_rates_short == {}, verdict.telemetry_rates_short
    assert verdict.autopilot_loss_failsafe == "takes_over"
    summary = verdict.autopilot_loss_failsafe_summary
    assert "COM_RC_LOSS_T=0.5 s" in summary and "NAV_RCL_ACT=2 = Return" in summary
    assert "after a 5 s Hold" in summary
    log = procs.log(vio)
    assert "events metadata:" in log and "over MAVLink FTP" in log, log[-3000:]
    assert "refusing MAVLink" not in log  # PX4's messages unknown to our dialect are not "foreign"

    wanted = {"ATTITUDE": 10.0, "GLOBAL_POSITION_INT": 5.0, "GPS_RAW_INT": 5.0,
              "LOCAL_POSITION_NED": 5.0, "SYS_STATUS": 1.0, "BATTERY_STATUS": 1.0}
    _, later = status.wait(lambda s: s.stamp_ns > verdict.stamp_ns + 2.5e9
                           and set(wanted) <= set(s.rates_hz), 15, "a status with rates")
    for name, hz in wanted.items():
        assert later.rates_hz[name] >= (0.75 if hz > 1 else 0.5) * hz, (name, later.rates_hz)
        # asked for, not PX4's onboard-link default (ATTITUDE 100 Hz, GLOBAL_POSITION_INT 50 Hz)
        assert later.rates_hz[name] <= 1.5 * hz + 0.5, (name, later.rates_hz)
    print(f"rates {later.rates_hz}")

    took_s, refused = armed_in_manual(bus, procs, vio, px4)
    print(f"first arm refused: {refused.reason}; armed {took_s:.1f} s after allowing it")
    assert not refused.accepted and refused.detail["result"] == "TEMPORARILY_REJECTED"
    texts = refused.detail.get("autopilot_text", [])
    assert "Arming denied: Resolve system health failures first" in texts, refused
    assert ODID_MISSING in texts, refused
    assert all(t in refused.reason for t in texts)
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and thrust_forwarded(s), 10,
                "armed in MANUAL, thrust forwarded", fresh=True)
    alive(vio, procs, px4)
    # PX4 numbers its STATUSTEXTs from 0 on each link, so its first long one comes in chunks of
    # id 0: each text is said whole, never a 50-character piece and its tail apart. And it tags a
    # STATUSTEXT that an EVENT says too with a tab: with its events decoded, said once, untagged.
    said = re.findall(r"autopilot says: (.*?)(?: \(\d+ more like it[^)]*\))?$", procs.log(vio), re.M)
    assert "Armed by external command" in said, procs.log(vio)[-3000:]
    pieces = [t for t in said if len(t) == 50 and any(u != t and u.startswith(t) for u in said)]
    assert pieces == [] and "Arming denied: Resolve system health failures firs" not in said, said
    assert [t for t in said if t.endswith("\t")] == [], said


@needs_px4
@pytest.mark.slow
def test_directions_neutral_and_sigkill_failsafe_on_px4(zenoh_env, procs, bus, tmp_path, px4):
    """Each motor at the commanded share of full thrust within 3 %, ahead and astern; port >
    starboard turns clockwise (and the mirror); neutral at the motors within 0.4 s of the last
    command; SIGKILL of vehicle_io ends in PX4's own Hold after COM_RC_LOSS_T and Return after
    COM_FAIL_ACT_T, as the verdict said."""
    obs = px4.observer
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
    _, verdict = status.wait(lambda s: s.link_ok and s.autopilot_loss_failsafe is not None, 60,
                             "vehicle_io's link and verdict")
    assert verdict.autopilot_loss_failsafe == "takes_over"
    armed_in_manual(bus, procs, vio, px4)
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and thrust_forwarded(s), 10,
                "armed in MANUAL, thrust forwarded", fresh=True)

    # -- forward and astern: each motor at the commanded share of full thrust, within 3 % ---------
    errors = {}
    for force in (12.0, 30.0, 60.0, 75.0, -20.0, -75.0):
        hold_thrust(bus, force, force, 0.6)
        t = time.monotonic()
        hold_thrust(bus, force, force, 0.4)
        got = obs.motors_since(t)
        assert len(got) >= 5, "too few HIL_ACTUATOR_CONTROLS"
        want = force / THRUST_MAX_N
        errors[force] = max(abs(v - want) / abs(want) for m in got for v in (m.right, m.left))
        assert errors[force] <= 0.03, (force, got[-3:])
    print("worst relative motor error per command [N]: "
          + ", ".join(f"{f:g}: {e:.2%}" for f, e in errors.items()))

    # -- direction: port > starboard turns clockwise (yaw rate > 0), and the mirror -----------
    hold_thrust(bus, 40.0, 10.0, 1.5)
    t = time.monotonic()
    hold_thrust(bus, 40.0, 10.0, 1.5)
    cw = obs.mean_yaw_rate_since(t)
    m = obs.motors_since(t)[-1]
    assert m.left > m.right, m  # port (Motor2, left) the stronger
    hold_thrust(bus, 10.0, 40.0, 2.5)
    t = time.monotonic()
    hold_thrust(bus, 10.0, 40.0, 1.5)
    ccw = obs.mean_yaw_rate_since(t)
    print(f"yaw rate: port>starboard {cw:+.3f} rad/s, starboard>port {ccw:+.3f} rad/s")
    assert cw > 0.05 and ccw < -0.05, (cw, ccw)

    # -- neutral at the motors within 0.4 s of the last command ---------------------------------
    last = hold_thrust(bus, 40.0, 40.0, 1.0)
    neutral = wait_for(lambda: next((s for s in obs.motors_since(last) if s.neutral), None), 3,
                       what="neutral at the motors after the commands stop")
    print(f"neutral at the motors {neutral.mono_s - last:.3f} s after the last command")
    assert neutral.mono_s - last <= 0.4

    # -- SIGKILL: PX4's manual-control loss failsafe, Hold then Return ---------------------------
    hold_thrust(bus, 40.0, 40.0, 1.5)
    bus.publisher(keys.THRUST).put(ThrustCommand.make(
        stamp_ns=time.time_ns(), thrust_port_n=40.0, thrust_starboard_n=40.0, source="test"))
    kill_at = time.monotonic()
    procs.stop(vio, signal.SIGKILL)
    hold = wait_for(lambda: next((t for t, mode, _ in obs.modes_since(kill_at)
                                  if mode == custom_mode("HOLD")), None), 10,
                    what="PX4's Hold after the manual-control loss")
    ret = wait_for(lambda: next((t for t, mode, _ in obs.modes_since(kill_at)
                                 if mode == custom_mode("RTL")), None), 15,
                   what="PX4's Return after COM_FAIL_ACT_T")
    print(f"SIGKILL -> Hold after {hold - kill_at:.2f} s, Return after {ret - kill_at:.2f} s")
    assert hold - kill_at <= 0.5 + 2.5  # COM_RC_LOSS_T, then the commander (1.2-1.7 s measured)
    assert 5.0 - 0.5 <= ret - hold <= 5.0 + 1.5  # COM_FAIL_ACT_T Hold first
    assert px4.proc.poll() is None



@needs_px4
@pytest.mark.slow
def test_a_mode_change_by_a_second_ground_station_is_named_on_px4(zenoh_env, procs, bus, tmp_path,
                                                                   px4):
    """Armed PX4 put in Hold by another MAVLink client (the test's own, system 250): vehicle_io
    names it ``gcs_mode_change``; Seaway's own MANUAL clears it. (Disarmed, a mode change is no
    one taking the vessel from Seaway: ``FailsafeCause.mode_changed``.)"""
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, px4.vio_url)
    status.wait(lambda s: s.link_ok and s.autopilot == "px4", 60, "vehicle_io's link to PX4")
    armed_in_manual(bus, procs, vio, px4)
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and s.hold_reason is None, 10,
                "armed in MANUAL, asked by Seaway")
    main, sub = MODES["HOLD"]
    skip = len(status.poll())  # PX4 booted in Hold: only statuses from now on

    def hold_from_the_second_station():
        # Seen first, sent (again) only if not: a repeat after Seaway's own MANUAL would be a
        # second mode change by the other client.
        held = next((s for _, s in status.poll()[skip:] if s.mode == "HOLD"), None)
        if held is None:
            conn = px4.observer.sih  # PX4 SITL instance N is system N + 1
            conn.mav.command_long_send(conn.target_system, 1, 176, 0, 1, main, sub, 0, 0, 0, 0)
        return held

    held = wait_for(hold_from_the_second_station, 20, interval_s=1.0,
                    what="HOLD set by the second client")
    assert held.hold_reason == "gcs_mode_change", (held.hold_reason, held.hold_reason_detail)
    assert set_mode(bus, "MANUAL").accepted
    status.wait(lambda s: s.mode == "MANUAL" and s.hold_reason is None, 10,
                "Seaway's own MANUAL clearing it", fresh=True)
    alive(vio, procs, px4)
