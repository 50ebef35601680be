"""Issue #57 item 5, honest states: a mission sent while the vehicle cannot fly it (disarmed, a
mode that withholds the thrust, no link) is accepted as ``waiting``, saying for what, never
"started"; it starts by itself at the first status from its acceptance on that says the vehicle
applies the thrust (the launcher arms and sets the mode, then sends the mission)."""

from __future__ import annotations

import pytest
from seaway.contract.messages import MissionCommand

from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_vehicle_pause import status

T0 = 1_000 * DT_NS


@pytest.mark.parametrize(("withheld", "mode", "said"), [
    ("disarmed", "MANUAL", "disarmed"),
    ("mode", "HOLD", "mode HOLD"),
    ("no_link", "MANUAL", "no link"),
])
def test_a_mission_sent_while_the_vehicle_cannot_fly_it_waits_and_says_why(withheld, mode, said):
    core = make_core(ScriptedSolver())
    core.on_vehicle_status(status(T0 - DT_NS, withheld, mode))
    reply = core.handle_mission(T0, mission())
    assert reply.accepted and reply.detail["state"] == "waiting"
    assert "started" not in reply.reason and said in reply.reason
    cmd, record, st = core.step(T0 + DT_NS, state(1))
    assert st.state == "waiting" and said in st.reason and record is None
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and cmd.source == "waiting"
    assert st.energy_used_j == 0.0
    # Still not: it keeps waiting, saying why.
    assert core.on_vehicle_status(status(T0 + DT_NS + 1, withheld, mode)) is None
    _, _, st = core.step(T0 + 2 * DT_NS, state(2))
    assert st.state == "waiting"
    # Armed and in the right mode: it starts by itself.
    assert core.on_vehicle_status(status(T0 + 2 * DT_NS + 1, None)) is not None
    _, record, st = core.step(T0 + 3 * DT_NS, state(3))
    assert st.state == "active" and st.reason == "" and record is not None


def test_the_launchers_flow_arm_then_send_starts_at_the_next_status() -> None:
    # The last status heard predates the arming the launcher just did: the mission waits for the
    # next one, which says armed, and flies.
    core = make_core(ScriptedSolver())
    core.on_vehicle_status(status(T0 - 1, "disarmed"))
    assert core.handle_mission(T0, mission()).detail["state"] == "waiting"
    core.on_vehicle_status(status(T0 + 1, None))
    _, _, st = core.step(T0 + DT_NS, state(1))
    assert st.state == "active"


def test_a_vehicle_that_applies_the_thrust_starts_at_once() -> None:
    core = make_core(ScriptedSolver())
    core.on_vehicle_status(status(T0 - 1, None))
    reply = core.handle_mission(T0, mission())
    assert reply.detail["state"] == "active" and "started" in reply.reason
    # No vehicle_io at all (lockstep): no status, no wait.
    assert make_core(ScriptedSolver()).handle_mission(T0, mission()).detail["state"] == "active"


def test_a_waiting_mission_can_be_aborted() -> None:
    core = make_core(ScriptedSolver())
    core.on_vehicle_status(status(T0 - 1, "disarmed"))
    core.handle_mission(T0, mission())
    reply = core.handle_command(T0 + 1, MissionCommand.make(stamp_ns=0, command="abort"))
    assert reply.accepted and core.missions.state == "aborted"
    core.on_vehicle_status(status(T0 + 2, None))
    assert core.missions.state == "aborted"  # not started by the arming


def test_a_waiting_mission_paused_by_the_operator_does_not_start_at_the_arming() -> None:
    core = make_core(ScriptedSolver())
    core.on_vehicle_status(status(T0 - 1, "disarmed"))
    core.handle_mission(T0, mission())
    reply = core.handle_command(T0 + 1, MissionCommand.make(stamp_ns=0, command="pause"))
    assert reply.accepted and core.missions.state == "paused"
    core.on_vehicle_status(status(T0 + 2, None))  # armed, applying the thrust: not started
    _, record, st = core.step(T0 + DT_NS, state(1))
    assert st.state == "paused" and record is None
    # Resumed by the operator once the vehicle can fly it, it flies.
    reply = core.handle_command(T0 + DT_NS + 1, MissionCommand.make(stamp_ns=0, command="resume"))
    assert reply.accepted
    _, record, st = core.step(T0 + 2 * DT_NS, state(2))
    assert st.state == "active" and record is not None
