"""Faults on ArduPilot Rover's own firmware under the whole stack, mid-mission (issue #63): a mode
change by a second ground station, a 10 s radio fade, a forced reboot, a kill and restart of the
firmware. Each time the operator must be told the truth in ``mission/status``: the mission paused,
the autopilot's cause in its reason, and it does not resume by itself; the link and the telemetry
rates come back; the operator's resume works once the autopilot applies thrust again.

The ``sitl-ardupilot`` profile (every Seaway service, the identified SITL boat), except that the
test runs the firmware itself (to kill and restart it) and vehicle_io reaches SERIAL0 through a
relay the test can fade (``tests/system/vehicle_io/relay.py``). ArduPilot's ground-station failsafe
is switched on (FS_GCS_ENABLE 1: Hold when vehicle_io's HEARTBEATs stop for FS_GCS_TIMEOUT, 5 s);
the fault-injecting ground station is the test's own link on SERIAL1 (system 250). The mission is
the lake square flown four times (about 2.5 min at the boat's cruise), so every fault lands while
it is active. Slow: one firmware boot of ~40 s before arming, then ~3 min of faults.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    HOLD_REASON_TEXT,
    ArmRequest,
    MissionCommand,
    MissionStatus,
    ModeRequest,
    VehicleStatus,
)
from seaway.runtime.bus import Bus
from seaway.simkit.scenario import load_scenario
from seaway_vehicle_io import sitl
from seaway_vehicle_io.mav import mavutil

from tests.conftest import REPO, solver_built, wait_for
from tests.system.launch.test_sitl_ardupilot import BIN, PROFILES
from tests.system.vehicle_io.ardupilot_sitl import FIRMWARE, needs_sitl, sitl_instance
from tests.system.vehicle_io.relay import TcpRelay

pytestmark = [pytest.mark.system, pytest.mark.slow]

MAV_CMD_DO_SET_MODE, MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN = 176, 246
MODE_HOLD = 4
FORCE_REBOOT = 20190226  # param6: ArduPilot reboots while armed only when forced (GCS_Common.cpp)
FAILSAFE_PARAMS = "FS_GCS_ENABLE 1\nFS_GCS_TIMEOUT 5\n"
FADE_S = 10.0
STAYS_PAUSED_S = 8.0  # watched after each fault: no resume by itself
REQUEST_TIMEOUT_S = 8.0
REBOOTED = "the autopilot rebooted"  # in the controller's reason for no link, and for disarmed
RATE_OK_HZ = 3.0  # the telemetry vehicle_io asks for comes at >= 4 Hz; Rover's default is 1 Hz


@pytest.fixture
def bus(zenoh_env):
    b = Bus.open("vessel1")
    try:
        yield b
    finally:
        b.close()


class Watch:
    """Every VehicleStatus and MissionStatus, with the time they arrived."""

    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.vehicle: list[tuple[float, VehicleStatus]] = []
        self.mission: list[tuple[float, MissionStatus]] = []
        bus.subscribe(keys.VEHICLE_STATUS, callback=lambda _k, m: self._add(self.vehicle, m))
        bus.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: self._add(self.mission, m))

    def _add(self, into: list, msg) -> None:
        with self.lock:
            into.append((time.monotonic(), msg))

    def since(self, what: str, t: float) -> list:
        with self.lock:
            return [m for (at, m) in getattr(self, what) if at >= t]

    def first(self, what: str, pred, timeout_s: float, why: str, since: float = 0.0):
        try:
            return wait_for(lambda: next((m for m in self.since(what, since) if pred(m)), None),
                            timeout_s, interval_s=0.1, what=why)
        except pytest.fail.Exception as err:
            pytest.fail(f"{err}\n{self.changes(since)}")

    def changes(self, since: float) -> str:
        """Each change of the mission's state and reason, and of the vehicle's mode, arming, link,
        withheld thrust and hold reason, since ``since``: what a failed wait needs to be read."""
        out, seen = [], {}
        for what, fields in (("mission", ("state", "reason")),
                             ("vehicle", ("link_ok", "armed", "mode", "thrust_withheld",
                                          "hold_reason"))):
            for m in self.since(what, since):
                now = tuple(getattr(m, f, None) for f in fields)
                if seen.get(what) != now:
                    seen[what] = now
                    out.append(f"{what} {m.stamp_ns / 1e9:.3f}: {dict(zip(fields, now, strict=True))}")
        return "\n".join(out[-40:])


def profile_without_sitl(tmp: Path, url: str) -> Path:
    """``sitl-ardupilot``, with no mission on start, running on, the firmware left to the test and
    vehicle_io on ``url``."""
    text = (PROFILES / "sitl-ardupilot.toml").read_text()
    blocks = text.split("[[processes]]")
    text = "[[processes]]".join(b for b in blocks if 'name = "sitl"' not in b)
    text = text.replace('after = ["sitl"]', 'after = ["recorder"]')
    text = text.replace("mission_on_start = true", "mission_on_start = false")
    text = text.replace("stop_when_complete = true", "stop_when_complete = false")
    text = text.replace('"--config", "ardupilot-sitl"]',
                        f'"--config", "ardupilot-sitl", "--mavlink", "{url}"]')
    assert text.count(url) == 1 and 'name = "sitl"' not in text
    out = tmp / "faults.toml"
    out.write_text(text)
    return out


class Firmware:
    """ArduPilot SITL on an instance of this test's own, started (and restarted) by the test with
    the profile's parameters plus ``FAILSAFE_PARAMS``."""

    def __init__(self, tmp: Path, run_json: Path) -> None:
        self.instance = sitl_instance()
        self.tmp = tmp
        self.params = tmp / "failsafe.parm"
        self.params.write_text(FAILSAFE_PARAMS)
        self.run_json = run_json
        self.starts = 0
        self.proc: subprocess.Popen | None = None
        self.start()

    def start(self) -> None:
        self.starts += 1
        log = open(self.tmp / f"sitl-{self.starts}.log", "wb")  # noqa: SIM115 - closed by the process
        self.proc = subprocess.Popen(
            [str(BIN / "seaway"), "sitl", "ardupilot", "--run", str(self.run_json), "--dir",
             str(self.tmp / "sitl"), "--instance", str(self.instance), "--params", str(self.params)],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True, cwd=REPO)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)

    @property
    def serial0_port(self) -> int:
        return sitl.BASE_TCP_PORT + sitl.PORTS_PER_INSTANCE * self.instance

    def second_station(self):
        """The test's own ground station on SERIAL1 (system 250), once the firmware listens."""
        def connect():
            try:
                return mavutil.mavlink_connection(f"tcp:127.0.0.1:{self.serial0_port + 1}",
                                                  source_system=250, source_component=190,
                                                  autoreconnect=False)
            except OSError:
                return None
        return wait_for(connect, 60, interval_s=0.5, what="SITL's SERIAL1")


def long_mission():
    """The lake scenario's mission request with its square flown four times."""
    sc = load_scenario("lake")
    assert sc.mission is not None
    req = sc.mission.to_request(time.time_ns(), mission_id="faults")
    loop = req.waypoints[1:] + req.waypoints[:1]
    # 'warn': the energy budget must not turn it home (it did, pricing the way home under the
    # disturbance estimated after a fault), nor far from the origin (PX4's SIH has its own home).
    return req.model_copy(update={"waypoints": req.waypoints + loop * 4, "on_low_energy": "warn"})


def request(bus: Bus, spec, msg):
    return bus.request(spec, msg, timeout_s=REQUEST_TIMEOUT_S)


def take_back(bus: Bus, watch: Watch) -> None:
    """The operator takes the vessel back: MANUAL (armed again if the autopilot disarmed), then
    resume; the mission flies again."""
    t = time.monotonic()
    last = watch.since("vehicle", 0.0)[-1]
    if not last.armed:
        wait_for(lambda: request(bus, keys.VEHICLE_ARM, ArmRequest.make(
            stamp_ns=time.time_ns(), arm=True)).accepted, 60, interval_s=2.0, what="armed again")
    assert request(bus, keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode="MANUAL")).accepted
    reply = wait_for(lambda: (r := request(bus, keys.MISSION_COMMAND, MissionCommand.make(
        stamp_ns=time.time_ns(), command="resume"))).accepted and r, 30, interval_s=1.0,
        what="the operator's resume accepted")
    assert reply.accepted
    watch.first("mission", lambda m: m.state == "active", 15, "the mission active again", since=t)


def paused_with(watch: Watch, since: float, words: tuple[str, ...], timeout_s: float) -> MissionStatus:
    """The first paused mission status since ``since`` whose reason has all of ``words``."""
    return watch.first("mission", lambda m: m.state == "paused" and all(w in m.reason for w in words),
                       timeout_s, f"mission paused saying {words}", since=since)


def stays_paused(watch: Watch, since: float) -> None:
    time.sleep(STAYS_PAUSED_S)
    states = {m.state for m in watch.since("mission", since)}
    assert "active" not in states, states


def rates_back(watch: Watch, since: float, timeout_s: float = 60.0) -> VehicleStatus:
    """The telemetry at its requested rates again, with the warning cleared."""
    return watch.first("vehicle", lambda s: s.link_ok and s.telemetry_rates_short == {}
                       and s.rates_hz.get("ATTITUDE", 0.0) >= RATE_OK_HZ, timeout_s,
                       "the telemetry back at its rates, the warning cleared", since=since)


@needs_sitl
@pytest.mark.timeout(900)
def test_faults_mid_mission_reach_the_operator_on_ardupilot(tmp_path, zenoh_env, procs, bus) -> None:
    assert FIRMWARE is not None
    solver_built("cc-empc", "ardupilot-sitl-motorboat")
    watch = Watch(bus)
    run_dir = tmp_path / "run"
    relay = None
    fw = None
    try:
        # The launcher writes the run description the firmware takes its home from.
        relay = TcpRelay(0)  # its upstream is set once the firmware's instance is known
        launcher = procs.launch(zenoh_env, str(profile_without_sitl(tmp_path, relay.url)),
                                "--run-dir", str(run_dir))
        wait_for(lambda: (run_dir / "run.json").exists(), 60, what="run.json")
        fw = Firmware(tmp_path, run_dir / "run.json")
        relay.upstream_port = fw.serial0_port
        gcs = fw.second_station()
        watch.first("vehicle", lambda s: s.link_ok and s.armed and s.mode == "MANUAL", 300,
                    "armed in MANUAL by the launcher")
        t = time.monotonic()
        assert request(bus, keys.MISSION_SET, long_mission()).accepted
        watch.first("mission", lambda m: m.state == "active" and m.mission_id == "faults", 30,
                    "the long mission active", since=t)
        time.sleep(3.0)

        # 1. A second ground station sets HOLD: the operator is told who.
        t = time.monotonic()
        gcs.mav.command_long_send(1, 1, MAV_CMD_DO_SET_MODE, 0, 1, MODE_HOLD, 0, 0, 0, 0, 0)
        st = paused_with(watch, t, ("mode HOLD", HOLD_REASON_TEXT["gcs_mode_change"]), 20)
        print(f"second station: {st.reason!r}")
        stays_paused(watch, time.monotonic())
        take_back(bus, watch)

        # 2. A 10 s radio fade: ArduPilot's GCS failsafe holds; the cause reaches the operator.
        time.sleep(3.0)
        t = time.monotonic()
        relay.fade(FADE_S)
        time.sleep(FADE_S)
        watch.first("vehicle", lambda s: s.link_ok, 30, "the link back", since=t + FADE_S)
        time.sleep(3.0)
        causes = {(s.mode, s.hold_reason, s.hold_reason_detail)
                  for s in watch.since("vehicle", t + FADE_S) if s.link_ok}
        print(f"radio fade: dropped {relay.dropped} bytes; after it: {causes}")
        assert ("HOLD", "gcs_link_loss") in {c[:2] for c in causes}, causes
        assert any("GCS Failsafe" in c[2] for c in causes if c[1] == "gcs_link_loss"), causes
        st = paused_with(watch, t, (HOLD_REASON_TEXT["gcs_link_loss"], "GCS Failsafe"), 30)
        print(f"radio fade: {st.reason!r}")
        rates_back(watch, time.monotonic())
        stays_paused(watch, time.monotonic())
        take_back(bus, watch)

        # 3. A forced reboot: rebooted disarmed, paused saying so, the rates asked for again.
        time.sleep(3.0)
        t = time.monotonic()
        connects = relay.upstream_connects
        gcs.mav.command_long_send(1, 1, MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0, 1, 0, 0, 0, 0,
                                  FORCE_REBOOT, 0)
        st = watch.first("mission", lambda m: m.state == "paused" and REBOOTED in m.reason, 60,
                         "the mission paused by the reboot", since=t)
        print(f"reboot: {st.reason!r}")
        assert HOLD_REASON_TEXT["gcs_mode_change"] not in st.reason  # a reboot is nobody's mode change
        wait_for(lambda: relay.upstream_connects > connects, 60, what="SITL back after its reboot")
        rates_back(watch, time.monotonic() + 3.0)
        stays_paused(watch, time.monotonic())
        gcs.close()

        # 4. The firmware killed and started again: the same, from a cold boot.
        t = time.monotonic()
        fw.kill()
        fw.start()
        gcs = fw.second_station()
        rates_back(watch, t + 5.0, timeout_s=120)
        st = watch.first("mission", lambda m: m.state == "paused" and REBOOTED in m.reason, 60,
                         "the mission paused by the restart", since=t)
        print(f"kill and restart: {st.reason!r}")
        assert HOLD_REASON_TEXT["gcs_mode_change"] not in st.reason
        stays_paused(watch, time.monotonic())
        assert launcher.poll() is None, procs.log(launcher)[-3000:]
        gcs.close()
    finally:
        if fw is not None:
            fw.kill()
        if relay is not None:
            relay.close()
