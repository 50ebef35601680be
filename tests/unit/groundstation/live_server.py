"""The ground station served as ``seaway-groundstation`` serves it (uvicorn, ``server_config``) on
loopback over an in-memory bus, for tests that need a real socket: a WebSocket client that stops
reading, one that sends too much."""

from __future__ import annotations

import base64
import contextlib
import os
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import uvicorn
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.service import server_config
from seaway_groundstation.settings import Settings
from seaway_groundstation.station import GroundStation

TOKEN = "live-edge-token-0123456789"


@dataclass
class Served:
    port: int
    gs: GroundStation
    server: uvicorn.Server
    app: Any

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"


@contextlib.contextmanager
def serve(hub: MemoryHub, token: str = TOKEN, **settings: Any) -> Iterator[Served]:
    """The app on a loopback socket until the block ends; ``settings`` over the defaults."""
    app = create_app(hub.bus("gs"), Settings(token=token, **settings))
    sock = socket.create_server(("127.0.0.1", 0))
    server = uvicorn.Server(server_config(app, "warning"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        assert time.monotonic() < deadline and thread.is_alive(), "uvicorn did not start"
        time.sleep(0.02)
    try:
        yield Served(sock.getsockname()[1], app.state.groundstation, server, app)
    finally:
        server.should_exit = True
        thread.join(15)
        sock.close()
    assert not thread.is_alive(), "uvicorn did not stop"


def stuck_client(port: int, path: str = "/api/stream") -> socket.socket:
    """A WebSocket client that completes the handshake and then reads nothing (a small receive
    buffer, so the server's side fills soon)."""
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.settimeout(30)
    s.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall((f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
               f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
               "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head:
        byte = s.recv(1)
        assert byte, "the server closed the handshake"
        head += byte
    assert b" 101 " in head.split(b"\r\n")[0], head
    return s


def poll(predicate: Any, timeout_s: float = 60.0, what: str = "a condition") -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)
