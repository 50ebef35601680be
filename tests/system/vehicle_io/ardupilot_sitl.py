"""Where the tests find ArduPilot Rover SITL, and an instance number (so a port block) of their own.

The firmware folder is the one ``seaway sitl ardupilot`` uses (``seaway_vehicle_io.sitl``):
``$SEAWAY_ARDUPILOT_SITL``, else ``../shared/sitl/ardupilot``. Tests needing it are skipped, saying
why, only when it is absent.
"""

from __future__ import annotations

import fcntl
import os
import socket
import tempfile
from pathlib import Path

import pytest
from seaway.contract.config import repo_root
from seaway_vehicle_io import sitl

SITL_DIR = sitl.default_folder(os.environ, repo_root())
try:
    FIRMWARE: sitl.ArduPilotSitl | None = sitl.find_firmware(SITL_DIR)
    _MISSING = ""
except sitl.SitlError as err:
    FIRMWARE, _MISSING = None, str(err)
START = SITL_DIR / "start-motorboat.sh" if SITL_DIR else None
"""The shipped folder's start script (the vehicle_io tests start the firmware through it)."""

needs_sitl = pytest.mark.skipif(FIRMWARE is None or START is None or not START.exists(),
                                reason=f"ArduPilot Rover SITL: {_MISSING or 'no start-motorboat.sh'}")

_used_instances: set[int] = set()



def _ports_free(instance: int) -> bool:
    for port in (sitl.BASE_TCP_PORT + sitl.PORTS_PER_INSTANCE * instance + k for k in range(3)):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                return False
    return True


def sitl_instance() -> int:
    """An instance number of our own: per pytest-xdist worker a block of 20, skipping numbers in
    use (in this process, by another test process on this machine: ``instance_lock``, or by
    anything holding its ports)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    base = 40 + 20 * int("".join(c for c in worker if c.isdigit()) or 0)
    for instance in range(base, base + 20):
        if instance not in _used_instances and instance_lock("ardupilot", instance) \
                and _ports_free(instance):
            _used_instances.add(instance)
            return instance
    pytest.fail(f"no free ArduPilot SITL instance number in {base}..{base + 19}")


_locks: dict[str, int] = {}
LOCK_DIR = Path(tempfile.gettempdir()) / "seaway-sitl-instances"


def instance_lock(firmware: str, instance: int) -> bool:
    """Hold ``firmware``'s ``instance`` for the rest of this process (True), unless another process
    holds it (False): free ports alone do not make a number ours, since a SITL started by another
    test process a moment later takes them (its ports are bound only once it has booted)."""
    name = f"{firmware}-{instance}"
    if name in _locks:
        return False
    LOCK_DIR.mkdir(exist_ok=True)
    fd = os.open(LOCK_DIR / f"{name}.lock", os.O_CREAT | os.O_RDWR, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return False
    _locks[name] = fd  # released when this process exits
    return True
