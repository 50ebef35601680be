"""vehicle_io as a real process listens on no more interfaces than its autopilot needs."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from seaway.contract import keys

from tests.conftest import wait_for
from tests.system.vehicle_io.test_vehicle_io_system import (
    Watch,
    alive,
    needs_sim,
    start_sim,
    start_vio,
    udp_port,
)

pytestmark = pytest.mark.system


def hex_address(field: str) -> tuple[str, int]:
    """/proc/net/udp's little-endian hex 'IP:PORT' as ('a.b.c.d', port)."""
    hex_ip, hex_port = field.split(":")
    return ".".join(str(int(hex_ip[i : i + 2], 16)) for i in (6, 4, 2, 0)), int(hex_port, 16)


def udp_sockets(pid: int) -> set[tuple[str, int, tuple[str, int] | None]]:
    """(local address, port, peer or None) of every IPv4 UDP socket process ``pid`` holds, from
    /proc: the peer is the address a connected socket takes datagrams from, and from no other."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        target = os.readlink(fd)
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    out = set()
    for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
        fields = line.split()
        if fields[9] in inodes:
            ip, port = hex_address(fields[1])
            peer = hex_address(fields[2])
            out.add((ip, port, None if peer == ("0.0.0.0", 0) else peer))
    return out


@needs_sim
@pytest.mark.parametrize(("bind_host", "bound"), [(None, "127.0.0.1"), ("0.0.0.0", "0.0.0.0")])
def test_the_mavlink_socket_is_on_loopback_for_a_loopback_autopilot(
    zenoh_env, procs, bus, tmp_path, bind_host, bound
):
    port = udp_port()
    start_sim(procs, zenoh_env, port)  # the simulated PX4, listening on 127.0.0.1
    cfg = {} if bind_host is None else {"bind_host": bind_host}
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}", **cfg)
    Watch(bus, keys.VEHICLE_STATUS).wait(lambda s: s.link_ok, 15, "link (the answers reach us)")
    line = wait_for(lambda: re.search(r"MAVLink \S+ open on (\S+):(\d+)", procs.log(vio)), 5, what="open")
    host, local_port = line.group(1), int(line.group(2))
    assert host == bound

    def held() -> list[tuple[str, tuple[str, int] | None]]:
        return [(ip, peer) for ip, p, peer in udp_sockets(vio.pid) if p == local_port]

    # What the kernel says the process holds on that port: a socket open to anyone on that address
    # only, and the autopilot's own socket (``link.py``), which takes datagrams from it alone. That
    # one opens at the receive thread's next wait after the link locked, a few ms after link_ok.
    wait_for(lambda: any(peer for _ip, peer in held()), 5, what="the autopilot's own socket")
    sockets = held()
    assert {ip for ip, peer in sockets if peer is None} == {bound}
    assert [peer for _ip, peer in sockets if peer is not None] == [("127.0.0.1", port)]
    alive(vio, procs)
