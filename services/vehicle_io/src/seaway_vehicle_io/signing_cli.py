"""``seaway signing``: make a MAVLink 2 signing key file, and give the key to the autopilot.

    seaway signing new PATH
    seaway signing push --key PATH --mavlink URL [--system 245] [--component 191] [--timeout 15]

``new`` writes a random 32-byte key as 64 hex characters, mode 0600 (umask 077; a missing folder is
made 0700), refusing to overwrite. ``push`` waits for the autopilot's HEARTBEAT on URL, sends it
SETUP_SIGNING (the key and our current signing timestamp, signed with the key) once a second, and
succeeds when a frame from the autopilot arrives signed with that key. PX4 (1.17+) and ArduPilot
take SETUP_SIGNING only while disarmed; ArduPilot on any MAVLink 2 port, PX4 on any link, and both
then sign on every link. The key is never printed. vehicle_io must not be on the same UDP port
(stop it, or push over another link).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from seaway.mavlink.signing import KeyFileError, SignatureVerifier, read_key, write_key
from seaway.runtime.argtypes import positive_float, whole_number

from seaway_vehicle_io.config import SOURCE_COMPONENT, SOURCE_SYSTEM
from seaway_vehicle_io.link import check_url
from seaway_vehicle_io.mav import mavlink, mavutil
from seaway_vehicle_io.signing import (
    DEFAULT_LINK_ID,
    SigningClock,
    SigningSetup,
    TimestampFileError,
    is_signed_by,
    private_parent,
    restrict_umask,
    send_setup_signing,
    timestamp_path,
)

PROG = "seaway signing"
RESEND_PERIOD_S = 1.0
REFUSAL_TEXTS = ("signing", "armed")  # STATUSTEXT words worth showing while pushing


def cmd_new(path: Path) -> int:
    old_umask = restrict_umask()
    try:
        private_parent(path)
        write_key(path)
    except FileExistsError:
        print(f"{PROG}: {path} exists; remove it first if you mean to replace the key (every peer "
              "holding the old key must then get the new one)", file=sys.stderr)
        return 1
    except OSError as err:
        print(f"{PROG}: {path}: {err.strerror or err}", file=sys.stderr)
        return 1
    finally:
        os.umask(old_umask)
    print(f"wrote a new MAVLink signing key to {path} (mode 0600); give it to the autopilot with: "
          f"{PROG} push --key {path} --mavlink URL")
    return 0


def _autopilot_heartbeat(msg: object) -> bool:
    return (msg.get_type() == "HEARTBEAT"  # type: ignore[attr-defined]
            and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID  # type: ignore[attr-defined]
            and msg.type != mavlink.MAV_TYPE_GCS)  # type: ignore[attr-defined]


def push(url: str, setup: SigningSetup, system: int, component: int, timeout_s: float) -> int:
    """Give ``setup.key`` to the autopilot on ``url``; 0 once it signs with it, 1 otherwise."""
    conn = mavutil.mavlink_connection(check_url(url), source_system=system,
                                      source_component=component, dialect="ardupilotmega",
                                      autoreconnect=False)
    conn.WIRE_PROTOCOL_VERSION = "2.0"
    tx = mavlink.MAVLink(conn, srcSystem=system, srcComponent=component)
    clock = SigningClock(setup, time.time_ns(), time.monotonic_ns())
    clock.attach(tx)
    verifier = SignatureVerifier(setup.key)
    target: tuple[int, int] | None = None
    deadline = time.monotonic() + timeout_s
    next_send = 0.0
    try:
        while time.monotonic() < deadline:
            if target is not None and time.monotonic() >= next_send:
                clock.before_send(tx, time.time_ns(), time.monotonic_ns())
                send_setup_signing(tx, target[0], target[1], setup.key, clock.timestamp)
                clock.note_sent(tx)
                next_send = time.monotonic() + RESEND_PERIOD_S
            msg = conn.recv_match(blocking=True, timeout=0.2)
            if msg is None:
                continue
            if target is None and _autopilot_heartbeat(msg):
                target = (msg.get_srcSystem(), msg.get_srcComponent())
                print(f"autopilot: system {target[0]} component {target[1]}; sending SETUP_SIGNING")
                continue
            if target is None or msg.get_srcSystem() != target[0]:
                continue
            if msg.get_type() == "STATUSTEXT" and any(w in msg.text.lower() for w in REFUSAL_TEXTS):
                print(f"autopilot says: {msg.text}")
            if is_signed_by(msg, verifier):
                print(f"autopilot system {target[0]} now signs with the key: its "
                      f"{msg.get_type()} arrived signed with it")
                return 0
    finally:
        clock.close()
        conn.close()
    what = "no autopilot HEARTBEAT" if target is None else "the autopilot did not sign with the key"
    print(f"{PROG}: {what} within {timeout_s:g} s on {url} (is it armed? on ArduPilot, is the port "
          "MAVLink 2?)", file=sys.stderr)
    return 1


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, help="new: make a key; push: give it")
    new = sub.add_parser("new", help="write a new random key file (mode 0600)",
                         description="Write a new random 32-byte key, 0600; never overwrites.")
    new.add_argument("path", type=Path, help="the key file to create")
    p = sub.add_parser("push", help="give the key to the autopilot (SETUP_SIGNING) and check it",
                       description="Send SETUP_SIGNING until the autopilot signs with the key.")
    p.add_argument("--key", type=Path, required=True, help="the key file (64 hex characters)")
    p.add_argument("--mavlink", required=True, help="the autopilot's MAVLink URL (as vehicle_io's)")
    p.add_argument("--system", type=whole_number(1, 255), default=SOURCE_SYSTEM,
                   help="our system id (1-255)")
    p.add_argument("--component", type=whole_number(1, 255), default=SOURCE_COMPONENT,
                   help="our component id (1-255)")
    p.add_argument("--link-id", type=whole_number(0, 255), default=DEFAULT_LINK_ID,
                   help="our signing link id (0-255)")
    p.add_argument("--timestamp-file", type=Path, default=None,
                   help="our signing timestamp file (default: the key file's, as vehicle_io's)")
    p.add_argument("--timeout", type=positive_float, default=15.0,
                   help="give up after this long [s]")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "new":
        return cmd_new(args.path)
    try:
        setup = SigningSetup(read_key(args.key), args.link_id,
                             args.timestamp_file or timestamp_path(args.key))
        return push(args.mavlink, setup, args.system, args.component, args.timeout)
    except (KeyFileError, TimestampFileError, ValueError) as err:
        print(f"{PROG}: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
