"""vehicle_io's signing: the key file from ``seaway signing new``, the signing timestamp that never
goes back (across sends, link reopenings and restarts, whatever the wall clock does), and the
config fields that name them. Real files, real pymavlink packing; the clock is passed in."""

from __future__ import annotations

import itertools
import socket
import time

import pytest
from seaway.contract.config import ConfigError, parse_config
from seaway.mavlink.signing import (
    ACCEPTED,
    KEY_BYTES,
    TIMESTAMP_UNITS_PER_S,
    SignatureVerifier,
    read_key,
    signing_timestamp,
    write_key,
)
from seaway_vehicle_io import signing_cli
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import SendHeartbeat
from seaway_vehicle_io.link import MavlinkLink
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.signing import (
    RESTART_MARGIN,
    SAVE_PERIOD_S,
    SigningClock,
    SigningSetup,
    TimestampFileError,
    read_timestamp,
    timestamp_path,
)

KEY = bytes(range(1, 33))
S = 1_000_000_000
WALL = 1_780_000_000 * S  # a wall clock in 2026 [ns]


def clock_at(tmp_path, wall_ns: int, mono_ns: int = 0) -> SigningClock:
    return SigningClock(SigningSetup(KEY, 3, tmp_path / "k.timestamp"), wall_ns, mono_ns)


def sender() -> mavlink.MAVLink:
    return mavlink.MAVLink(None, srcSystem=245, srcComponent=191)


def send(clock: SigningClock, mav: mavlink.MAVLink, wall_ns: int, mono_ns: int) -> bytes:
    clock.before_send(mav, wall_ns, mono_ns)
    frame = bytes(mav.heartbeat_encode(6, 8, 0, 0, 4).pack(mav))
    clock.note_sent(mav)
    return frame


def frame_timestamp(frame: bytes) -> int:
    return int.from_bytes(frame[-12:-6], "little")


# -- key file -------------------------------------------------------------------------------------


def test_new_writes_a_private_key_in_a_private_new_folder_and_never_overwrites(tmp_path, capsys):
    path = tmp_path / "secrets" / "vessel1.key"
    assert signing_cli.main(["new", str(path)]) == 0
    key = read_key(path)  # refuses a file others may read
    assert len(key) == KEY_BYTES and any(key)
    assert path.stat().st_mode & 0o777 == 0o600
    assert path.parent.stat().st_mode & 0o777 == 0o700
    assert key.hex() not in capsys.readouterr().out  # the key is never printed
    assert signing_cli.main(["new", str(path)]) == 1
    assert "exists" in capsys.readouterr().err and read_key(path) == key


def test_push_with_a_bad_key_file_names_it(tmp_path, capsys):
    bad = tmp_path / "short.key"
    bad.write_text("ab" * 16)
    bad.chmod(0o600)
    assert signing_cli.main(["push", "--key", str(bad), "--mavlink", "udpin:127.0.0.1:0"]) == 2
    assert "short.key" in (err := capsys.readouterr().err) and "64 hexadecimal" in err


# -- timestamp ------------------------------------------------------------------------------------


def test_the_timestamp_starts_at_the_wall_clock_and_is_saved(tmp_path):
    clock = clock_at(tmp_path, WALL)
    mav = sender()
    clock.attach(mav)
    frame = send(clock, mav, WALL, 0)
    assert frame[2] & 0x01 and frame[-13] == 3  # signed, our link id
    assert frame_timestamp(frame) == signing_timestamp(WALL)
    assert SignatureVerifier(KEY).check(frame, signing_timestamp(WALL)) == ACCEPTED
    assert clock.close()
    saved = read_timestamp(tmp_path / "k.timestamp")
    assert saved is not None and saved >= frame_timestamp(frame)
    assert (tmp_path / "k.timestamp").stat().st_mode & 0o777 == 0o600


def test_the_timestamp_never_goes_back_when_the_wall_clock_does(tmp_path):
    clock = clock_at(tmp_path, WALL)
    mav = sender()
    clock.attach(mav)
    stamps = [frame_timestamp(send(clock, mav, WALL + k * S // 10, k)) for k in range(5)]
    stamps += [frame_timestamp(send(clock, mav, WALL - 3600 * S, 10 + k)) for k in range(5)]
    assert all(b > a for a, b in itertools.pairwise(stamps)), stamps
    clock.close()


def test_a_restart_with_the_clock_behind_resumes_past_the_saved_timestamp(tmp_path):
    first = clock_at(tmp_path, WALL)
    mav = sender()
    first.attach(mav)
    last = frame_timestamp(send(first, mav, WALL, 0))
    assert first.close()
    # the companion computer boots without a real-time clock: 1970
    again = clock_at(tmp_path, 0)
    mav2 = sender()
    again.attach(mav2)
    frame = send(again, mav2, 0, 0)
    assert frame_timestamp(frame) >= last + RESTART_MARGIN
    assert SignatureVerifier(KEY).check(frame, signing_timestamp(WALL)) == ACCEPTED
    again.close()


def test_a_crash_between_saves_is_covered_by_the_margin(tmp_path):
    """Saved every SAVE_PERIOD_S; a crash just before a save loses at most that much wall clock,
    which the restart margin exceeds."""
    clock = clock_at(tmp_path, WALL)
    mav = sender()
    clock.attach(mav)
    period_ns = int(SAVE_PERIOD_S * S)
    t = 0
    while t < 5 * period_ns:
        last = frame_timestamp(send(clock, mav, WALL + t, t))
        t += S // 20
    clock._writer.flush(5.0)  # what is on disk when the process is killed (no close)
    saved = read_timestamp(tmp_path / "k.timestamp")
    assert saved is not None and last - saved <= SAVE_PERIOD_S * TIMESTAMP_UNITS_PER_S
    assert saved + RESTART_MARGIN > last
    clock.close()


def test_a_reopened_link_continues_the_same_clock(tmp_path):
    """The saved timestamp is an hour ahead of the wall clock (one that was set back): a link that
    started again from the wall clock would go back by an hour."""
    ahead = signing_timestamp(time.time_ns()) + 3600 * TIMESTAMP_UNITS_PER_S
    (tmp_path / "k.timestamp").write_text(str(ahead))
    clock = clock_at(tmp_path, time.time_ns(), time.monotonic_ns())
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    peer.settimeout(2.0)
    url = f"udpout:127.0.0.1:{peer.getsockname()[1]}"
    stamps = []
    try:
        for _ in range(2):
            link = MavlinkLink(url, 245, 191, signing=clock)
            for _ in range(3):
                link.send(SendHeartbeat())
                stamps.append(frame_timestamp(peer.recv(2048)))
            link.close()
    finally:
        peer.close()
        clock.close()
    assert stamps[0] > ahead
    assert all(b > a for a, b in itertools.pairwise(stamps)), stamps


def test_a_corrupt_timestamp_file_is_an_error_naming_it(tmp_path):
    path = tmp_path / "k.timestamp"
    path.write_text("yesterday")
    with pytest.raises(TimestampFileError, match=r"k\.timestamp.*whole number"):
        read_timestamp(path)


# -- config ---------------------------------------------------------------------------------------


def test_config_names_the_field_of_a_bad_key_length(tmp_path):
    short = tmp_path / "short.key"
    short.write_text("ab" * 31 + "\n")
    short.chmod(0o600)
    with pytest.raises(ConfigError, match=r"signing_key_file.*short\.key.*64 hexadecimal"):
        parse_config({"signing_key_file": str(short)}, VehicleIoConfig, "test")


def test_config_signing_fields(tmp_path):
    key_file = tmp_path / "v.key"
    write_key(key_file)
    cfg = parse_config({"signing_key_file": str(key_file)}, VehicleIoConfig)
    setup = cfg.signing_setup()
    assert setup is not None and setup.link_id == 1
    assert setup.timestamp_file == timestamp_path(key_file) == tmp_path / "v.key.timestamp"
    assert KEY.hex() not in repr(SigningSetup(KEY, 1, key_file))
    with pytest.raises(ConfigError, match="signing_link_id"):
        parse_config({"signing_key_file": str(key_file), "signing_link_id": 256}, VehicleIoConfig)
    bad_ts = tmp_path / "bad.timestamp"
    bad_ts.write_text("-5")
    with pytest.raises(ConfigError, match=r"signing_timestamp_file.*bad\.timestamp"):
        parse_config({"signing_key_file": str(key_file),
                      "signing_timestamp_file": str(bad_ts)}, VehicleIoConfig)
    assert parse_config({}, VehicleIoConfig).signing_setup() is None
