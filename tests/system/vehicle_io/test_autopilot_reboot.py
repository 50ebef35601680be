"""A forced reboot of ArduPilot's own firmware (Rover SITL) under vehicle_io (issue #63).

A rebooted autopilot forgets the message intervals it was asked for and streams at its defaults
(1 Hz on Rover). A reboot faster than vehicle_io's heartbeat timeout never drops the link, so only
the reboot itself (SYSTEM_TIME's boot time, or every stamp, going back) can tell vehicle_io to ask
again. SITL re-executes itself in about 3 s, so vehicle_io's heartbeat timeout is set longer here
(on a real autopilot, the issue saw a gap under the default 3 s).

vehicle_io and SITL's SERIAL0 talk over a serial line, as on a boat: two pseudo-terminals whose
bytes the test relays (a UDP or TCP link would not do: SITL re-executes itself on reboot, which
closes its TCP connections and sends UDP from a new port, which vehicle_io's source lock refuses).
The test commands the reboot on SERIAL1 (TCP 5761 + 10 I) with its own MAVLink identity. Slow: the
firmware boots twice.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import threading
import time
import tty
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import VehicleStatus
from seaway_vehicle_io import sitl
from seaway_vehicle_io.mav import mavutil

from tests.conftest import BIN, REPO, wait_for
from tests.system.vehicle_io.ardupilot_sitl import FIRMWARE, needs_sitl, sitl_instance

pytestmark = [pytest.mark.system, pytest.mark.slow]

VIO = BIN / "seaway-vehicle-io"
BOAT_PARM = REPO / "services" / "vehicle_io" / "config" / "ardupilot-boat.parm"
MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN = 246
ATTITUDE_HZ = 10.0
HEARTBEAT_TIMEOUT_S = 15.0  # longer than SITL's reboot (about 3 s): the link must not drop
AT_RATE_HZ = 7.0  # a status window of >= 2 s at 10 Hz, with margin for a loaded machine


class SerialLine:
    """Two pseudo-terminals joined: what is written to one end comes out of the other."""

    def __init__(self) -> None:
        self.m1, s1 = os.openpty()
        self.m2, s2 = os.openpty()
        for fd in (s1, s2):
            tty.setraw(fd)
        self.path1, self.path2 = os.ttyname(s1), os.ttyname(s2)
        self._slaves = (s1, s2)  # kept open: a reopening end (a rebooting SITL) finds the line
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        peer = {self.m1: self.m2, self.m2: self.m1}
        while not self._stop.is_set():
            ready, _, _ = select.select(list(peer), [], [], 0.1)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                    os.write(peer[fd], data)
                except OSError:
                    pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        for fd in (self.m1, self.m2, *self._slaves):
            with contextlib.suppress(OSError):
                os.close(fd)


def _start_sitl(tmp: Path, instance: int, serial_path: str) -> subprocess.Popen:
    assert FIRMWARE is not None
    args = sitl.command(FIRMWARE, "28.18,112.94,30,0", instance, (BOAT_PARM,))
    args[args.index("--serial0") + 1] = f"uart:{serial_path}:115200"
    run_dir = tmp / f"sitl-{instance}"
    run_dir.mkdir()
    with open(tmp / f"sitl-{instance}.log", "wb") as log:
        return subprocess.Popen(
            args, cwd=run_dir, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )


def _statuses(sub) -> list[VehicleStatus]:
    return list(sub.drain())


@needs_sitl
def test_a_fast_reboot_gets_the_telemetry_rates_asked_for_again(zenoh_env, procs, bus, tmp_path):
    instance = sitl_instance()
    line = SerialLine()
    proc = _start_sitl(tmp_path, instance, line.path1)
    obs = None
    try:
        cfg = tmp_path / "vio.toml"
        cfg.write_text(
            f'mavlink = "{line.path2}"\nautopilot = "ardupilot"\n'
            f"message_rates_hz = {{ ATTITUDE = {ATTITUDE_HZ} }}\n"
            f"heartbeat_timeout_s = {HEARTBEAT_TIMEOUT_S}\n"
        )
        sub = bus.subscribe(keys.VEHICLE_STATUS, mode="fifo")
        vio = procs.start([str(VIO), "--config", str(cfg), "--scenario", "lake"], zenoh_env, name="vio")
        seen: list[VehicleStatus] = []

        def status_where(pred, since_ns: int = 0) -> VehicleStatus | None:
            seen.extend(_statuses(sub))
            return next((s for s in seen if s.stamp_ns >= since_ns and pred(s)), None)

        wait_for(
            lambda: status_where(
                lambda s: (
                    s.link_ok
                    and s.telemetry_rates_short == {}
                    and s.rates_hz.get("ATTITUDE", 0) >= AT_RATE_HZ
                )
            ),
            120,
            interval_s=0.2,
            what="ATTITUDE at the requested rate before the reboot",
        )

        obs = wait_for(lambda: _tcp(5761 + 10 * instance), 30, interval_s=0.5, what="SITL's SERIAL1")
        obs.mav.command_long_send(1, 1, MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0, 1, 0, 0, 0, 0, 0, 0)
        t_reboot = time.time_ns()
        wait_for(
            lambda: any(w in procs.log(vio) for w in ("autopilot rebooted", "clock restarted", "link LOST")),
            60,
            interval_s=0.2,
            what="vehicle_io seeing the reboot",
        )
        # After the reboot: the rate is back at what was asked, in a status window that began
        # after vehicle_io asked again (>= 2 s windows, so 5 s after the reboot is seen).
        t_seen = time.time_ns()
        after = wait_for(
            lambda: status_where(
                lambda s: s.link_ok and s.rates_hz.get("ATTITUDE", 0) >= AT_RATE_HZ,
                since_ns=t_seen + 5_000_000_000,
            ),
            60,
            interval_s=0.2,
            what="ATTITUDE back at the requested rate after the reboot",
        )
        assert vio.poll() is None, procs.log(vio)[-3000:]
        log = procs.log(vio)
        lost = "link LOST" in log
        print(
            f"reboot seen {(t_seen - t_reboot) / 1e9:.1f} s after the command; link lost: "
            f"{lost}; ATTITUDE {after.rates_hz.get('ATTITUDE')} Hz after"
        )
        assert not lost, "the link dropped: this run did not test a fast reboot"
        assert log.count("SET_MESSAGE_INTERVAL") >= 1
    finally:
        if obs is not None:
            with contextlib.suppress(OSError):
                obs.close()
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
        line.close()


def _tcp(port: int):
    try:
        return mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{port}", source_system=250, source_component=190, autoreconnect=False
        )
    except OSError:
        return None
