"""A boat and a shore for the deployment tests, set up the way docs/deployment.md says.

* ``create``: the deployment's credentials, made by the real command (``seaway credentials create DIR
  --deployment --boat-host ...``): ``DIR/boat`` and ``DIR/shore``, one authority, in a tmp folder
  (each test run makes its own keys; nothing is ever committed).
* ``client_file``: a copy of a shipped client config with only its router port moved (processes
  take a file, ``SEAWAY_ZENOH_CONFIG``), so parallel tests never collide.
* ``session``: a test's own Zenoh session from a shipped client config, as one identity of a side
  (``seaway.runtime.zenoh_bus.load_zenoh_config``, exactly what a service does), port moved.
* ``link_address``: an address of this computer that is not loopback, or None: a link made to it
  arrives on a real interface, as the shore router's does on the boat.
"""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import sys
from pathlib import Path

import zenoh
from seaway.runtime import credentials
from seaway.runtime.zenoh_bus import close_at_exit, load_zenoh_config

REPO = Path(__file__).resolve().parents[3]
ZENOH_DIR = REPO / "deploy" / "zenoh"
BOAT_PORT, SHORE_PORT = 7447, 7448
"""The ports the shipped client configs connect their router on (moved per test)."""


def create(folder: Path, boat_hosts: tuple[str, ...] = ()) -> Path:
    """``seaway credentials create FOLDER --deployment [--boat-host H ...]``; returns ``FOLDER``."""
    cmd = [sys.executable, "-m", "seaway.tools.cli", "credentials", "create", str(folder), "--deployment",
           "--days", "1"]
    for host in boat_hosts:
        cmd += ["--boat-host", host]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}): {out.stderr}")
    return folder


def other_authority(folder: Path) -> credentials.Credentials:
    """A stack of another authority (what an intruder with a Seaway installation of its own has)."""
    return credentials.create(folder)


def client_file(side: str, tmp: Path, port: int) -> Path:
    """The shipped ``<side>-client.json5`` with its router port moved to ``port``, in ``tmp``."""
    text = (ZENOH_DIR / f"{side}-client.json5").read_text()
    shipped = f"tls/127.0.0.1:{BOAT_PORT if side == 'boat' else SHORE_PORT}"
    if shipped not in text:
        raise AssertionError(f"{side}-client.json5 no longer connects to {shipped}: update this helper")
    out = tmp / f"{side}-client-{port}.json5"
    out.write_text(text.replace(shipped, f"tls/127.0.0.1:{port}"))
    return out


def session(side: str, identity: str, folder: Path, endpoint: str, *, rules: bool = True,
            mode: str | None = None) -> zenoh.Session:
    """A session from the shipped ``<side>-client.json5`` as ``identity`` with the side's credentials
    in ``folder`` (the deployment's root), connected to ``endpoint`` instead of its router.

    ``rules=False``: without the side's access rules (a compromised computer that ignores its own
    rules, to show the other side's refusing); ``mode``: e.g. ``client`` for a session that goes
    straight to a router and makes no links of its own."""
    conf = load_zenoh_config(ZENOH_DIR / f"{side}-client.json5", identity,
                             credentials.Credentials(folder / side))
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    if not rules:
        conf.insert_json5("access_control/enabled", "false")
    if mode is not None:
        conf.insert_json5("mode", json.dumps(mode))
        conf.insert_json5("listen/endpoints", "[]")
    return close_at_exit(zenoh.open(conf))


def bare_tls_client(endpoint: str, ca: Path, cert: Path | None = None, key: Path | None = None,
                    timeout_ms: int = 2000) -> zenoh.Session:
    """A client session straight to a TLS listener, trusting ``ca``, showing ``cert`` if given;
    raises ``zenoh.ZError`` if the handshake is refused within ``timeout_ms``."""
    tls: dict[str, object] = {"root_ca_certificate": str(ca)}
    if cert is not None:
        tls |= {"connect_certificate": str(cert), "connect_private_key": str(key), "enable_mtls": True}
    conf = zenoh.Config.from_json5(json.dumps({
        "mode": "client",
        "connect": {"endpoints": [endpoint], "timeout_ms": timeout_ms},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {"link": {"tls": tls}},
    }))
    return close_at_exit(zenoh.open(conf))


def link_address() -> str | None:
    """This computer's address on its default route (no packet is sent), unless it is loopback."""
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.connect(("192.0.2.1", 9))  # TEST-NET-1: only the routing table is consulted
        addr = s.getsockname()[0]
        if not addr.startswith("127."):
            return addr
    return None
