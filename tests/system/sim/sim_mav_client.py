"""A minimal MAVLink 2 ground-side client over a real UDP socket, for the sim's system tests.

It plays vehicle_io's part: sends with system id 255 / component 190 (a GCS), keeps every message
it receives, by type, with the wall time of arrival.
"""

from __future__ import annotations

import socket
import time
from collections import defaultdict
from typing import Any

from pymavlink.dialects.v20 import common as ml

SIM_SYSID = 1


class MavClient:
    def __init__(self, port: int) -> None:
        self.addr = ("127.0.0.1", port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.tx = ml.MAVLink(None, 255, 190)
        self.got: dict[str, list[tuple[float, Any]]] = defaultdict(list)

    def send(self, msg: Any) -> None:
        self.sock.sendto(msg.pack(self.tx), self.addr)

    def send_raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.addr)

    def pump(self, seconds: float) -> None:
        """Receive for ``seconds``, filing every message by type."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data, _ = self.sock.recvfrom(65535)
            except TimeoutError:
                return
            for m in ml.MAVLink(None).parse_buffer(data) or []:
                self.got[m.get_type()].append((time.time(), m))

    def wait(self, kind: str, timeout_s: float = 5.0, where=lambda m: True,
             keep_streaming: Any = None) -> Any:
        """The first new ``kind`` message matching ``where``; ``keep_streaming`` is sent meanwhile."""
        seen = len(self.got[kind])
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if keep_streaming is not None:
                self.send(keep_streaming)
            self.pump(0.05)
            for _, m in self.got[kind][seen:]:
                if where(m):
                    return m
            seen = len(self.got[kind])
        raise AssertionError(f"no {kind} within {timeout_s} s")

    def command(self, cmd: int, *params: float, keep_streaming: Any = None) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(ml.MAVLink_command_long_message(SIM_SYSID, 1, cmd, 0, *p))
        ack = self.wait("COMMAND_ACK", where=lambda m: m.command == cmd,
                        keep_streaming=keep_streaming)
        return ack.result

    def messages(self, kind: str) -> list[Any]:
        return [m for _, m in self.got[kind]]

    def close(self) -> None:
        self.sock.close()


def manual_control(y: int, z: int, x: int = 0, r: int = 0) -> Any:
    return ml.MAVLink_manual_control_message(SIM_SYSID, x, y, z, r, 0)
