"""A minimal scripted MAVLink autopilot: the other end of vehicle_io for tests and the benchmark.

Not a simulator (the sim service is that): it speaks just enough PX4 or ArduPilot MAVLink to drive
vehicle_io, over real UDP, and records what it receives:

* HEARTBEAT at 1 Hz (autopilot 12 or 3, armed flag, custom_mode of the current mode);
* telemetry with ``time_boot_ms`` (ATTITUDE, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, GPS_RAW_INT,
  SYS_STATUS) at modest rates;
* COMMAND_LONG: ARM_DISARM and DO_SET_MODE answered with COMMAND_ACK (ACCEPTED, or a configured
  refusal); PARAM_REQUEST_READ answered from a parameter table (PX4 integers bytewise-encoded,
  as PX4 does);
* every MANUAL_CONTROL received is recorded with its monotonic arrival time (and appended to a
  JSON-lines file in process mode), which is how tests measure the watchdog at the MAVLink side.

Run as a process: ``python -m seaway_lab.fake_autopilot --to 127.0.0.1:14540 --record mc.jsonl``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import socket
import struct
import threading
import time
from dataclasses import dataclass
from typing import Any

from seaway.runtime.service import install_stop_signals
from seaway_vehicle_io import ardupilot, px4
from seaway_vehicle_io.mav import mavlink

PX4_DEFAULT_PARAMS: dict[str, tuple[float, int]] = {
    # name: (value, MAV_PARAM_TYPE); PX4 defaults per docs/autopilots.md A.3, except NAV_RCL_ACT
    # set to 1 (Hold), the recommended value.
    "COM_RC_IN_MODE": (1, 6), "COM_RC_LOSS_T": (0.5, 9), "NAV_RCL_ACT": (1, 6),
    "COM_FAIL_ACT_T": (5.0, 9), "NAV_DLL_ACT": (0, 6), "CA_AIRFRAME": (6, 6),
    # What px4-boat.params sets: no throttle slew, the roll stick at full scale.
    "RO_ACCEL_LIM": (0.0, 9), "RO_DECEL_LIM": (0.0, 9), "RO_MAX_THR_SPEED": (3.2, 9),
    "RD_YAW_STK_GAIN": (1.0, 9),
}
ARDUPILOT_DEFAULT_PARAMS: dict[str, tuple[float, int]] = {
    "FS_THR_ENABLE": (1, 2), "FS_ACTION": (2, 2), "FS_TIMEOUT": (1.5, 9), "FS_GCS_ENABLE": (0, 2),
    "RC_OVERRIDE_TIME": (3.0, 9), "RC_OPTIONS": (0, 4), "PILOT_STEER_TYPE": (1, 2),
    "SYSID_MYGCS": (255, 4), "FRAME_CLASS": (2, 2), "MOT_SLEWRATE": (0, 4),
    "MOT_THST_ASYM": (1.0, 9), "RC1_DZ": (0, 4), "RC3_DZ": (0, 4),
    # the RC calibration vehicle_io inverts (no dead zone, trim mid-range: the plain mapping)
    "RCMAP_ROLL": (1, 1), "RCMAP_THROTTLE": (3, 1),
    **{f"RC{ch}_{f}": (v, 4) for ch in (1, 3)
       for f, v in (("MIN", 1000), ("TRIM", 1500), ("MAX", 2000), ("REVERSED", 0))},
}


@dataclass(frozen=True)
class ManualControlRecord:
    arrival_mono_ns: int
    target: int
    x: int
    y: int
    z: int
    r: int
    src_system: int


def _bytewise(value: float, param_type: int) -> float:
    """PX4's integer parameter encoding: the int32's bytes in the float field."""
    if param_type == 9:
        return float(value)
    return struct.unpack("<f", struct.pack("<i", int(value)))[0]


class FakeAutopilot:
    """A scripted autopilot on a UDP socket, sending to ``to`` (vehicle_io's udpin address)."""

    def __init__(self, to: tuple[str, int], autopilot: str = "px4", sysid: int = 1,
                 compid: int = 1, armed: bool = False, telemetry: bool = True,
                 params: dict[str, tuple[float, int]] | None = None,
                 refuse_arm_result: int | None = None, record_path: str | None = None) -> None:
        if autopilot not in ("px4", "ardupilot"):
            raise ValueError("autopilot must be px4 or ardupilot")
        self.to = to
        self.autopilot = autopilot
        self.profile = px4.PROFILE if autopilot == "px4" else ardupilot.PROFILE
        self.armed = armed
        self.mode = "MANUAL"
        self.telemetry = telemetry
        self.params = dict(params if params is not None else (
            PX4_DEFAULT_PARAMS if autopilot == "px4" else ARDUPILOT_DEFAULT_PARAMS))
        self.refuse_arm_result = refuse_arm_result
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.boot_mono_ns = time.monotonic_ns()
        self.lock = threading.Lock()
        self.manual_controls: list[ManualControlRecord] = []
        self.received: dict[str, int] = {}
        self.commands: list[tuple[int, tuple[float, ...]]] = []
        self.on_manual_control: Any = None  # optional callback(record), from the receive thread
        self._record = open(record_path, "a", encoding="utf-8") if record_path else None  # noqa: SIM115
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    # -- lifecycle -----------------------------------------------------------------------------

    def start(self) -> FakeAutopilot:
        for target, name in ((self._rx_loop, "peer-rx"), (self._tx_loop, "peer-tx")):
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)
        return self

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(2.0)
        self.sock.close()
        if self._record:
            self._record.close()

    def __enter__(self) -> FakeAutopilot:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- sending -------------------------------------------------------------------------------

    def time_boot_ms(self) -> int:
        return (time.monotonic_ns() - self.boot_mono_ns) // 1_000_000

    def send(self, msg: Any) -> None:
        self.send_raw(msg.pack(self.mav))

    def send_raw(self, data: bytes) -> None:
        # Nobody listening yet gives ECONNREFUSED on loopback: like a real autopilot, go on.
        with contextlib.suppress(OSError):
            self.sock.sendto(data, self.to)

    def heartbeat(self) -> None:
        with self.lock:
            base = 1 | (128 if self.armed else 0)
            if self.autopilot == "px4":
                main, sub = px4.MODES[self.mode]
                custom = (main << 16) | (sub << 24)
                self.send(mavlink.MAVLink_heartbeat_message(10, 12, base, custom, 4, 3))
            else:
                custom = ardupilot.MODES[self.mode]
                self.send(mavlink.MAVLink_heartbeat_message(11, 3, base, custom, 4, 3))

    def send_telemetry(self, k: int) -> None:
        t = self.time_boot_ms()
        yaw = math.remainder(0.01 * k, 2 * math.pi)
        self.send(mavlink.MAVLink_attitude_message(t, 0.01, -0.02, yaw, 0.0, 0.0, 0.1))
        if k % 4 == 0:
            self.send(mavlink.MAVLink_global_position_int_message(
                t, 473977420, 85455940, 488_000, 0, 150, -50, 0, 0))
            self.send(mavlink.MAVLink_local_position_ned_message(t, 1.5, -2.0, 0.0, 1.5, -0.5, 0.0))
        if k % 20 == 0:
            self.send(mavlink.MAVLink_gps_raw_int_message(
                t * 1000, 3, 473977420, 85455940, 488_000, 80, 120, 150, 0, 12, h_acc=1200))
            self.send(mavlink.MAVLink_sys_status_message(
                0, 0, 0, 100, 16_200, 150, 87, 0, 0, 0, 0, 0, 0))

    # -- loops -------------------------------------------------------------------------------------

    def _tx_loop(self) -> None:
        k = 0
        next_hb = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_hb:
                self.heartbeat()
                next_hb += 1.0
            if self.telemetry:
                self.send_telemetry(k)
            k += 1
            self._stop.wait(0.05)

    def _rx_loop(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(2048)
            except (TimeoutError, BlockingIOError):
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            arrival = time.monotonic_ns()
            try:
                msgs = self.parser.parse_buffer(data) or []
            except Exception:
                continue
            for msg in msgs:
                self._handle(msg, arrival)

    def _handle(self, msg: Any, arrival_ns: int) -> None:
        mtype = msg.get_type()
        with self.lock:
            self.received[mtype] = self.received.get(mtype, 0) + 1
        if mtype == "MANUAL_CONTROL":
            rec = ManualControlRecord(arrival_ns, msg.target, msg.x, msg.y, msg.z, msg.r,
                                      msg.get_srcSystem())
            with self.lock:
                self.manual_controls.append(rec)
            if self._record:
                self._record.write(json.dumps(rec.__dict__) + "\n")
                self._record.flush()
            cb = self.on_manual_control
            if cb is not None:
                cb(rec)
        elif mtype == "COMMAND_LONG":
            self._on_command(msg)
        elif mtype == "PARAM_REQUEST_READ":
            name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else msg.param_id
            if name in self.params:
                value, ptype = self.params[name]
                encoded = _bytewise(value, ptype) if self.autopilot == "px4" else float(value)
                self.send(mavlink.MAVLink_param_value_message(
                    name.encode(), encoded, ptype, len(self.params), 0))

    def _on_command(self, msg: Any) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6,
                  msg.param7)
        with self.lock:
            self.commands.append((msg.command, params))
        result = 0
        if msg.command == 400:
            if msg.param1 == 1.0 and self.refuse_arm_result is not None:
                result = self.refuse_arm_result
            else:
                with self.lock:
                    self.armed = msg.param1 == 1.0
        elif msg.command == 176:
            name = self._mode_name(params)
            if name is None:
                result = 2  # DENIED
            else:
                with self.lock:
                    self.mode = name
        else:
            result = 3  # UNSUPPORTED
        self.send(mavlink.MAVLink_command_ack_message(msg.command, result, 0, 0,
                                                      msg.get_srcSystem(), msg.get_srcComponent()))
        if result == 0:
            self.heartbeat()  # like PX4, report the new state promptly

    def _mode_name(self, params: tuple[float, ...]) -> str | None:
        if self.autopilot == "px4":
            want = (int(params[1]), int(params[2]))
            return next((n for n, v in px4.MODES.items() if v == want), None)
        return next((n for n, v in ardupilot.MODES.items() if v == int(params[1])), None)

    # -- queries for tests ---------------------------------------------------------------------

    def manual_controls_since(self, mono_ns: int) -> list[ManualControlRecord]:
        with self.lock:
            return [r for r in self.manual_controls if r.arrival_mono_ns >= mono_ns]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m seaway_lab.fake_autopilot",
                                 description="a scripted MAVLink autopilot for tests")
    ap.add_argument("--to", required=True, help="HOST:PORT vehicle_io listens on (udpin)")
    ap.add_argument("--autopilot", choices=("px4", "ardupilot"), default="px4")
    ap.add_argument("--sysid", type=int, default=1)
    ap.add_argument("--armed", action="store_true")
    ap.add_argument("--record", default=None, help="append MANUAL_CONTROL arrivals here (JSON lines)")
    args = ap.parse_args(argv)
    host, port = args.to.rsplit(":", 1)
    stop = threading.Event()
    install_stop_signals(stop)
    peer = FakeAutopilot((host, int(port)), args.autopilot, args.sysid, armed=args.armed,
                         record_path=args.record).start()
    print(f"peer {args.autopilot} sysid {args.sysid} on {peer.sock.getsockname()} -> {args.to}",
          flush=True)
    stop.wait()
    peer.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
