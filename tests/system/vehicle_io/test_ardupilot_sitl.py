"""vehicle_io against ArduPilot's own firmware: Rover SITL as a skid-steer motorboat (issue #19).

The firmware is the built SITL in ``../shared/sitl/ardupilot`` (``SEAWAY_ARDUPILOT_SITL`` to use
another folder), started with the parameters Seaway expects on a boat
(``services/vehicle_io/config/ardupilot-boat.parm``). Each test starts its own SITL instance
(a distinct ``-I`` instance number, so its ports are its own) and always kills it at the end.

vehicle_io talks to SERIAL0 (TCP 5760 + 10 I). The test watches the firmware itself on SERIAL1
(5761 + 10 I) with a plain pymavlink connection: ``SERVO_OUTPUT_RAW`` (what the autopilot puts on
the thruster outputs, SERVO1 = left/port = function 73, SERVO3 = right/starboard = 74), ATTITUDE
and HEARTBEAT, at rates it asks for on its own link. The force at a thruster is read back as
``(pwm - trim) / (max - trim) * thrust_max_n`` (SERVOn 1000..2000 us, trim 1500; MOT_THST_ASYM 1).

Skipped, saying why, only when the firmware binary is absent.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    THRUST_APPLIED_ANYWAY,
    ArmRequest,
    BatteryState,
    ModeRequest,
    ThrustCommand,
    VehicleStatus,
)
from seaway.runtime.bus import Bus
from seaway.vessel.model import load_vessel
from seaway_vehicle_io.mav import mavlink, mavutil

from tests.conftest import BIN, REPO, Procs, wait_for
from tests.system.vehicle_io.ardupilot_sitl import START, needs_sitl, sitl_instance

pytestmark = pytest.mark.system

BOAT_PARM = REPO / "services" / "vehicle_io" / "config" / "ardupilot-boat.parm"
VIO = BIN / "seaway-vehicle-io"

THRUST_MAX_N = 75.0  # paper-boat (the lake scenario's vessel), MOT_THST_ASYM = 1: same astern
SERVO_TRIM_US, SERVO_HALF_SPAN_US = 1500, 500
RC_OVERRIDE_TIME_S = 1.0  # ardupilot-boat.parm
RADIO_FAILSAFE_S = 0.5
FS_TIMEOUT_S = 1.5  # Rover default
MODE_HOLD = 4
REQUEST_TIMEOUT_S = 5.0
EKF_READY_TIMEOUT_S = 180.0  # ~40 s on an idle machine; generous for a busy 2-core one


class Sitl:
    """One ArduPilot Rover SITL process (its own process group), and an observer on SERIAL1."""

    def __init__(self, tmp: Path) -> None:
        self.instance = sitl_instance()
        self.run_dir = tmp / f"sitl-{self.instance}"
        self.log_path = tmp / f"sitl-{self.instance}.log"
        env = dict(os.environ, EXTRA_PARM=str(BOAT_PARM))
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen(
                [str(START), str(self.run_dir), str(self.instance), "28.18,112.94,30,0", "-w"],
                env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        self.observer: Observer | None = None

    @property
    def vio_url(self) -> str:
        return f"tcp:127.0.0.1:{5760 + 10 * self.instance}"

    def observe(self) -> Observer:
        port = 5761 + 10 * self.instance
        self.observer = wait_for(lambda: _connect(port), 60, interval_s=0.5,
                                 what=f"SITL instance {self.instance} listening on {port}")
        self.observer.start()
        return self.observer

    def kill(self) -> None:
        if self.observer is not None:
            self.observer.close()
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(10)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")


def _connect(port: int) -> Observer | None:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1):
            pass
    except OSError:
        return None
    return Observer(port)


@dataclass(frozen=True)
class Servo:
    mono_s: float
    left_us: int
    right_us: int

    def force_n(self, pwm: int) -> float:
        return (pwm - SERVO_TRIM_US) / SERVO_HALF_SPAN_US * THRUST_MAX_N

    @property
    def neutral(self) -> bool:
        return abs(self.left_us - SERVO_TRIM_US) <= 2 and abs(self.right_us - SERVO_TRIM_US) <= 2


class Observer:
    """The test's own MAVLink link to the firmware (system 250): reads, never commands thrust."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{port}", source_system=250,
                                               source_component=190, dialect="ardupilotmega",
                                               autoreconnect=False)
        self.servos: deque[Servo] = deque(maxlen=5000)
        self.yawspeeds: deque[tuple[float, float]] = deque(maxlen=2000)
        self.modes: deque[tuple[float, int, bool]] = deque(maxlen=1000)
        self.last_seen: dict[str, float] = {}
        self.rc_in: tuple[int, int] | None = None  # RC1, RC3 as the autopilot reads them [us]
        self.ekf_flags: deque[tuple[float, int]] = deque(maxlen=2000)  # EKF_STATUS_REPORT flags
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        hb = self.conn.wait_heartbeat(timeout=30)
        assert hb is not None, "no HEARTBEAT from the SITL on SERIAL1"
        for msg_id, hz in ((mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW, 25),  # 50 is DENIED (loop rate)
                           (mavlink.MAVLINK_MSG_ID_ATTITUDE, 20),
                           (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 2)):
            self.conn.mav.command_long_send(self.conn.target_system, 1, 511, 0, msg_id, 1e6 / hz,
                                            0, 0, 0, 0, 0)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_msg()
            except OSError:
                return
            if msg is None:
                time.sleep(0.002)
                continue
            now = time.monotonic()
            kind = msg.get_type()
            self.last_seen[kind] = now
            if kind == "SERVO_OUTPUT_RAW":
                self.servos.append(Servo(now, msg.servo1_raw, msg.servo3_raw))
            elif kind == "RC_CHANNELS":
                self.rc_in = (msg.chan1_raw, msg.chan3_raw)
            elif kind == "ATTITUDE":
                self.yawspeeds.append((now, msg.yawspeed))
            elif kind == "EKF_STATUS_REPORT":
                self.ekf_flags.append((now, msg.flags))
            elif kind == "HEARTBEAT" and msg.autopilot == 3:
                self.modes.append((now, msg.custom_mode, bool(msg.base_mode & 128)))

    def set_param(self, name: str, value: float) -> None:
        self.conn.mav.param_set_send(self.conn.target_system, 1, name.encode(), value, 9)

    def servos_since(self, t: float) -> list[Servo]:
        return [s for s in list(self.servos) if s.mono_s >= t]

    def mean_yawspeed_since(self, t: float) -> float:
        values = [w for (m, w) in list(self.yawspeeds) if m >= t]
        assert values, "no ATTITUDE from the SITL"
        return sum(values) / len(values)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        with contextlib.suppress(OSError):
            self.conn.close()


@pytest.fixture
def sitl(tmp_path):
    s = Sitl(tmp_path)
    try:
        yield s
    finally:
        s.kill()


# -- vehicle_io -------------------------------------------------------------------------------------------


def start_vio(procs: Procs, env: dict[str, str], tmp: Path, url: str, **cfg: object):
    # vehicle_io's own identity (system 245, component 191), which ardupilot-boat.parm makes
    # ArduPilot's MAV_GCS_SYSID
    lines = [f'mavlink = "{url}"', 'autopilot = "ardupilot"']
    lines += [f"{k} = {json.dumps(v)}" for k, v in cfg.items()]
    path = tmp / f"vio-{len(procs.procs)}.toml"
    path.write_text("\n".join(lines) + "\n")
    return procs.start([str(VIO), "--config", str(path), "--scenario", "lake"], env,
                       name=f"vio-{len(procs.procs)}")


class StatusWatch:
    """Every VehicleStatus with its arrival time."""

    def __init__(self, bus: Bus) -> None:
        self.sub = bus.subscribe(keys.VEHICLE_STATUS, mode="fifo")
        self.seen: list[tuple[float, VehicleStatus]] = []

    def poll(self) -> list[tuple[float, VehicleStatus]]:
        now = time.monotonic()
        self.seen.extend((now, m) for m in self.sub.drain())
        return self.seen

    def wait(self, pred, timeout_s: float, what: str,
             fresh: bool = False) -> tuple[float, VehicleStatus]:
        """The first status satisfying ``pred``: of all seen, or (``fresh``) of those arriving
        from now on."""
        skip = len(self.poll()) if fresh else 0
        return wait_for(lambda: next(((t, m) for t, m in self.poll()[skip:] if pred(m)), None),
                        timeout_s, interval_s=0.02, what=what)


def thrust_forwarded(s: VehicleStatus) -> bool:
    """vehicle_io forwards the commanded thrust (a mission might still wait for the autopilot's
    health: that does not stop the thrust)."""
    return s.thrust_withheld is None or s.thrust_withheld in THRUST_APPLIED_ANYWAY


def arm(bus: Bus):
    return bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                       timeout_s=REQUEST_TIMEOUT_S)


def hold_thrust(bus: Bus, port_n: float, starboard_n: float, seconds: float) -> float:
    """Publish the command at 20 Hz for ``seconds``; returns the monotonic time of the last put."""
    pub = bus.publisher(keys.THRUST)
    end = time.monotonic() + seconds
    last = time.monotonic()
    while time.monotonic() < end:
        pub.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=port_n,
                                   thrust_starboard_n=starboard_n, source="test"))
        last = time.monotonic()
        time.sleep(0.05)
    return last


def alive(p: subprocess.Popen, procs: Procs, sitl: Sitl) -> None:
    assert p.poll() is None, f"vehicle_io exited ({p.returncode}):\n{procs.log(p)[-3000:]}"
    assert sitl.proc.poll() is None, f"SITL exited:\n{sitl.log()[-3000:]}"


# =====================================================================================================


@needs_sitl
def test_link_verdict_and_telemetry_rates_within_5_s(zenoh_env, procs, bus, tmp_path, sitl):
    """Connection -> the start-up verdict (failsafe parameters under 4.7's names, rates measured)
    within 5 s, with the telemetry at the rates vehicle_io asked for.

    vehicle_io connects once the autopilot has a position (as on a boat powered up before its
    companion): until its EKF has an origin, ArduPilot sends no LOCAL_POSITION_NED at all, and the
    check rightly reports it missing."""
    obs = sitl.observe()
    wait_for(lambda: "LOCAL_POSITION_NED" in obs.last_seen, 120, interval_s=0.5,
             what="the SITL's EKF origin (LOCAL_POSITION_NED)")
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url, rc_receiver="present")
    t_link, _ = status.wait(lambda s: s.link_ok and s.autopilot == "ardupilot", 90,
                            "vehicle_io's link to the SITL")
    t_verdict, verdict = status.wait(
        lambda s: s.autopilot_loss_failsafe is not None and s.telemetry_rates_short is not None,
        30, "the start-up verdict")
    alive(vio, procs, sitl)
    log = procs.log(vio)
    assert t_verdict - t_link <= 5.0, f"verdict {t_verdict - t_link:.1f} s after the link"
    assert verdict.telemetry_rates_short == {}, verdict.telemetry_rates_short
    assert verdict.autopilot_loss_failsafe == "takes_over", verdict.autopilot_loss_failsafe_summary
    assert f"held for RC_OVERRIDE_TIME={RC_OVERRIDE_TIME_S:g} s" in (
        verdict.autopilot_loss_failsafe_summary)
    assert "parameters not reported" not in log  # MAV_GCS_SYSID answered for SYSID_MYGCS
    assert "SET_MESSAGE_INTERVAL" in log and "REQUEST_DATA_STREAM" not in log  # no fallback needed

    # the rates as vehicle_io keeps measuring them, against what it asked for
    wanted = {"ATTITUDE": 10.0, "GLOBAL_POSITION_INT": 5.0, "GPS_RAW_INT": 5.0,
              "LOCAL_POSITION_NED": 5.0, "SYS_STATUS": 1.0, "BATTERY_STATUS": 1.0}
    _, later = status.wait(lambda s: s.stamp_ns > verdict.stamp_ns + 2.5e9
                           and set(wanted) <= set(s.rates_hz), 10, "a status with rates")
    for name, hz in wanted.items():
        # status windows are >= 2 s, not aligned to arrivals: a 1 Hz message may count 2 in 2.5 s
        assert later.rates_hz[name] >= (0.75 if hz > 1 else 0.5) * hz, (name, later.rates_hz)
    print(f"verdict {t_verdict - t_link:.2f} s after the link; rates {later.rates_hz}")


@needs_sitl
def test_battery_from_ardupilots_own_monitor(zenoh_env, procs, bus, tmp_path, sitl):
    """ArduPilot's battery monitor reaches the bus as a BatteryState in SI units, completed from the
    vessel file (paper-boat, the lake scenario's). The monitor is on in SITL by default
    (``BATT_MONITOR 4``, analog voltage and current, in Rover's default rover.parm) and measures
    the simulated pack, ``SIM_BATT_VOLTAGE`` (12.6 V): a change of it on the firmware is followed."""
    pack = load_vessel("paper-boat").battery
    assert pack is not None
    batteries = bus.subscribe(keys.VEHICLE_BATTERY, mode="fifo")
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url)
    seen: list[BatteryState] = []

    def first(pred):
        seen.extend(batteries.drain())
        return next((b for b in seen if pred(b)), None)

    b = wait_for(lambda: first(lambda b: b.voltage_v is not None and b.remaining_frac is not None
                               and b.consumed_j is not None), 90,
                 what="vehicle_io's first BatteryState from the SITL after its BATTERY_STATUS")
    alive(vio, procs, sitl)
    assert b.source == "autopilot" and abs(b.stamp_ns - time.time_ns()) < 30e9
    assert b.voltage_v == pytest.approx(12.6, abs=0.05)  # SIM_BATT_VOLTAGE's default
    assert 0.0 <= b.remaining_frac <= 1.0
    assert b.current_a is not None and b.current_a >= 0.0  # measured (0 A: disarmed)
    assert b.power_w == pytest.approx(b.voltage_v * b.current_a)
    assert b.consumed_j >= 0.0  # ArduPilot's energy count (hJ)
    assert b.remaining_j == pytest.approx(b.remaining_frac * pack.energy_j)
    assert (b.capacity_j, b.reserve_j) == (pack.energy_j, pack.reserve_energy_j)
    print(f"ArduPilot's battery: {b.voltage_v:.3f} V, {b.current_a:.2f} A, "
          f"{b.remaining_frac:.0%}, {b.consumed_j:.0f} J drawn")

    obs = sitl.observe()
    obs.set_param("SIM_BATT_VOLTAGE", 15.3)
    t_set = time.time_ns()
    changed = wait_for(lambda: first(lambda b: b.stamp_ns > t_set and b.voltage_v is not None
                                     and abs(b.voltage_v - 15.3) < 0.05), 20,
                       what="the new SIM_BATT_VOLTAGE in vehicle_io's BatteryState")
    print(f"SIM_BATT_VOLTAGE 15.3 V seen after {(changed.stamp_ns - t_set) / 1e9:.2f} s")
    alive(vio, procs, sitl)


@needs_sitl
@pytest.mark.slow
def test_arming_thrust_turns_neutral_and_failsafes_on_the_firmware(zenoh_env, procs, bus,
                                                                     tmp_path, sitl):
    """Arm refused before the EKF is ready with ArduPilot's own reason, accepted after; the
    thrust mapping at the servos within 3 % across the range (RC dead zone compensated); port >
    starboard turns clockwise; neutral at the servos within 0.4 s of the last command; SIGKILL of
    vehicle_io ends as its verdict said, with a receiver and without one."""
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url, rc_receiver="present")
    status.wait(lambda s: s.link_ok and s.autopilot_loss_failsafe is not None, 90,
                "vehicle_io's link and verdict")
    obs = sitl.observe()

    # -- arming: refused with the firmware's reason while the EKF starts, then accepted --------
    first = arm(bus)
    assert not first.accepted, "armed before the EKF could be ready"
    texts = first.detail.get("autopilot_text", [])
    assert texts and all(t.startswith(("PreArm:", "Arm:")) for t in texts), first
    assert texts[0] in first.reason
    print(f"first arm refused: {first.reason}")
    t0 = time.monotonic()
    reply = first
    while not reply.accepted:
        assert time.monotonic() - t0 < EKF_READY_TIMEOUT_S, f"never armed; last: {reply.reason}"
        time.sleep(2.0)
        reply = arm(bus)
        alive(vio, procs, sitl)
    print(f"armed {time.monotonic() - t0:.0f} s after the first refusal")
    # Its EKF may not use GPS yet ('autopilot_unhealthy': a mission would wait), but vehicle_io
    # forwards the thrust all the same
    status.wait(lambda s: s.armed and thrust_forwarded(s), 10, "armed, thrust forwarded")

    # -- thrust mapping: force at the servos within 3 % of the command ----------------------------
    errors = {}
    for force in (12.0, 20.0, 40.0, 60.0, 75.0, -12.0, -40.0, -75.0):
        hold_thrust(bus, force, force, 0.8)
        t = time.monotonic()
        hold_thrust(bus, force, force, 0.4)
        got = obs.servos_since(t)
        assert len(got) >= 5, "too few SERVO_OUTPUT_RAW"
        for s in got:
            for pwm in (s.left_us, s.right_us):
                err = (s.force_n(pwm) - force) / force
                errors[force] = max(errors.get(force, 0.0), abs(err))
                assert abs(err) <= 0.03, (force, s, s.force_n(pwm), obs.rc_in,
                                          [(x.mono_s - t, x.left_us, x.right_us) for x in got])
    print("worst relative force error per command [N]: "
          + ", ".join(f"{f:g}: {e:.2%}" for f, e in errors.items()))

    # -- direction: port > starboard turns clockwise (yaw rate > 0), and the mirror -----------
    hold_thrust(bus, 40.0, 10.0, 2.0)
    t = time.monotonic()
    hold_thrust(bus, 40.0, 10.0, 2.0)
    cw = obs.mean_yawspeed_since(t)
    s = obs.servos_since(t)[-1]
    assert s.left_us > s.right_us, s  # port (SERVO1, throttleLeft) the stronger
    hold_thrust(bus, 10.0, 40.0, 3.0)
    t = time.monotonic()
    hold_thrust(bus, 10.0, 40.0, 2.0)
    ccw = obs.mean_yawspeed_since(t)
    print(f"yaw rate: port>starboard {cw:+.3f} rad/s, starboard>port {ccw:+.3f} rad/s")
    assert cw > 0.05 and ccw < -0.05, (cw, ccw)

    # -- neutral at the servos within 0.4 s of the last command ---------------------------------
    last = hold_thrust(bus, 40.0, 40.0, 1.0)
    neutral = wait_for(lambda: next((s for s in obs.servos_since(last) if s.neutral), None), 3,
                       what="neutral at the servos after the commands stop")
    print(f"neutral at the servos {neutral.mono_s - last:.3f} s after the last command")
    assert neutral.mono_s - last <= 0.4

    # -- SIGKILL with a receiver: the last command held RC_OVERRIDE_TIME, then the sticks -------
    st = status.poll()[-1][1]  # the latest
    assert st.link_ok and st.autopilot_loss_failsafe == "takes_over", st
    kill_at = kill_during_thrust(bus, procs, vio)
    back = wait_for(lambda: next((s for s in obs.servos_since(kill_at) if s.neutral), None), 10,
                    what="neutral after SIGKILL (the sticks)")
    held_s = back.mono_s - kill_at
    print(f"receiver: SIGKILL -> neutral after {held_s:.2f} s (RC_OVERRIDE_TIME "
          f"{RC_OVERRIDE_TIME_S:g} s)")
    assert RC_OVERRIDE_TIME_S - 0.3 <= held_s <= RC_OVERRIDE_TIME_S + 0.6
    _, mode, armed = obs.modes[-1]
    assert (mode, armed) == (0, True)  # still MANUAL and armed: the sticks drive, nothing else

    # -- SIGKILL without a receiver: radio failsafe after 0.5 s, then Hold ---------------------------
    obs.set_param("SIM_RC_FAIL", 1)  # the simulated receiver sends no more pulses
    vio2 = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url, rc_receiver="absent")
    _, st = status.wait(lambda s: s.link_ok and s.autopilot_loss_failsafe is not None
                        and "rc_receiver = absent" in s.autopilot_loss_failsafe_summary, 60,
                        "the second vehicle_io's verdict")
    assert st.autopilot_loss_failsafe == "stops", st.autopilot_loss_failsafe_summary
    # the receiver's loss (no overrides, no pulses) itself tripped the failsafe into HOLD: back
    assert bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode="MANUAL"),
                       timeout_s=REQUEST_TIMEOUT_S).accepted
    status.wait(lambda s: s.armed and s.mode == "MANUAL" and thrust_forwarded(s), 10,
                "armed in MANUAL again", fresh=True)
    kill_at = kill_during_thrust(bus, procs, vio2)
    stopped = wait_for(lambda: next((s for s in obs.servos_since(kill_at) if s.neutral), None), 10,
                       what="neutral after SIGKILL (radio failsafe)")
    assert obs.modes[-1][1] == 0 or obs.modes[-1][0] > kill_at  # MANUAL when killed
    hold = wait_for(lambda: next((t for t, m, _ in list(obs.modes) if t > kill_at
                                  and m == MODE_HOLD), None), 15, what="HOLD after FS_TIMEOUT")
    print(f"no receiver: SIGKILL -> neutral after {stopped.mono_s - kill_at:.2f} s, HOLD after "
          f"{hold - kill_at:.2f} s")
    assert RADIO_FAILSAFE_S - 0.2 <= stopped.mono_s - kill_at <= RADIO_FAILSAFE_S + 0.5
    assert hold - kill_at <= RADIO_FAILSAFE_S + FS_TIMEOUT_S + 1.5


def kill_during_thrust(bus: Bus, procs: Procs, vio: subprocess.Popen) -> float:
    """Drive (40, 40) N, then SIGKILL vehicle_io mid-stream; returns when it was killed."""
    hold_thrust(bus, 40.0, 40.0, 1.5)
    pub = bus.publisher(keys.THRUST)
    pub.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=40.0,
                               thrust_starboard_n=40.0, source="test"))
    kill_at = time.monotonic()
    procs.stop(vio, signal.SIGKILL)
    return kill_at


@needs_sitl
@pytest.mark.slow
def test_a_mode_change_by_a_second_ground_station_is_named(zenoh_env, procs, bus, tmp_path, sitl):
    """A second ground station (the test's own link, system 250, on SERIAL1) puts the armed
    firmware in HOLD: vehicle_io names it ``gcs_mode_change`` in its status, rather than a plain
    'mode HOLD'; Seaway's own mode request then clears it. (Disarmed, a mode change is no one
    taking the vessel from Seaway: ``FailsafeCause.mode_changed``.)"""
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url, rc_receiver="present")
    obs = sitl.observe()
    status.wait(lambda s: s.link_ok and s.mode == "MANUAL", 120, "the SITL in MANUAL")
    # MANUAL (0) on the firmware itself, past INITIALISING (16), which refuses mode changes
    wait_for(lambda: obs.modes and obs.modes[-1][1] == 0, 60, what="the SITL in MANUAL")
    t0 = time.monotonic()
    while not (reply := arm(bus)).accepted:
        assert time.monotonic() - t0 < EKF_READY_TIMEOUT_S, f"never armed; last: {reply.reason}"
        time.sleep(2.0)
    status.wait(lambda s: s.armed and s.mode == "MANUAL", 10, "armed in MANUAL")

    skip = len(status.poll())

    def hold_from_the_second_station():
        # Seen first, sent (again) only if not: a repeat arriving after Seaway's own MANUAL below
        # would be a second mode change by the second station.
        held = next((s for _, s in status.poll()[skip:] if s.mode == "HOLD"), None)
        if held is None:
            obs.conn.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, 1, MODE_HOLD, 0,
                                           0, 0, 0, 0)
        return held

    held = wait_for(hold_from_the_second_station, 20, interval_s=1.0,
                    what="HOLD set by the second station")
    assert held.hold_reason == "gcs_mode_change", (held.hold_reason, held.hold_reason_detail)
    assert "gcs_mode_change" in procs.log(vio)  # logged (at WARNING)
    time.sleep(1.5)  # a HOLD the second station sent again before its first showed lands first
    reply = bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode="MANUAL"),
                        timeout_s=REQUEST_TIMEOUT_S)
    assert reply.accepted, reply
    status.wait(lambda s: s.mode == "MANUAL" and s.hold_reason is None, 10,
                "Seaway's own MANUAL clearing it", fresh=True)
    alive(vio, procs, sitl)


@needs_sitl
@pytest.mark.slow
def test_the_autopilots_low_battery_reaches_the_battery_message_and_the_status(
        zenoh_env, procs, bus, tmp_path, sitl):
    """The pack drops to 11.0 V under ArduPilot's BATT_LOW_VOLT (11.5 V): the firmware's own low
    flag reaches vehicle/battery (autopilot_level) beside its voltage and remaining, and the status
    names the battery as the cause (hold_reason). Armed with neutral thrust: ArduPilot checks its
    battery failsafes only while armed."""
    batteries = bus.subscribe(keys.VEHICLE_BATTERY, mode="fifo")
    status = StatusWatch(bus)
    vio = start_vio(procs, zenoh_env, tmp_path, sitl.vio_url)
    obs = sitl.observe()
    status.wait(lambda s: s.link_ok and s.mode == "MANUAL", 120, "the SITL in MANUAL")
    # ArduPilot checks its battery failsafes only while armed
    t0 = time.monotonic()
    while not (reply := arm(bus)).accepted:
        assert time.monotonic() - t0 < EKF_READY_TIMEOUT_S, f"never armed; last: {reply.reason}"
        time.sleep(2.0)
    for name, value in (("BATT_LOW_TIMER", 1.0), ("BATT_LOW_VOLT", 11.5), ("BATT_FS_LOW_ACT", 2.0),
                        ("SIM_BATT_VOLTAGE", 11.0)):
        obs.set_param(name, value)
    seen: list[BatteryState] = []

    def low():
        seen.extend(batteries.drain())
        return next((b for b in seen if b.autopilot_level in ("low", "critical")), None)

    b = wait_for(low, 30, interval_s=0.2, what="the autopilot's low flag in vehicle/battery")
    print(f"autopilot_level {b.autopilot_level} ({b.autopilot_level_detail!r}) at "
          f"{b.voltage_v} V, remaining {b.remaining_frac}")
    assert b.voltage_v == pytest.approx(11.0, abs=0.1)
    status.wait(lambda s: s.hold_reason == "battery", 10, "hold_reason battery")
    alive(vio, procs, sitl)
