"""Mission checkpoints: a restarted controller resumes the same mission at the same leg."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from seaway.contract.messages import MissionRequest
from seaway.runtime import atomic
from seaway_controller import checkpoint
from seaway_controller.checkpointing import resume

from tests.unit.controller.test_core import ScriptedSolver, make_core, mission, state


def run_to_second_leg():
    core = make_core(ScriptedSolver())
    assert core.handle_mission(0, mission()).accepted
    for k in range(5):
        core.step(k * 100_000_000, state(k, x=2.0 + k))
    core.step(6 * 100_000_000, state(6, x=7.5, y=0.0))  # inside P1's circle: leg 2 now
    return core


def test_progress_round_trips_through_the_file(tmp_path: Path) -> None:
    core = run_to_second_leg()
    req, leg, st, energy = core.progress()
    assert (leg, st) == (2, "active") and energy > 0
    path = tmp_path / "cp.json"
    checkpoint.save(path, checkpoint.MissionCheckpoint(request=req.model_dump(mode="json"),
                                                       active_leg=leg, state=st, energy_used_j=energy,
                                                       saved_unix_ns=1))
    fresh = make_core(ScriptedSolver())
    resume(fresh, path, 10)
    assert fresh.progress()[1:] == (2, "active", energy)
    assert fresh.missions.leg() == ((8.0, 0.0), (5.13, 8.57))
    assert not list(tmp_path.glob(".cp.json.*"))  # no temporary file left behind


def test_finished_or_unreadable_checkpoints_start_idle(tmp_path: Path, caplog) -> None:
    path = tmp_path / "cp.json"
    core = make_core(ScriptedSolver())
    resume(core, path, 0)  # no file: idle, silently
    assert core.progress() is None
    path.write_text("{ half a file")
    resume(core, path, 0)
    assert core.progress() is None and "ignoring the mission checkpoint" in caplog.text
    good = dict(request=mission().model_dump(mode="json"), active_leg=2, state="complete",
                energy_used_j=3.0, saved_unix_ns=1)
    path.write_text(json.dumps(good))
    resume(core, path, 0)
    assert core.progress() is None  # a complete mission is not restarted
    path.write_text(json.dumps({**good, "state": "active", "active_leg": 7}))
    resume(core, path, 0)
    assert core.missions.state == "idle" and "active leg 7 is not a leg" in caplog.text
    path.write_text(json.dumps({**good, "state": "active", "activ_leg": 2}))
    with pytest.raises(checkpoint.CheckpointError, match="activ_leg: unknown field"):
        checkpoint.load(path)


def test_only_a_durable_save_waits_for_the_disk(tmp_path: Path, monkeypatch) -> None:
    """Real time fsyncs each checkpoint (a power loss keeps it); lockstep does not (a simulation:
    a crash loses nothing the OS has), and both replace the file whole."""
    synced: list[int] = []
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: synced.append(fd))
    req = MissionRequest.make(stamp_ns=0, waypoints=[{"x_m": 0.0, "y_m": 0.0}, {"x_m": 5.0, "y_m": 0.0}],
                              coa_radius_m=1.0, task_power_w=0.49)
    cp = checkpoint.MissionCheckpoint(request=req.model_dump(mode="json"), active_leg=1,
                                      state="active", energy_used_j=3.0, saved_unix_ns=1)
    path = tmp_path / "mission.json"
    checkpoint.save(path, cp, durable=False)
    assert synced == [] and checkpoint.load(path).energy_used_j == 3.0
    checkpoint.save(path, cp.model_copy(update={"energy_used_j": 4.0}))
    assert len(synced) == 1 and checkpoint.load(path).energy_used_j == 4.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mission.json"]  # no temporary left


def test_a_checkpoint_from_an_earlier_launch_into_the_run_folder_is_not_resumed(tmp_path: Path,
                                                                              caplog) -> None:
    """The run folder may be reused (``seaway launch --run-dir``): a checkpoint saved before this
    run's description was written is the earlier launch's mission, not this run's."""
    caplog.set_level("INFO")
    core = run_to_second_leg()
    req, leg, st, energy = core.progress()
    run_file = tmp_path / "run.json"
    run_file.write_text("{}")
    started = run_file.stat().st_mtime_ns
    path = tmp_path / "cp.json"

    def saved_at(ns: int) -> None:
        checkpoint.save(path, checkpoint.MissionCheckpoint(
            request=req.model_dump(mode="json"), active_leg=leg, state=st, energy_used_j=energy,
            saved_unix_ns=ns), durable=False)

    saved_at(started - 1)
    fresh = make_core(ScriptedSolver())
    resume(fresh, path, 10, run_file)
    assert fresh.progress() is None and "saved before this run started" in caplog.text
    saved_at(started)  # this run's (a restart): resumed
    resume(fresh, path, 10, run_file)
    assert fresh.progress()[1:] == (2, "active", energy)
    other = make_core(ScriptedSolver())
    saved_at(started - 1)
    resume(other, path, 10, None)  # started by hand, no run file: the file is all there is
    assert other.progress()[1:] == (2, "active", energy)


def test_real_time_never_waits_for_the_checkpoints_disk(tmp_path: Path, monkeypatch) -> None:
    """A durable write (fsync) took over a second beside another process's large write, and on the
    control loop it left the vessel without a command past vehicle_io's watchdog (CI). Real time
    hands the checkpoint to a writer thread: the request's reply and the control steps go on while
    the disk holds the write, and the last progress is on disk once the service closes."""
    import threading

    from seaway.runtime.clock import WallClock
    from seaway.runtime.memory_bus import MemoryHub
    from seaway.runtime.node import LiveDriver
    from seaway.runtime.run import RunDescription
    from seaway.runtime.service import ServiceContext
    from seaway_controller.node import ControllerNode

    from tests.unit.controller.test_core import DT_NS

    gate, writing, writers, synced = threading.Event(), threading.Event(), [], []
    real_write = atomic.write_text

    def held_write(p, text, durable=True):  # the disk holds every write until the gate opens
        writers.append((threading.current_thread().name, durable))
        writing.set()
        assert gate.wait(10)
        real_write(p, text, durable)

    monkeypatch.setattr(atomic, "write_text", held_write)
    real_fsync = atomic.os.fsync
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: synced.append(fd) or real_fsync(fd))
    hub = MemoryHub()
    ctx = ServiceContext(name="controller", vessel="vessel1", bus=hub.bus("vessel1"), clock=WallClock(),
                         stop=threading.Event(), run=RunDescription(run_id="unit", vessel="vessel1"))
    path = tmp_path / "controller-state.json"
    node = ControllerNode(make_core(ScriptedSolver()), state_file=path)
    node.attach(LiveDriver(ctx, node, DT_NS / 1e9))  # the runtime's wall-clock driver
    assert node._serve("mission/set", node.core.handle_mission, mission()).accepted  # saves (forced)
    t0 = ctx.clock.now_ns()
    for k in range(1, 4):  # each step would save too, a second apart on the service's clock
        monkeypatch.setattr(ctx.clock, "now_ns", lambda k=k: t0 + k * 1_000_000_000)
        node.step(k * DT_NS, state(k, x=2.0 + k))
    assert not gate.is_set() and not path.exists()  # all answered while the disk held the first write
    assert writing.wait(10)  # (the writer's thread may start late on a busy machine)
    assert all(name == "checkpoint" for name, _ in writers)
    gate.set()
    node.checkpoints.close()
    saved = checkpoint.load(path)
    assert saved is not None and saved.state == "active"
    assert saved.energy_used_j == pytest.approx(node.core.progress()[3], rel=1e-12)  # the last step's
    assert all(durable for _, durable in writers) and len(synced) == len(writers)
    ctx.bus.close()


def test_a_return_home_decided_before_a_restart_goes_on_as_a_return_home(tmp_path: Path) -> None:
    """A controller restarted on its way home said 'LOW ENERGY (policy: warn)' and took the return
    for a mission of its own: the checkpoint held the return's request (its own policy only warns)
    and not the decision. The decision is saved with the progress and resumed with it."""
    import threading

    from seaway.contract.messages import BatteryState
    from seaway.runtime.clock import WallClock
    from seaway.runtime.memory_bus import MemoryHub
    from seaway.runtime.run import RunDescription
    from seaway.runtime.service import ServiceContext
    from seaway_controller.budget import SUDDEN_DECIDE_S

    from tests.unit.controller.test_core import DT_NS

    hub = MemoryHub()
    ctx = ServiceContext(name="controller", vessel="vessel1", bus=hub.bus("vessel1"), clock=WallClock(),
                         stop=threading.Event(),
                         run=RunDescription(run_id="unit", vessel="vessel1", clock="lockstep"))
    path = tmp_path / "controller-state.json"
    core = make_core(ScriptedSolver())
    svc = lockstep_node(ctx, core, path)
    assert core.handle_mission(0, mission()).accepted
    core.on_battery(BatteryState.make(stamp_ns=0, source="sim", remaining_j=1.0, reserve_j=0.5))
    # Short from the start: decided once that has lasted (``SUDDEN_DECIDE_S``).
    n = round(SUDDEN_DECIDE_S * 1e9 / DT_NS) + 1
    for k in range(n):
        core.step(k * DT_NS, state(k, x=3.0))
    assert core.budget.returning and core.budget.decision == "return"
    svc.save_checkpoint()
    ctx.bus.close()

    fresh = make_core(ScriptedSolver())
    resume(fresh, path, 10)
    req, leg, st, _ = fresh.progress()
    assert req.mission_id == core.mission_request.mission_id and (leg, st) == (1, "active")
    b = fresh.budget
    assert (b.returning, b.decision, b.decided_ns) == (True, "return", core.budget.decided_ns)
    fresh.on_battery(BatteryState.make(stamp_ns=n * DT_NS, source="sim", remaining_j=1.0,
                                       reserve_j=0.5))
    for k in range(n, n + 3):
        fresh.step(k * DT_NS, state(k, x=2.5))
    last = fresh.take_budget()
    assert last is not None and last.returning and last.decision == "return"


def lockstep_node(ctx, core, path: Path):
    """A controller node with the checkpoint ``path``, attached to the runtime's lockstep driver on
    ``ctx``'s bus (not run: its clock stays before the first period)."""
    from seaway.runtime.node import MemberDriver
    from seaway_controller.node import ControllerNode

    node = ControllerNode(core, state_file=path)
    node.attach(MemberDriver(ctx.bus, node))
    return node


def _service_with_checkpoint(tmp_path: Path, core):
    import threading

    from seaway.runtime.clock import WallClock
    from seaway.runtime.memory_bus import MemoryHub
    from seaway.runtime.run import RunDescription
    from seaway.runtime.service import ServiceContext

    hub = MemoryHub()
    ctx = ServiceContext(name="controller", vessel="vessel1", bus=hub.bus("vessel1"),
                         clock=WallClock(), stop=threading.Event(),
                         run=RunDescription(run_id="unit", vessel="vessel1", clock="lockstep"))
    return lockstep_node(ctx, core, tmp_path / "cp.json"), ctx


@pytest.mark.parametrize("at_rest", ["complete", "paused"])
def test_a_controller_restarted_at_rest_goes_on_holding_station_where_it_held(
        tmp_path: Path, at_rest: str) -> None:
    """A controller restarted while the vessel held station (after the last waypoint, or paused)
    came back idle and the vessel drifted: the hold point was not in the checkpoint and a complete
    mission was not taken up again. Now the new one holds at the same point."""
    from seaway.contract.messages import MissionCommand

    from tests.unit.controller.test_core import DT_NS

    core = make_core(ScriptedSolver())
    svc, ctx = _service_with_checkpoint(tmp_path, core)
    assert core.handle_mission(0, mission()).accepted
    core.step(0, state(0, x=2.0, y=0.0))
    if at_rest == "complete":
        core.step(DT_NS, state(1, x=7.5, y=0.0))    # P1's circle: leg 2
        core.step(2 * DT_NS, state(2, x=5.1, y=8.5))  # the last waypoint's circle: complete
        want = (5.13, 8.57)
    else:
        core.step(DT_NS, state(1, x=3.0, y=0.2))
        assert core.handle_command(2 * DT_NS, MissionCommand.make(stamp_ns=2 * DT_NS,
                                                                  command="pause")).accepted
        want = (3.0, 0.2)
    assert core.missions.state == at_rest and core.missions.hold_point == want
    svc.save_checkpoint(force=True)
    ctx.bus.close()

    fresh = make_core(ScriptedSolver())
    resume(fresh, tmp_path / "cp.json", 10)
    assert fresh.missions.state == at_rest
    assert fresh.missions.hold_point == pytest.approx(want)
    # Pushed 3 m off the hold point, the new controller drives back to it (not zero thrust).
    off = state(3, x=want[0] - 3.0, y=want[1])
    cmd, record, status = fresh.step(3 * DT_NS, off)
    assert record is None and status.state == at_rest
    assert cmd.thrust_port_n + cmd.thrust_starboard_n != 0.0


def test_a_restarted_controller_keeps_the_vessels_home_with_or_without_a_mission(tmp_path: Path
                                                                                ) -> None:
    # The home was where the vessel was armed (or the operator's): a restarted controller hears no
    # arming of a vessel armed already, so without the kept home a mission sent after the restart
    # took where the vessel happened to be as home, and its low-energy return went there.
    import threading

    from seaway.contract.messages import HomeRequest, Waypoint
    from seaway_controller.checkpointing import Checkpoints

    from tests.unit.controller.test_vehicle_pause import status

    path = tmp_path / "cp.json"
    core = make_core(ScriptedSolver())
    core.step(0, state(0, x=3.0, y=4.0))
    core.on_vehicle_status(status(1, None))  # armed here: home (3, 4)
    assert core.home == (3.0, 4.0)
    Checkpoints(path).save(core, threading.Lock(), 10)  # no mission: the home alone is kept
    assert checkpoint.load(path).request is None
    fresh = make_core(ScriptedSolver())
    resume(fresh, path, 20)
    assert fresh.home == (3.0, 4.0) and fresh.progress() is None
    fresh.step(30, state(1, x=40.0, y=0.0))  # the vessel is out on the water now
    fresh.on_vehicle_status(status(31, None))  # its first status: armed already, no new arming
    assert fresh.home == (3.0, 4.0)
    assert fresh.handle_mission(40, mission()).accepted
    assert fresh.mission_request.home == Waypoint(x_m=3.0, y_m=4.0)  # the kept home, not (40, 0)
    # An operator's home set mid-mission is kept with the mission's progress.
    assert fresh.handle_home(50, HomeRequest.make(stamp_ns=50, home=Waypoint(x_m=1.0, y_m=1.0))
                             ).accepted
    Checkpoints(path).save(fresh, threading.Lock(), 60)
    again = make_core(ScriptedSolver())
    resume(again, path, 70)
    assert again.home == (1.0, 1.0) and again.progress() is not None
    # A real arming (disarmed, then armed) still moves it.
    again.step(80, state(2, x=9.0, y=9.0))
    again.on_vehicle_status(status(81, "disarmed"))
    again.on_vehicle_status(status(82, None))
    assert again.home == (9.0, 9.0)
