"""PX4 SITL (SIH, differential rover airframe 10046) for system tests: start, observe, stop.

The firmware is the build in ``../shared/sitl/px4`` (``SEAWAY_PX4_SITL`` to use another folder; its
README says what it is). That copy's ``bin/px4-*`` command links arrived as 3-byte text files
(``px4``) instead of symlinks, and PX4's start-up script runs every module through them, so the
binary is copied into the test's folder next to real links (3 MB, milliseconds); ``etc`` and
``test_data`` are used where they are. Each instance binds only 127.0.0.1 (the build's patch):

- vehicle_io: the onboard/API link, PX4 on 14580 + N sending to ``udpin:127.0.0.1:14540 + N``;
- the observer: the SIH display link, PX4 on 19450 + N sending HEARTBEAT, HIL_ACTUATOR_CONTROLS
  (the motor outputs in [-1, 1], Motor1 = right, Motor2 = left) and HIL_STATE_QUATERNION (the
  simulated truth) to 19410 + N. (The GCS link always sends to 14550, shared by every instance, so
  it is left alone.)

Skipped, saying why, only when the binary is absent.
"""

from __future__ import annotations

import contextlib
import os
import signal
import struct
import subprocess
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import pytest
from seaway_vehicle_io import sitl_px4
from seaway_vehicle_io.mav import mavutil
from seaway_vehicle_io.profile import decode_param_value

from tests.conftest import REPO, udp_port_free, wait_for

PX4_DIR = Path(os.environ.get("SEAWAY_PX4_SITL", REPO.parent / "shared" / "sitl" / "px4"))
PX4_BIN = PX4_DIR / "bin" / "px4"
needs_px4 = pytest.mark.skipif(
    not (PX4_BIN.exists() and (PX4_DIR / "etc").is_dir()),
    reason=f"PX4 SITL not found at {PX4_DIR} (bin/px4, etc/): build it (docs/autopilots.md) or "
           "set SEAWAY_PX4_SITL to its folder")
BOAT_PARAMS = sitl_px4.BOAT_PARAMS
MODEL = sitl_px4.MODEL  # airframe 10046: PX4's rover_differential, two motors
BOOT_MODE_HOLD = 0x03040000  # AUTO/LOITER: PX4 boots in Hold


def boat_params(path: Path = BOAT_PARAMS) -> dict[str, float]:
    """The parameters Seaway expects on a PX4 boat (``NAME VALUE`` lines, ``#`` comments)."""
    return sitl_px4.read_params(path)


def as_sent(value: float, param_type: int) -> float:
    """``value`` as PX4 holds it: a float32 for REAL32 (9), a whole number otherwise."""
    if param_type == 9:
        return struct.unpack("<f", struct.pack("<f", float(value)))[0]
    return float(int(value))


def runnable_bin(into: Path) -> Path:
    """A bin folder PX4 can run from (``seaway sitl px4``'s)."""
    return sitl_px4.runnable_bin(sitl_px4.find_firmware(PX4_DIR), into)


@dataclass(frozen=True)
class Motors:
    """One HIL_ACTUATOR_CONTROLS: the motor outputs PX4's control allocation produced."""

    mono_s: float
    right: float  # Motor1, [-1, 1]
    left: float  # Motor2

    @property
    def neutral(self) -> bool:
        return abs(self.right) < 0.02 and abs(self.left) < 0.02


class Px4Sitl:
    """One PX4 SITL process (its own process group) with an observer on the GCS and SIH links."""

    def __init__(self, tmp: Path, params: dict[str, float] | None = None) -> None:
        # PX4's stock links (vehicle_io's sends to 14540 + N): an instance of STOCK_INSTANCES,
        # locked for as long as this object or the firmware holds the descriptor.
        self.instance, self._lock_fd = sitl_px4.free_instance(sitl_px4.STOCK_INSTANCES)
        self.run_dir = tmp / f"px4-{self.instance}"
        self.run_dir.mkdir(parents=True)
        exe = runnable_bin(tmp / "px4-bin")
        self.log_path = tmp / f"px4-{self.instance}.log"
        self._env = dict(os.environ, PX4_SIM_MODEL=MODEL, PX4_RUNTIME_DIR=str(self.run_dir),
                         PX4_MAVLINK_BIND_ADDR="127.0.0.1")
        self._args = [str(exe), "-d", "-i", str(self.instance), "-w", str(self.run_dir),
                      "-t", str(PX4_DIR / "test_data"), str(PX4_DIR / "etc")]
        self._popen("wb")
        self.observer = Observer(self.instance)
        self.observer.start()
        self.boot_mono_s = time.monotonic()
        if params:
            try:
                wait_for(lambda: self.observer.heartbeats, 30, what="PX4's first HEARTBEAT")
                for name, value in params.items():
                    self.observer.set_param(name, value)
            except BaseException:
                self.kill()  # no fixture will: the object was never handed out
                raise

    def _popen(self, log_mode: str) -> None:
        with open(self.log_path, log_mode) as log:
            self.proc = subprocess.Popen(self._args, cwd=self.run_dir, env=self._env, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True,
                                         pass_fds=(self._lock_fd,))

    def restart(self) -> None:
        """SIGKILL the firmware and start it again on the same instance and parameters (saved in
        its folder): a power cycle. The observer stays."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(10)
        wait_for(lambda: udp_port_free(14580 + self.instance), 10, what="PX4's port released")
        self._popen("ab")
        self.boot_mono_s = time.monotonic()

    @property
    def vio_url(self) -> str:
        return f"udpin:127.0.0.1:{14540 + self.instance}"

    def kill(self) -> None:
        self.observer.close()
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(10)
        with contextlib.suppress(OSError):
            os.close(self._lock_fd)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")


class Observer:
    """The test's own view of the firmware on the SIH link: reads, never commands thrust."""

    def __init__(self, instance: int) -> None:
        self.sih = mavutil.mavlink_connection(f"udpin:127.0.0.1:{19410 + instance}",
                                              source_system=250, source_component=191)
        self.instance = instance
        self.motors: deque[Motors] = deque(maxlen=20000)
        self.yaw_rates: deque[tuple[float, float]] = deque(maxlen=20000)  # (mono_s, rad/s)
        self.speeds: deque[tuple[float, float, float]] = deque(maxlen=20000)  # (mono_s, vx, vy)
        self.heartbeats: deque[tuple[float, int, bool]] = deque(maxlen=5000)  # custom_mode, armed
        self.texts: deque[tuple[float, str]] = deque(maxlen=500)
        self.params: dict[str, tuple[float, int]] = {}  # name -> (value as sent, type)
        self.mission: deque = deque(maxlen=500)  # MISSION_COUNT / MISSION_ITEM_INT heard
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._run, args=(self.sih,), daemon=True)]

    def start(self) -> None:
        for t in self._threads:
            t.start()

    def _run(self, conn) -> None:
        while not self._stop.is_set():
            try:
                msg = conn.recv_msg()
            except OSError:
                return
            if msg is None:
                time.sleep(0.001)
                continue
            now = time.monotonic()
            kind = msg.get_type()
            if kind == "HIL_ACTUATOR_CONTROLS":
                self.motors.append(Motors(now, msg.controls[0], msg.controls[1]))
            elif kind == "HIL_STATE_QUATERNION":
                self.yaw_rates.append((now, msg.yawspeed))
                self.speeds.append((now, msg.vx / 100.0, msg.vy / 100.0))
            elif kind == "HEARTBEAT" and msg.autopilot == 12 and msg.get_srcComponent() == 1:
                self.heartbeats.append((now, msg.custom_mode, bool(msg.base_mode & 128)))
            elif kind == "STATUSTEXT":
                self.texts.append((now, msg.text))
            elif kind == "PARAM_VALUE":
                self.params[msg.param_id] = (msg.param_value, msg.param_type)
            elif kind in ("MISSION_COUNT", "MISSION_ITEM_INT"):
                self.mission.append(msg)

    def set_param(self, name: str, value: float, timeout_s: float = 10.0) -> None:
        """PARAM_SET on the SIH link, in the type PX4 declares (it ignores a set of another type:
        INT32 goes bytewise), confirmed by PX4's PARAM_VALUE echo."""

        def echo() -> tuple[float, int] | None:
            return self.params.get(name)

        self.params.pop(name, None)
        deadline = time.monotonic() + timeout_s
        while echo() is None:
            assert time.monotonic() < deadline, f"PX4 never reported parameter {name}"
            self.sih.mav.param_request_read_send(self.instance + 1, 1, name.encode(), -1)
            time.sleep(0.2)
        ptype = echo()[1]  # type: ignore[index]
        raw = float(value)
        if ptype != 9:  # an integer type: PX4 copies the bytes
            raw = struct.unpack("<f", struct.pack("<i", int(value)))[0]
        self.params.pop(name, None)
        while True:
            got = echo()
            if got is not None and decode_param_value(got[0], got[1]) == as_sent(value, ptype):
                return
            assert time.monotonic() < deadline, f"PX4 did not take {name} = {value} (has {got})"
            self.sih.mav.param_set_send(self.instance + 1, 1, name.encode(), raw, ptype)
            time.sleep(0.2)

    def download(self, mission_type: int, timeout_s: float = 5.0) -> list:
        """The firmware's list of ``mission_type`` (fence, rally), over the mission protocol on
        the SIH link: MISSION_REQUEST_LIST, then MISSION_REQUEST_INT per item."""

        def heard(kind: str, seq: int | None = None):
            return next((m for m in list(self.mission) if m.get_type() == kind
                         and m.mission_type == mission_type
                         and (seq is None or m.seq == seq)), None)

        target = self.instance + 1
        self.mission.clear()
        self.sih.mav.mission_request_list_send(target, 1, mission_type)
        count = wait_for(lambda: heard("MISSION_COUNT"), timeout_s, what="PX4's MISSION_COUNT")
        items = []
        for seq in range(count.count):
            self.sih.mav.mission_request_int_send(target, 1, seq, mission_type)
            items.append(wait_for(lambda seq=seq: heard("MISSION_ITEM_INT", seq), timeout_s,
                                  what=f"PX4's MISSION_ITEM_INT {seq}"))
        self.sih.mav.mission_ack_send(target, 1, 0, mission_type)
        return items

    def motors_since(self, t: float) -> list[Motors]:
        return [m for m in list(self.motors) if m.mono_s >= t]

    def mean_yaw_rate_since(self, t: float) -> float:
        values = [w for (m, w) in list(self.yaw_rates) if m >= t]
        assert values, "no HIL_STATE_QUATERNION from the SITL"
        return sum(values) / len(values)

    def modes_since(self, t: float) -> list[tuple[float, int, bool]]:
        return [h for h in list(self.heartbeats) if h[0] >= t]

    def close(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(2)
        with contextlib.suppress(OSError):
            self.sih.close()
