"""The controller's real loop (``ControllerService.run_lockstep``) on the in-memory bus, end to end.

No network and no hand-written fake: the estimator, the operator and the observers are other buses on
the same ``MemoryHub``, as they would be other processes on Zenoh. The core has an injected solver
(test_core's ``ScriptedSolver``), so nothing is compiled.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import NamedTuple

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionCommand, MissionStatus, SolveRecord, ThrustCommand
from seaway.runtime.clock import WallClock
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway.runtime.run import RunDescription
from seaway.runtime.service import ServiceContext
from seaway_controller.service import ControllerService

from tests.conftest import wait_for
from tests.unit.controller.test_core import ScriptedSolver, make_core, mission, state

VESSEL = "vessel1"


class Running(NamedTuple):
    hub: MemoryHub  # the network: the test joins it with buses of its own
    bus: MemoryBus  # the controller's bus (its stats)


@pytest.fixture
def controller() -> Iterator[Running]:
    """A controller running its lockstep loop on a thread, as its process would."""
    hub = MemoryHub()
    bus = hub.bus(VESSEL)
    stop = threading.Event()
    ctx = ServiceContext(name="controller", vessel=VESSEL, bus=bus, clock=WallClock(), stop=stop,
                         run=RunDescription(run_id="unit", vessel=VESSEL, clock="lockstep"))
    svc = ControllerService(ctx, make_core(ScriptedSolver()), lockstep=True)
    ctx.ready()
    loop = threading.Thread(target=svc.run_lockstep, name="controller-loop", daemon=True)
    loop.start()
    try:
        yield Running(hub, bus)
    finally:
        stop.set()
        loop.join(2.0)
        bus.close()
    assert not loop.is_alive()


def test_one_command_per_state_and_mission_requests_answered(controller: Running) -> None:
    hub = controller.hub
    estimator, operator, observer = hub.bus(VESSEL), hub.bus(VESSEL), hub.bus(VESSEL)
    thrust = observer.subscribe(keys.THRUST, mode="fifo")
    solves = observer.subscribe(keys.SOLVE, mode="fifo")
    status = observer.subscribe(keys.MISSION_STATUS, mode="fifo")
    assert operator.alive_services() == {"controller"}  # ctx.ready() declared the health token
    states = estimator.publisher(keys.NAV_STATE)

    # Idle: a zero command for the state, stamped with it, and no solve.
    states.put(state(0))
    idle: ThrustCommand = wait_for(lambda: thrust.get(0.05), 5, what="the idle command")
    assert (idle.stamp_ns, idle.thrust_port_n, idle.thrust_starboard_n) == (state(0).stamp_ns, 0.0, 0.0)
    assert status.get(1.0).state == "idle" and solves.drain() == []

    # A mission over the bus, answered with a Reply; then one solved command per state, in order.
    reply = operator.request(keys.MISSION_SET, mission(), timeout_s=2.0)
    assert reply.accepted, reply.reason
    for k in range(1, 6):
        states.put(state(k))
    commands = [thrust.get(5.0) for _ in range(5)]
    assert [c.stamp_ns for c in commands if c is not None] == [state(k).stamp_ns for k in range(1, 6)]
    assert {c.source for c in commands if c is not None} == {"cc-empc"}
    records: list[SolveRecord] = solves.drain()
    assert len(records) == 5 and all(r.success for r in records)
    last: MissionStatus = status.drain()[-1]
    assert (last.state, last.mission_id, last.active_leg) == ("active", "m1", 1)

    # A malformed state is counted and dropped by the controller's bus; the loop goes on.
    estimator.raw_publisher(keys.NAV_STATE.key(VESSEL)).put(b'{"stamp_ns": 1, "x_m": NaN}')
    paused = operator.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="pause"))
    assert paused.accepted, paused.reason
    states.put(state(6))
    held = thrust.get(5.0)
    assert held is not None and held.stamp_ns == state(6).stamp_ns and held.thrust_port_n == 0.0
    assert controller.bus.stats.malformed_by_key == {keys.NAV_STATE.key(VESSEL): 1}

    # A request the core refuses comes back refused, with its reason.
    refused = operator.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="pause"))
    assert not refused.accepted and refused.reason
