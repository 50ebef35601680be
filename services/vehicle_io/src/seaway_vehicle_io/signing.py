"""vehicle_io's MAVLink 2 signing: the key, our signing timestamp kept across restarts, SETUP_SIGNING.

The key file format and the check of incoming signatures are shared with the simulator
(``seaway.mavlink.signing``); signing our own frames is pymavlink's (``MAVLink.signing``:
``secret_key``, ``sign_outgoing``, ``link_id``, ``timestamp``). What this module adds:

**The timestamp never goes back.** A MAVLink receiver refuses a frame whose timestamp (10 us units
since 2015-01-01 UTC) is not newer than the last it took from the same stream (link id, system,
component): a sender whose timestamp went back is locked out until it catches up. The timestamp is
brought up to the wall clock before each send (``keep_up``), and, because a companion computer
without a real-time clock may boot with its clock behind, it is also written to a private file
(``<key file>.timestamp`` unless the config names another) every ``SAVE_PERIOD_S`` and at exit. At
the next start it resumes at least ``RESTART_MARGIN`` past the saved value, which covers what was
sent after the last save before a crash (a frame adds 10 us; the wall clock a second a second).

**SETUP_SIGNING** gives the autopilot the key and a starting timestamp (``push_key``); it is sent
signed with the new key, which an autopilot that signs with that key already takes as well as one
that does not sign yet (neither checks signatures before a key is set). The key is never logged.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seaway.mavlink.signing import (
    ACCEPTED,
    KEY_BYTES,
    TIMESTAMP_UNITS_PER_S,
    SignatureVerifier,
    keep_up,
    signing_timestamp,
)
from seaway.runtime.atomic import LatestWriter

log = logging.getLogger("seaway.vehicle_io.signing")

DEFAULT_LINK_ID = 1
"""Our signing link id: one link per vehicle_io. Receivers keep a stream per (link id, system,
component), so two senders sharing a key must differ in one of them."""
SAVE_PERIOD_S = 10.0
"""How often the signing timestamp is written to its file while frames are sent [s]."""
RESTART_MARGIN = 30 * TIMESTAMP_UNITS_PER_S
"""A restart resumes this far past the saved timestamp (10 us units): more than the timestamp can
advance between two saves (``SAVE_PERIOD_S`` of wall clock, plus a descheduled writer)."""
TIMESTAMP_SUFFIX = ".timestamp"


class TimestampFileError(ValueError):
    """A signing timestamp file exists but cannot be used; the text names it and says what to do."""


def timestamp_path(key_file: Path) -> Path:
    """The default timestamp file of a key file: beside it, ``<key file>.timestamp``."""
    return key_file.with_name(key_file.name + TIMESTAMP_SUFFIX)


def read_timestamp(path: Path) -> int | None:
    """The timestamp saved in ``path`` (10 us units since 2015), None if there is no file yet."""
    try:
        text = path.read_text(encoding="ascii").strip()
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as err:
        raise TimestampFileError(f"signing timestamp file {path}: cannot read it: {err}") from None
    if not text.isdigit() or int(text) >= 1 << 48:
        raise TimestampFileError(
            f"signing timestamp file {path}: expected one whole number below 2**48 (the MAVLink "
            f"signing timestamp, 10 us units since 2015-01-01), got {text[:40]!r}; remove the file "
            "to start again from the wall clock (only safe if the clock is right)")
    return int(text)


def initial_timestamp(saved: int | None, wall_ns: int) -> int:
    """Where our timestamp starts: the wall clock, or ``RESTART_MARGIN`` past the saved value if
    that is later (a clock that is behind, or a restart within the margin)."""
    start = signing_timestamp(wall_ns)
    return start if saved is None else max(start, saved + RESTART_MARGIN)


@dataclass(frozen=True)
class SigningSetup:
    """What signing needs: the 32-byte key, our link id and where the timestamp is kept."""

    key: bytes
    link_id: int
    timestamp_file: Path

    def __post_init__(self) -> None:
        if len(self.key) != KEY_BYTES:
            raise ValueError(f"a MAVLink signing key is {KEY_BYTES} bytes, got {len(self.key)}")
        if not 0 <= self.link_id <= 255:
            raise ValueError(f"signing link id {self.link_id}: must be 0..255")

    def __repr__(self) -> str:  # never the key
        return f"SigningSetup(link_id={self.link_id}, timestamp_file={self.timestamp_file})"


class SigningClock:
    """Our signing timestamp for the whole process: shared by every link it opens (a reopened
    link must not restart from an older value), saved to ``setup.timestamp_file``.

    ``attach`` turns signing on in a pymavlink ``MAVLink`` sender; ``before_send`` (call before each
    send) moves the sender's timestamp to ``max(what it reached, the clock's, the wall clock)`` and
    saves it every ``SAVE_PERIOD_S``; ``close`` saves the last value and waits for the write.
    """

    def __init__(self, setup: SigningSetup, wall_ns: int, mono_ns: int) -> None:
        self.setup = setup
        saved = read_timestamp(setup.timestamp_file)
        self.timestamp = initial_timestamp(saved, wall_ns)
        self.save_failures = 0
        self._writer = LatestWriter(setup.timestamp_file, self._on_write_error,
                                    name="signing-timestamp")
        self._last_save_mono_ns: int | None = None
        self._save(mono_ns)  # a crash before the first period still moves the next start on
        log.info("MAVLink signing: link id %d, timestamp %s (saved %s in %s)", setup.link_id,
                 self.timestamp, "none" if saved is None else saved, setup.timestamp_file)

    def attach(self, mav: Any) -> None:
        sig = mav.signing
        sig.secret_key, sig.sign_outgoing, sig.link_id = self.setup.key, True, self.setup.link_id
        sig.timestamp = self.timestamp

    def before_send(self, mav: Any, wall_ns: int, mono_ns: int) -> None:
        sig = mav.signing
        sig.timestamp = max(sig.timestamp, self.timestamp)
        keep_up(sig, wall_ns)
        self.timestamp = sig.timestamp
        if self._last_save_mono_ns is None or mono_ns - self._last_save_mono_ns >= SAVE_PERIOD_S * 1e9:
            self._save(mono_ns)

    def note_sent(self, mav: Any) -> None:
        """After a send: pymavlink added one unit per signed frame."""
        self.timestamp = max(self.timestamp, mav.signing.timestamp)

    def close(self, timeout_s: float = 5.0) -> bool:
        self._writer.submit(str(self.timestamp))
        return self._writer.close(timeout_s)

    def _save(self, mono_ns: int) -> None:
        self._last_save_mono_ns = mono_ns
        self._writer.submit(str(self.timestamp))

    def _on_write_error(self, err: OSError) -> None:
        self.save_failures += 1
        if self.save_failures == 1 or self.save_failures % 60 == 0:
            log.warning("MAVLink signing: cannot save the timestamp to %s (%d failures): %s; a "
                        "restart resumes from the wall clock or the last saved value",
                        self.setup.timestamp_file, self.save_failures, err)


def is_signed_by(msg: Any, verifier: SignatureVerifier) -> bool:
    """Whether a pymavlink message arrived signed with the verifier's key (its raw frame)."""
    return verifier.check(bytes(msg.get_msgbuf()), signing_timestamp(time.time_ns())) == ACCEPTED


def send_setup_signing(mav: Any, target_system: int, target_component: int, key: bytes,
                       timestamp: int) -> None:
    """One SETUP_SIGNING: the key and the timestamp the autopilot starts from."""
    mav.setup_signing_send(target_system, target_component, list(key), timestamp)


def private_parent(path: Path) -> None:
    """Make ``path``'s folder if it is missing, 0700 (``seaway.runtime.private``); an existing folder
    is left as it is (it may be the user's home)."""
    from seaway.runtime.private import private_folder

    if not path.parent.exists():
        private_folder(path.parent)


def restrict_umask() -> int:
    """Set the process umask to the stack's (077) and return the old one."""
    from seaway.runtime.private import PRIVATE_UMASK

    return os.umask(PRIVATE_UMASK)
