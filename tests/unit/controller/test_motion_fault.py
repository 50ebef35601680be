"""Issue 63: the vessel does not do what it is told. While the estimate carries a motion fault
(``StateEstimate.motion_fault``: aground, a thruster stuck, held by friction), an active mission is
paused with the fault named in ``MissionStatus.reason``, the thrust zeroed, and a resume is refused
while the fault lasts, saying which. Pure core, injected solver, time passed in."""

from __future__ import annotations

from seaway.contract.messages import MissionCommand

from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state

START_NS = 1_000 * DT_NS
DETAIL = "commanded 0.950 m/s, measured 0.004 m/s over ground"


def faulted(k: int):
    return state(k).model_copy(update={"motion_fault": "not_moving", "motion_fault_detail": DETAIL})


def resume(core, t_ns: int):
    return core.handle_command(t_ns, MissionCommand.make(stamp_ns=t_ns, command="resume"))


def flying():
    core = make_core(ScriptedSolver())
    assert core.handle_mission(START_NS, mission()).accepted
    for k in (1, 2):
        _, _, st = core.step(START_NS + k * DT_NS, state(1000 + k))
    assert st.state == "active" and st.reason == ""
    return core


def test_a_motion_fault_pauses_the_mission_naming_it() -> None:
    core = flying()
    cmd, record, st = core.step(START_NS + 3 * DT_NS, faulted(1003))
    assert st.state == "paused" and record is None
    assert "motion fault not_moving" in st.reason and DETAIL in st.reason
    assert "does not move as commanded" in st.reason
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)  # drifts: no grinding


def test_resume_is_refused_while_the_fault_lasts_and_allowed_once_cleared() -> None:
    core = flying()
    core.step(START_NS + 3 * DT_NS, faulted(1003))
    core.step(START_NS + 4 * DT_NS, faulted(1004))
    refused = resume(core, START_NS + 4 * DT_NS + 1)
    assert not refused.accepted
    assert "cannot resume: motion fault not_moving" in refused.reason and "stays paused" in refused.reason
    _, _, st = core.step(START_NS + 5 * DT_NS, state(1005))  # the estimator cleared it
    assert st.state == "paused"  # not by itself
    assert resume(core, START_NS + 5 * DT_NS + 1).accepted
    _, record, st = core.step(START_NS + 6 * DT_NS, state(1006))
    assert st.state == "active" and record is not None


def test_no_fault_no_pause() -> None:
    core = flying()
    for k in range(3, 30):
        _, _, st = core.step(START_NS + k * DT_NS, state(1000 + k))
    assert st.state == "active" and st.reason == ""
