"""The live stream's edges against the real server (uvicorn on loopback, ``server_config``): a
client that stops reading, a client that sends huge messages, many vessel names on the bus."""

from __future__ import annotations

import json
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import SolveRecord, StateEstimate
from seaway.runtime.memory_bus import MemoryHub
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.unit.groundstation.live_server import poll, serve, stuck_client

BIG_PREDICTION = [float(i) for i in range(2000)]
"""A solve record's predicted trajectory long enough for ~40 kB frames: buffers fill fast."""


def solve(k: int) -> SolveRecord:
    return SolveRecord(stamp_ns=time.time_ns(), controller="cc-empc", status="ok", success=True,
                       iterations=k, solve_time_s=0.01, predicted_x_m=BIG_PREDICTION,
                       predicted_y_m=BIG_PREDICTION)


def state(x_m: float) -> StateEstimate:
    return StateEstimate(stamp_ns=time.time_ns(), u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=0.0,
                         psi_rad=0.0)


def drained_to_the_end(sock) -> bool:
    """Read the socket until the server's side is gone (EOF or reset); False if it stays open."""
    sock.settimeout(5)
    try:
        while sock.recv(1 << 20):
            pass
    except TimeoutError:
        return False
    except OSError:  # reset: the connection was cut with data unread
        pass
    return True


def test_a_client_that_stops_reading_is_dropped_and_its_place_freed() -> None:
    """Reproduced: a client that completed the handshake and then read nothing kept its place for
    good (75 s and counting, with uvicorn's keep-alive ping long timed out: the server's close
    waits for buffers the client never drains); ``max_stream_clients`` of them shut every page
    out with 1013."""
    hub = MemoryHub()
    vessel = hub.bus("v1")
    vessel.declare_alive("controller")
    solves = vessel.publisher(keys.SOLVE)
    with serve(hub, stream_rate_hz=1000.0, max_stream_clients=1, stream_send_timeout_s=1.0) as s:
        stuck = stuck_client(s.port)
        poll(lambda: s.gs.hub.clients == 1, what="the stuck client to be served")
        stop = threading.Event()

        def flood() -> None:  # ~40 kB frames until the stuck client's buffers are full
            k = 0
            while not stop.is_set():
                k += 1
                solves.put(solve(k))
                time.sleep(0.002)

        feeder = threading.Thread(target=flood, daemon=True)
        feeder.start()
        try:
            poll(lambda: s.gs.hub.clients == 0, what="the stuck client to be dropped")
        finally:
            stop.set()
            feeder.join(10)
        assert s.gs.hub.dropped_slow == 1
        assert drained_to_the_end(stuck), "the stuck client's connection was left open"
        stuck.close()
        # Its place is free: a new client is served (not told 1013 "too many stream clients").
        with connect(f"{s.url}/api/stream", open_timeout=30) as ws:
            frame = json.loads(ws.recv(timeout=30))
            assert frame["vessel"] == "v1"


def test_a_client_that_reads_slowly_but_keeps_up_stays() -> None:
    """The deadline is per frame taken, not a rate: a client that reads, however slowly, stays."""
    hub = MemoryHub()
    vessel = hub.bus("v1")
    vessel.declare_alive("controller")
    states = vessel.publisher(keys.NAV_STATE)
    with serve(hub, stream_send_timeout_s=5.0) as s, \
            connect(f"{s.url}/api/stream", open_timeout=30) as ws:
        for k in range(20):
            states.put(state(float(k)))
            json.loads(ws.recv(timeout=30))
        assert s.gs.hub.dropped_slow == 0 and s.gs.hub.clients == 1


def test_a_client_sending_a_huge_message_is_closed_with_1009_and_others_go_on() -> None:
    """Reproduced: uvicorn's default bound is 16 MiB a message, and the stream reads (and throws
    away) whatever a client sends: 16 clients each sending 15 MiB took the server from 71 MB to a
    peak of 1.25 GB (256 clients: several GB)."""
    hub = MemoryHub()
    vessel = hub.bus("v1")
    vessel.declare_alive("controller")
    vessel.publisher(keys.NAV_STATE).put(state(1.0))
    with serve(hub) as s, connect(f"{s.url}/api/stream", open_timeout=30) as good:
        assert json.loads(good.recv(timeout=30))["vessel"] == "v1"
        with connect(f"{s.url}/api/stream", open_timeout=30, max_size=None) as bad:
            bad.recv(timeout=30)
            bad.send("x" * (1 << 20))
            with pytest.raises(ConnectionClosed) as closed:
                while True:
                    bad.recv(timeout=30)
            assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
        # A small message (a page's own keep-alive, say) is read and ignored, as before.
        good.send("ping")
        vessel.publisher(keys.NAV_STATE).put(state(2.0))
        poll_frames = [json.loads(good.recv(timeout=30)) for _ in range(1)]
        assert poll_frames[0]["updates"]["state"]["message"]["x_m"] == 2.0
