"""A link between vehicle_io and an autopilot's firmware that the test can fade: every byte (TCP)
or datagram (UDP) is carried both ways, except while faded, when both ways are dropped, as over a
radio out of range. The link stays up across the firmware's restarts.

* ``TcpRelay``: vehicle_io connects to ``url``; the relay connects to the firmware's TCP port (ArduPilot
  SITL's SERIAL0), and again whenever the firmware closes it (a reboot re-executes SITL, a killed
  one is started again), while vehicle_io's connection stays open, as a serial line would.
* ``UdpRelay``: PX4 SITL sends to ``udpin:127.0.0.1:P`` and listens on its own port; the relay takes
  P, and talks to vehicle_io on a port of its own (vehicle_io's ``url``).
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time


class _Fade:
    def __init__(self) -> None:
        self.until = 0.0
        self.dropped = 0  # bytes or datagrams dropped

    def fade(self, seconds: float) -> None:
        """Drop everything both ways for ``seconds`` from now."""
        self.until = time.monotonic() + seconds

    @property
    def faded(self) -> bool:
        return time.monotonic() < self.until


class TcpRelay(_Fade):
    def __init__(self, upstream_port: int) -> None:
        super().__init__()
        self.upstream_port = upstream_port
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"tcp:127.0.0.1:{self.listener.getsockname()[1]}"
        self.upstream_connects = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _connect(self) -> socket.socket | None:
        try:
            s = socket.create_connection(("127.0.0.1", self.upstream_port), timeout=1)
        except OSError:
            return None
        self.upstream_connects += 1
        return s

    def _run(self) -> None:
        self.listener.settimeout(0.2)
        down: socket.socket | None = None
        up: socket.socket | None = None
        while not self._stop.is_set():
            if down is None:
                with contextlib.suppress(TimeoutError, OSError):
                    down, _ = self.listener.accept()
                continue
            if up is None:
                up = self._connect()
                if up is None:
                    time.sleep(0.2)
                    continue
            ready, _, _ = select.select([down, up], [], [], 0.1)
            for s in ready:
                peer = up if s is down else down
                try:
                    data = s.recv(65536)
                except OSError:
                    data = b""
                if not data:
                    if s is up:  # the firmware went away: connect again, keep vehicle_io's side
                        up.close()
                        up = None
                        break
                    self._stop.set()  # vehicle_io closed its end
                    break
                if self.faded:
                    self.dropped += len(data)
                    continue
                with contextlib.suppress(OSError):
                    peer.sendall(data)
        for s in (down, up, self.listener):
            if s is not None:
                with contextlib.suppress(OSError):
                    s.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(3)


class UdpRelay(_Fade):
    def __init__(self, firmware_sends_to: int, firmware_listens_on: int) -> None:
        super().__init__()
        self.up = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.up.bind(("127.0.0.1", firmware_sends_to))
        self.firmware = ("127.0.0.1", firmware_listens_on)
        self.down = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.down.bind(("127.0.0.1", 0))
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        probe.bind(("127.0.0.1", 0))
        self.vio_port = probe.getsockname()[1]
        probe.close()
        self.url = f"udpin:127.0.0.1:{self.vio_port}"
        self._vio_from: tuple[str, int] | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.up, self.down], [], [], 0.1)
            for s in ready:
                try:
                    data, _src = s.recvfrom(65536)
                except OSError:
                    continue
                if self.faded:
                    self.dropped += 1
                    continue
                with contextlib.suppress(OSError):
                    if s is self.up:  # from the firmware: to vehicle_io's udpin port
                        self.down.sendto(data, ("127.0.0.1", self.vio_port))
                    else:  # from vehicle_io: to the firmware
                        self.up.sendto(data, self.firmware)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(3)
        for s in (self.up, self.down):
            with contextlib.suppress(OSError):
                s.close()
