"""MAVLink 2 message signing: the secret key file, and the check of an incoming signature.

Shared by vehicle_io and the simulator (the sim must not depend on vehicle_io), so it is written on
raw frame bytes (``seaway.mavlink.wire``) with ``hashlib`` only: no pymavlink here. Signing
*outgoing* frames is pymavlink's job (``MAVLink.signing``: ``secret_key``, ``sign_outgoing``,
``link_id``, ``timestamp``); callers set it up with ``signing_timestamp`` for the initial timestamp.

**Key file**: the 32-byte secret key written as 64 hexadecimal characters (surrounding whitespace
and one trailing newline are fine), nothing else. ``write_key`` creates one with a random key, mode
0600; ``python -m seaway.mavlink.signing PATH`` does the same from a shell.

**Why not pymavlink's own check**: ``MAVLink.check_signature`` (pymavlink 2.4.x) stores a stream's
timestamp *before* it compares the signature, so a single forged frame carrying the timestamp
2**48 - 1 and a valid-looking (sysid, compid, link id) makes every later genuine frame of that
stream "old" and rejected: one unauthenticated packet would cut the link. ``SignatureVerifier``
follows the MAVLink specification (and the C library PX4 and ArduPilot use): the signature first,
then the timestamp, and only an authentic frame ever moves a stream's timestamp.

Timestamps are in the protocol's unit: 10 microseconds since 2015-01-01 00:00:00 UTC.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
import stat
import sys
from pathlib import Path
from typing import Any

from seaway.mavlink.wire import CRC_LEN, HEADER_LEN, IFLAG_SIGNED, MAVLINK2_MAGIC, SIGNATURE_BLOCK_LEN

KEY_BYTES = 32
KEY_HEX_CHARS = 2 * KEY_BYTES

EPOCH_2015_UNIX_S = 1_420_070_400
TIMESTAMP_UNITS_PER_S = 100_000  # 10 us
NEW_STREAM_MAX_AGE = 60 * TIMESTAMP_UNITS_PER_S  # the specification's one minute

# Verdicts of SignatureVerifier.check
ACCEPTED = "accepted"
UNSIGNED = "unsigned"
BAD_SIGNATURE = "bad_signature"
REPLAYED = "replayed"


class KeyFileError(ValueError):
    """A signing key file is missing, unreadable or not 64 hex characters; the text names it."""


# -- key files --------------------------------------------------------------------------------


def read_key(path: str | Path) -> bytes:
    """The 32-byte secret key in ``path`` (64 hexadecimal characters). Raises KeyFileError.

    Refused as well: a key of all zeros (SETUP_SIGNING with a zero key *disables* signing on PX4
    and ArduPilot, so such a file is a mistake, not a key), and, on POSIX, a file group or others
    have any access to (the key is only as secret as the file; as the stack's credentials, 0600).
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
        mode = stat.S_IMODE(p.stat().st_mode)
    except OSError as err:
        raise KeyFileError(f"signing key file {p}: cannot read: {err.strerror or err}") from None
    try:
        text = raw.decode("ascii").strip()
    except UnicodeDecodeError:
        text = None
    if text is None or len(text) != KEY_HEX_CHARS or not _is_hex(text):
        raise KeyFileError(
            f"signing key file {p}: expected the {KEY_BYTES}-byte key as exactly {KEY_HEX_CHARS} "
            f"hexadecimal characters (0-9, a-f) and nothing else, got {len(raw)} bytes; create one "
            f"with: python -m seaway.mavlink.signing {p}")
    key = bytes.fromhex(text)
    if not any(key):
        raise KeyFileError(f"signing key file {p}: the key is all zeros, which means 'signing off' "
                           "to PX4 and ArduPilot; write a random key")
    if os.name == "posix" and mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise KeyFileError(f"signing key file {p}: mode {mode:o} lets others read it; only its "
                           f"owner may (chmod 600 {p})")
    return key


def write_key(path: str | Path) -> bytes:
    """Create ``path`` holding a new random key (mode 0600) and return the key.

    Refuses to overwrite an existing file (FileExistsError): replacing a key locks out every peer
    that still has the old one, so rotating is a deliberate remove-then-write.
    """
    key = secrets.token_bytes(KEY_BYTES)
    p = Path(path)
    # O_EXCL: never follow a planted file or symlink; the mode applies from the first byte.
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as f:
        f.write(key.hex() + "\n")
    return key


def _is_hex(text: str) -> bool:
    return all(c in "0123456789abcdefABCDEF" for c in text)


# -- timestamps -------------------------------------------------------------------------------


def signing_timestamp(wall_ns: int) -> int:
    """The MAVLink signing timestamp (10 us since 2015-01-01 UTC) of a Unix time [ns]."""
    return max(0, wall_ns // 10_000 - EPOCH_2015_UNIX_S * TIMESTAMP_UNITS_PER_S)


def keep_up(signing: Any, wall_ns: int) -> None:
    """Bring a sender's signing timestamp (pymavlink's ``MAVLink.signing``) up to the wall clock
    before it signs, never back: call before each send.

    pymavlink adds one unit (10 us) per frame it signs and never looks at a clock, so a link that
    sends 50 frames a second falls behind the wall clock by about a second a second. A receiver that
    restarts (an autopilot rebooting, a restarted vehicle_io) knows no stream yet and takes one only
    within ``NEW_STREAM_MAX_AGE`` (a minute) of its own clock: after the sender's first minute, every
    frame was refused as replayed and the link never came back."""
    signing.timestamp = max(signing.timestamp, signing_timestamp(wall_ns))


# -- incoming frames --------------------------------------------------------------------------


class SignatureVerifier:
    """Checks the signatures of incoming MAVLink 2 frames against one secret key.

    ``check(frame, now_timestamp)`` takes one complete frame as received (header to signature) and
    the receiver's current signing timestamp, and returns ``ACCEPTED``, ``UNSIGNED`` (no signature,
    or MAVLink 1), ``BAD_SIGNATURE`` or ``REPLAYED``. As the specification has it, a stream is
    (link id, system id, component id); an authentic frame is accepted when its timestamp is newer
    than the stream's last, or, for a stream not seen yet, not more than one minute behind
    ``now_timestamp``. Only accepted frames are remembered, so the table holds key holders only.
    """

    def __init__(self, key: bytes) -> None:
        if len(key) != KEY_BYTES:
            raise ValueError(f"a MAVLink signing key is {KEY_BYTES} bytes, got {len(key)}")
        self._key = bytes(key)
        self.streams: dict[tuple[int, int, int], int] = {}

    def check(self, frame: bytes, now_timestamp: int) -> str:
        if (len(frame) < HEADER_LEN + CRC_LEN + SIGNATURE_BLOCK_LEN or frame[0] != MAVLINK2_MAGIC
                or not frame[2] & IFLAG_SIGNED):
            return UNSIGNED
        expected = hashlib.sha256(self._key + bytes(frame[:-6])).digest()[:6]
        if not hmac.compare_digest(expected, bytes(frame[-6:])):
            return BAD_SIGNATURE
        link_id = frame[-SIGNATURE_BLOCK_LEN]
        timestamp = int.from_bytes(frame[-12:-6], "little")
        stream = (link_id, frame[5], frame[6])
        last = self.streams.get(stream)
        if last is None:
            if timestamp + NEW_STREAM_MAX_AGE < now_timestamp:
                return REPLAYED
        elif timestamp <= last:
            return REPLAYED
        self.streams[stream] = timestamp
        return ACCEPTED


def main(argv: list[str] | None = None) -> int:
    """``python -m seaway.mavlink.signing PATH``: write a new random key file (mode 0600)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or args[0].startswith("-"):
        print("usage: python -m seaway.mavlink.signing PATH\n"
              "writes a new random MAVLink 2 signing key to PATH (64 hex characters, mode 0600); "
              "refuses to overwrite an existing file", file=sys.stderr)
        return 2
    try:
        write_key(args[0])
    except FileExistsError:
        print(f"{args[0]}: exists; remove it first if you mean to replace the key (every peer "
              "holding the old key must then get the new one)", file=sys.stderr)
        return 1
    except OSError as err:
        print(f"{args[0]}: {err.strerror or err}", file=sys.stderr)
        return 1
    print(f"wrote a new MAVLink signing key to {args[0]} (mode 0600)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
