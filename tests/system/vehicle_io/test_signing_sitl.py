"""MAVLink 2 signing against the autopilots' own firmware: ArduPilot Rover SITL and PX4 SITL (#63).

For each firmware, with the key made by ``seaway signing new`` and given to the autopilot by
``seaway signing push`` (SETUP_SIGNING):

* every frame the autopilot then sends carries a signature (incompat flag 0x01 on the raw bytes)
  made with that key, checked here on the bytes themselves;
* a vehicle_io holding another key never locks the link: it refuses the autopilot's frames as
  ``bad_signature`` (counted in VehicleStatus.refused_messages, one WARNING naming the source);
* vehicle_io holding the key links, reads the telemetry at its rates and changes the mode (its
  COMMAND_LONG is signed, or the autopilot would ignore it);
* a sender with a wrong key, and one without a key, gets neither an ACK nor a mode change from the
  autopilot; the same sender with the right key gets both (the control);
* ArduPilot's SERIAL0 takes an unsigned command even so (its channel 0 is "the USB port").

Links: ArduPilot takes anything, unsigned too, on SERIAL0 (its channel 0, "the USB port"), so
vehicle_io uses SERIAL1 (5761 + 10 I), the sender SERIAL2 (5762 + 10 I) and the observer, which
reads the mode, SERIAL0. PX4 signs and checks on every link; vehicle_io uses the onboard link, the
sender the GCS link (18570 + N), the observer the SIH link.
"""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ModeRequest
from seaway.mavlink.signing import (
    ACCEPTED,
    BAD_SIGNATURE,
    SignatureVerifier,
    read_key,
    signing_timestamp,
)
from seaway.runtime.bus import Bus
from seaway_vehicle_io import ardupilot, px4
from seaway_vehicle_io.mav import mavlink

from tests.conftest import BIN, Procs, wait_for
from tests.system.vehicle_io.ardupilot_sitl import needs_sitl
from tests.system.vehicle_io.px4_sitl import Px4Sitl, boat_params, needs_px4
from tests.system.vehicle_io.test_ardupilot_sitl import Observer, Sitl, StatusWatch

pytestmark = [pytest.mark.system, pytest.mark.slow]

VIO = BIN / "seaway-vehicle-io"
SEAWAY = BIN / "seaway"
MAV_CMD_DO_SET_MODE = 176
MSG_COMMAND_ACK = 77
ATTACKER = (254, 190)  # a ground station's ids, not vehicle_io's
QUIET_S = 4.0  # how long a refused command is watched for an effect


# -- raw MAVLink bytes ------------------------------------------------------------------------------


def split_frames(buf: bytearray) -> list[bytes]:
    """Cut complete MAVLink frames off the front of ``buf`` (bytes before a start marker are
    skipped); what is left is an incomplete frame."""
    out: list[bytes] = []
    while buf:
        if buf[0] not in (0xFD, 0xFE):
            del buf[0]
            continue
        if len(buf) < 3:
            break
        # MAVLink 2: 10 header + payload + 2 CRC (+ 13 signature); MAVLink 1: 6 + payload + 2
        n = 12 + buf[1] + (13 if buf[2] & 0x01 else 0) if buf[0] == 0xFD else 8 + buf[1]
        if len(buf) < n:
            break
        out.append(bytes(buf[:n]))
        del buf[:n]
    return out


def command(key: bytes | None, target_system: int, params: tuple[float, ...]) -> bytes:
    """DO_SET_MODE as raw bytes from ATTACKER, signed with ``key`` (None: unsigned)."""
    tx = mavlink.MAVLink(None, srcSystem=ATTACKER[0], srcComponent=ATTACKER[1])
    if key is not None:
        tx.signing.secret_key, tx.signing.sign_outgoing, tx.signing.link_id = key, True, 7
        tx.signing.timestamp = signing_timestamp(time.time_ns())
    msg = tx.command_long_encode(target_system, 1, MAV_CMD_DO_SET_MODE, 0, *params,
                                 *([0.0] * (7 - len(params))))
    return bytes(msg.pack(tx))


def heartbeat_frame() -> bytes:
    tx = mavlink.MAVLink(None, srcSystem=ATTACKER[0], srcComponent=ATTACKER[1])
    return bytes(tx.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                     0).pack(tx))


class Sender:
    """The test's second ground station on a link of its own: raw bytes out, raw frames in."""

    def __init__(self, sock: socket.socket, dest: tuple[str, int] | None) -> None:
        self.sock, self.dest = sock, dest
        self.sock.settimeout(0.1)
        self.buf = bytearray()

    def send(self, data: bytes) -> None:
        if self.dest is None:
            self.sock.sendall(data)
        else:
            self.sock.sendto(data, self.dest)

    def frames_for(self, seconds: float) -> list[bytes]:
        out: list[bytes] = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                data = self.sock.recv(65536)
            except (TimeoutError, BlockingIOError):
                continue
            self.buf.extend(data)
            out += split_frames(self.buf)
        return out

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def msg_id(frame: bytes) -> int:
    return int.from_bytes(frame[7:10], "little") if frame[0] == 0xFD else frame[5]


def acks(frames: list[bytes]) -> list[bytes]:
    """COMMAND_ACKs to DO_SET_MODE among ``frames``."""
    return [f for f in frames if msg_id(f) == MSG_COMMAND_ACK
            and int.from_bytes(f[10:12], "little") == MAV_CMD_DO_SET_MODE]


def sender_system(frame: bytes) -> int:
    return frame[5] if frame[0] == 0xFD else frame[3]


def assert_all_signed(frames: list[bytes], sysid: int, key: bytes, wrong: bytes,
                      what: str) -> None:
    """Every frame of the autopilot (system ``sysid``) signed (flag 0x01), and with ``key``:
    accepted by a verifier holding it, refused as bad_signature by one holding ``wrong``. (PX4
    forwards other systems' frames between links, vehicle_io's HEARTBEAT included, with a
    signature block that does not verify: not the autopilot's own, so not checked here.)"""
    frames = [f for f in frames if sender_system(f) == sysid]
    assert len(frames) >= 3, f"{what}: only {len(frames)} frames"
    unsigned = [f for f in frames if f[0] != 0xFD or not f[2] & 0x01]
    assert not unsigned, f"{what}: {len(unsigned)} of {len(frames)} frames unsigned"
    good, bad = SignatureVerifier(key), SignatureVerifier(wrong)
    now = signing_timestamp(time.time_ns())
    refused = [(msg_id(f), v, f.hex()) for f in frames if (v := good.check(f, now)) != ACCEPTED]
    assert not refused, f"{what}: {len(refused)} of {len(frames)} frames refused: {refused}"
    assert all(bad.check(f, now) == BAD_SIGNATURE for f in frames)


# -- the tools under test ---------------------------------------------------------------------------


def new_key(tmp: Path, name: str) -> Path:
    path = tmp / "keys" / name
    out = subprocess.run([str(SEAWAY), "signing", "new", str(path)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert path.stat().st_mode & 0o777 == 0o600 and path.parent.stat().st_mode & 0o777 == 0o700
    return path


def push(key: Path, url: str) -> str:
    out = subprocess.run([str(SEAWAY), "signing", "push", "--key", str(key), "--mavlink", url,
                          "--timeout", "90"], capture_output=True, text=True, timeout=150)
    assert out.returncode == 0, f"push failed:\n{out.stdout}\n{out.stderr}"
    assert key.read_text().strip() not in out.stdout + out.stderr  # never printed
    return out.stdout


def start_vio(procs: Procs, env: dict[str, str], tmp: Path, url: str, autopilot: str,
              key: Path) -> subprocess.Popen:
    lines = [f'mavlink = "{url}"', f'autopilot = "{autopilot}"',
             f"signing_key_file = {json.dumps(str(key))}"]
    path = tmp / f"vio-{len(procs.procs)}.toml"
    path.write_text("\n".join(lines) + "\n")
    return procs.start([str(VIO), "--config", str(path), "--scenario", "lake"], env,
                       name=f"vio-{len(procs.procs)}")


def wrong_key_vio_refuses(procs: Procs, env: dict[str, str], bus: Bus, tmp: Path, url: str,
                          autopilot: str, wrong: Path, autopilot_system: int) -> None:
    """vehicle_io with another key: no link, the autopilot's frames counted as bad_signature and
    named once at WARNING."""
    status = StatusWatch(bus)
    vio = start_vio(procs, env, tmp, url, autopilot, wrong)
    _, s = status.wait(lambda s: s.refused_messages.get("bad_signature", 0) >= 3, 60,
                       "vehicle_io refusing the autopilot's frames as bad_signature")
    assert not any(m.link_ok for _, m in status.poll()), "linked despite the wrong key"
    procs.stop(vio)
    log = procs.log(vio)
    assert "WARNING" in log and (f"refusing MAVLink from system {autopilot_system} component 1"
                                 in log) and "signature does not match our key" in log, log[-3000:]
    print(f"wrong-key vehicle_io: refused {s.refused_messages}")


def linked_vio(procs: Procs, env: dict[str, str], bus: Bus, tmp: Path, url: str, autopilot: str,
               key: Path, mode_name: str) -> subprocess.Popen:
    """vehicle_io with the key: links, gets the telemetry, and its mode request takes effect."""
    status = StatusWatch(bus)
    vio = start_vio(procs, env, tmp, url, autopilot, key)
    _, first = status.wait(lambda s: s.link_ok and s.autopilot == autopilot, 90,
                           "vehicle_io's signed link")
    _, later = status.wait(lambda s: s.stamp_ns > first.stamp_ns + 3e9
                           and s.rates_hz.get("ATTITUDE", 0) >= 2.0, 30,
                           "ATTITUDE flowing on the signed link")
    reply = bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                            mode=mode_name), timeout_s=10)
    assert reply.accepted, reply.reason
    _, after = status.wait(lambda s: s.mode == mode_name, 10, f"the status in {mode_name}")
    refused = after.refused_messages
    assert not refused.get("unsigned") and not refused.get("bad_signature"), refused
    assert (tmp / "keys" / "vio.key.timestamp").exists()
    print(f"signed link: rates {later.rates_hz}, refused {refused}")
    return vio


def wrong_senders_ignored(sender: Sender, key: bytes, wrong: bytes, target: int,
                          params: tuple[float, ...], mode_now, mode_wanted: int) -> None:
    """DO_SET_MODE to ``mode_wanted`` unsigned and with the wrong key: no ACK, no change; with
    the right key: ACK and change (so the path itself works)."""
    assert mode_now() != mode_wanted
    for label, k in (("unsigned", None), ("wrong key", wrong)):
        for _ in range(3):
            sender.send(command(k, target, params))
            time.sleep(0.3)
        got = sender.frames_for(QUIET_S)
        assert not acks(got), f"{label}: the autopilot answered"
        assert mode_now() != mode_wanted, f"{label}: the mode changed"
    got: list[bytes] = []
    for _ in range(5):  # UDP, and a busy autopilot: a few tries, each freshly stamped
        sender.send(command(key, target, params))
        got += sender.frames_for(2.0)
        if acks(got):
            break
    assert acks(got), "the right key got no ACK on the same link"
    wait_for(lambda: mode_now() == mode_wanted, 10, what="the mode set with the right key")


# -- PX4 --------------------------------------------------------------------------------------------


@pytest.fixture
def px4_sitl(tmp_path):
    s = Px4Sitl(tmp_path, params=boat_params())
    try:
        yield s
    finally:
        s.kill()


def px4_mode(s: Px4Sitl) -> int | None:
    hb = list(s.observer.heartbeats)
    return hb[-1][1] if hb else None


@needs_px4
def test_px4_signs_with_the_pushed_key_and_ignores_other_keys(zenoh_env, procs, bus, tmp_path,
                                                             px4_sitl):
    s = px4_sitl
    sysid = s.instance + 1
    key_file, wrong_file = new_key(tmp_path, "vio.key"), new_key(tmp_path, "wrong.key")
    key, wrong = read_key(key_file), read_key(wrong_file)
    print(push(key_file, s.vio_url))

    # the raw bytes PX4 sends to vehicle_io's port: all signed with the key
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    raw.bind(("127.0.0.1", 14540 + s.instance))
    listener = Sender(raw, None)
    frames = listener.frames_for(3.0)
    listener.close()
    assert_all_signed(frames, sysid, key, wrong, "PX4's onboard link")

    wrong_key_vio_refuses(procs, zenoh_env, bus, tmp_path, s.vio_url, "px4", wrong_file, sysid)
    vio = linked_vio(procs, zenoh_env, bus, tmp_path, s.vio_url, "px4", key_file, "MANUAL")
    manual = px4.MODES["MANUAL"][0] << 16
    wait_for(lambda: px4_mode(s) == manual, 10, what="PX4 in MANUAL (vehicle_io's signed command)")

    # a second ground station on PX4's GCS link: claims the link with a HEARTBEAT (PX4 takes
    # HEARTBEAT unsigned), then asks for Hold
    gcs = Sender(socket.socket(socket.AF_INET, socket.SOCK_DGRAM), ("127.0.0.1", 18570 + s.instance))
    gcs.sock.bind(("127.0.0.1", 0))
    try:
        gcs.send(heartbeat_frame())
        assert_all_signed(gcs.frames_for(2.0), sysid, key, wrong, "PX4's GCS link")
        main, sub = px4.MODES["HOLD"]
        wrong_senders_ignored(gcs, key, wrong, sysid, (1.0, float(main), float(sub)),
                              lambda: px4_mode(s), main << 16 | sub << 24)
    finally:
        gcs.close()
    assert vio.poll() is None, procs.log(vio)[-3000:]


# -- ArduPilot --------------------------------------------------------------------------------------


@pytest.fixture
def ardupilot_sitl(tmp_path):
    s = Sitl(tmp_path)
    try:
        yield s
    finally:
        s.kill()


def ardupilot_mode(obs: Observer) -> int | None:
    modes = list(obs.modes)
    return modes[-1][1] if modes else None


@needs_sitl
def test_ardupilot_signs_with_the_pushed_key_and_ignores_other_keys(zenoh_env, procs, bus, tmp_path,
                                                                   ardupilot_sitl):
    s = ardupilot_sitl
    port0 = 5760 + 10 * s.instance
    obs = wait_for(lambda: _observer(port0), 60, interval_s=0.5, what="SITL SERIAL0")
    s.observer = obs
    obs.start()
    sysid = obs.conn.target_system
    key_file, wrong_file = new_key(tmp_path, "vio.key"), new_key(tmp_path, "wrong.key")
    key, wrong = read_key(key_file), read_key(wrong_file)
    serial1, serial2 = f"tcp:127.0.0.1:{port0 + 1}", ("127.0.0.1", port0 + 2)
    print(push(key_file, f"tcp:127.0.0.1:{serial2[1]}"))

    sender = Sender(socket.create_connection(serial2, timeout=10), None)
    try:
        assert_all_signed(sender.frames_for(3.0), sysid, key, wrong, "ArduPilot's SERIAL2")
        wrong_key_vio_refuses(procs, zenoh_env, bus, tmp_path, serial1, "ardupilot", wrong_file,
                              sysid)
        vio = linked_vio(procs, zenoh_env, bus, tmp_path, serial1, "ardupilot", key_file, "HOLD")
        wait_for(lambda: ardupilot_mode(obs) == ardupilot.MODES["HOLD"], 10,
                 what="ArduPilot in HOLD (vehicle_io's signed command)")
        manual = ardupilot.MODES["MANUAL"]
        wrong_senders_ignored(sender, key, wrong, sysid, (1.0, float(manual)),
                              lambda: ardupilot_mode(obs), manual)
        # SERIAL0 (channel 0) takes an unsigned command all the same: why vehicle_io is not there
        hold = ardupilot.MODES["HOLD"]
        obs.conn.mav.command_long_send(sysid, 1, MAV_CMD_DO_SET_MODE, 0, 1, hold, 0, 0, 0, 0, 0)
        wait_for(lambda: ardupilot_mode(obs) == hold, 10,
                 what="ArduPilot taking an unsigned DO_SET_MODE on SERIAL0")
    finally:
        sender.close()
    assert vio.poll() is None, procs.log(vio)[-3000:]


def _observer(port: int) -> Observer | None:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1):
            pass
    except OSError:
        return None
    return Observer(port)
