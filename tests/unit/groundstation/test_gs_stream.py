"""The stream hub with stand-in sockets: a client stuck in ``send`` holds up nobody else, and once
it moves again it gets the latest state, not the backlog of what it missed."""

from __future__ import annotations

import asyncio
import json
from typing import Any

import pytest
from seaway.contract.messages import SolveRecord, StateEstimate
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.stream import StreamClient, StreamHub


class FakeSocket:
    """What ``StreamHub.serve`` uses of a WebSocket; ``send_text`` blocks while ``gate`` is clear."""

    def __init__(self, blocked: bool = False) -> None:
        self.sent: list[dict[str, Any]] = []
        self.gate = asyncio.Event()
        if not blocked:
            self.gate.set()
        self.closed = asyncio.Event()

    async def accept(self) -> None:
        pass

    async def close(self, code: int = 1000, reason: str = "") -> None:
        self.closed.set()

    async def send_text(self, text: str) -> None:
        self.sent.append(json.loads(text))
        await self.gate.wait()

    async def receive(self) -> dict[str, Any]:
        await self.closed.wait()
        return {"type": "websocket.disconnect"}

    def last_x(self) -> float | None:
        for frame in reversed(self.sent):
            if "state" in frame["updates"]:
                return frame["updates"]["state"]["message"]["x_m"]
        return None


async def until(predicate, timeout_s: float = 10.0) -> None:
    async def poll() -> None:
        while not predicate():
            await asyncio.sleep(0.001)

    await asyncio.wait_for(poll(), timeout_s)


def state(x_m: float) -> StateEstimate:
    return StateEstimate(stamp_ns=0, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=0.0, psi_rad=0.0)


def test_a_stuck_client_holds_up_nobody_and_then_gets_the_latest() -> None:
    async def scenario() -> None:
        fleet = Fleet()
        hub = StreamHub(fleet, rate_hz=1000.0)
        hub.bind(asyncio.get_running_loop())
        fleet.on_message("v1", "state", state(0.0), 0.0)
        slow, fast = FakeSocket(blocked=True), FakeSocket()
        serving = [asyncio.create_task(hub.serve(ws, None)) for ws in (slow, fast)]
        await until(lambda: fast.last_x() == 0.0 and slow.last_x() == 0.0)
        n = 100
        for k in range(1, n + 1):
            fleet.on_message("v1", "state", state(float(k)), 0.0)
            hub.notify("v1")
            await asyncio.sleep(0)
        await until(lambda: fast.last_x() == float(n))
        assert len(slow.sent) == 1  # still stuck in its first send; the fast one went on
        slow.gate.set()
        await until(lambda: slow.last_x() == float(n))
        assert len(slow.sent) == 2  # the first frame, then straight to the latest: no backlog
        for ws in (slow, fast):
            await ws.close()
        await asyncio.gather(*serving)
        assert hub.clients == 0

    asyncio.run(scenario())


def test_notifications_from_other_threads_are_coalesced_and_survive_a_closed_loop() -> None:
    fleet = Fleet()
    hub = StreamHub(fleet)
    hub.notify("v1")  # unbound: dropped quietly
    loop = asyncio.new_event_loop()
    hub.bind(loop)
    hub.notify("v1")
    hub.notify("v2")  # one wake-up is already scheduled for both
    loop.close()
    hub.bind(loop)
    hub.notify("v3")  # the loop closed under it: no exception reaches the bus thread


def solve(stamp_ns: int) -> SolveRecord:
    return SolveRecord(stamp_ns=stamp_ns, controller="cc-empc", status="ok", success=True, iterations=3,
                       solve_time_s=0.01)


def kinds(frames: list[str]) -> list[list[str]]:
    return [sorted(json.loads(f)["updates"]) for f in frames]


def test_the_rate_bound_is_per_kind_so_a_state_never_waits_behind_a_solve() -> None:
    """Times are passed in: 20 Hz (0.05 s) per vessel and kind, bursts of two."""
    fleet, client, period = Fleet(), StreamClient(None), 0.05
    fleet.on_message("v1", "state", state(1.0), 0.0)
    frames, release = client.take(fleet, 0.000, period, 0.0)
    assert kinds(frames) == [["state"]] and release is None  # nothing held back
    # The solve of the same period, 10 ms later: out at once (a whole-stream bound would hold it).
    fleet.on_message("v1", "solve", solve(1), 0.01)
    frames, _ = client.take(fleet, 0.010, period, 0.01)
    assert kinds(frames) == [["solve"]]
    # A state 20 ms after the last one still has a token (a late one must not delay the next)...
    fleet.on_message("v1", "state", state(2.0), 0.02)
    frames, _ = client.take(fleet, 0.020, period, 0.02)
    assert kinds(frames) == [["state"]]
    # ...but faster than that they are held back, and the one that goes is the latest.
    fleet.on_message("v1", "state", state(3.0), 0.025)
    fleet.on_message("v1", "state", state(4.0), 0.03)
    frames, release = client.take(fleet, 0.030, period, 0.03)
    assert frames == [] and release == pytest.approx(0.02)
    frames, _ = client.take(fleet, 0.050, period, 0.05)
    (frame,) = [json.loads(f) for f in frames]
    assert list(frame["updates"]) == ["state"] and frame["updates"]["state"]["message"]["x_m"] == 4.0
    # Nothing new: nothing sent, nothing held.
    assert client.take(fleet, 1.0, period, 1.0) == ([], None)


def test_a_flood_of_one_kind_reaches_a_client_at_the_stream_rate() -> None:
    fleet, client, period = Fleet(), StreamClient(None), 0.05
    sent, t, due = 0, 0.0, None
    for k in range(10_000):  # a state every millisecond for 10 s
        t = k * 0.001
        fleet.on_message("v1", "state", state(float(k)), t)
        if due is None or t >= due:
            frames, release = client.take(fleet, t, period, t)
            sent += len(frames)
            due = None if release is None else t + release
    assert 200 <= sent <= 203  # 20 per second, plus the first burst
