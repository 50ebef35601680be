"""The controller as a process on a real Zenoh session, in lockstep: a command for every state.

The test plays the lockstep simulator: it publishes nav/state stamped with t_k, waits for the command
stamped t_k and integrates the plant with it, as the sim service does.
"""

from __future__ import annotations

import signal
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionCommand, MissionRequest, PeriodDone, StateEstimate, Waypoint
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
VESSEL = "ctrltest"
DT_NS = 100_000_000


def state_msg(stamp_ns: int, x: list[float]) -> StateEstimate:
    return StateEstimate.make(stamp_ns=stamp_ns, u_mps=x[0], v_mps=x[1], r_radps=x[2], x_m=x[3],
                              y_m=x[4], psi_rad=max(-3.141592653589793, min(3.141592653589793, x[5])))


def test_lockstep_commands_missions_and_shutdown(zenoh_env, procs):
    proc = procs.start([str(BIN / "seaway-controller"), "--lockstep", "--scenario", "paper-c1",
                        "--vessel", VESSEL], zenoh_env, name="controller")
    with Bus.open(VESSEL) as bus:
        wait_for(lambda: "controller" in bus.alive_services(timeout_s=0.5) or proc.poll() is not None,
                 timeout_s=120, what="the controller's health token")
        assert proc.poll() is None, procs.log(proc)
        thrust = bus.subscribe(keys.THRUST, mode="fifo")
        solve = bus.subscribe(keys.SOLVE, mode="fifo")
        status = bus.subscribe(keys.MISSION_STATUS, mode="fifo")
        answers = bus.subscribe(keys.LOCKSTEP_CONTROLLER, mode="fifo")
        # This test is the sim and the estimator of the lockstep protocol (seaway.runtime.lockstep).
        sim, est = Member(bus, "sim", watched=()), Member(bus, "estimator", watched=())
        time.sleep(0.5)  # let the peers match publishers and subscribers

        def period(k: int, x) -> PeriodDone:
            p = Period(0, k * DT_NS)
            sim.answer(p, DT_NS)
            est.answer(p, DT_NS, [(keys.NAV_STATE, state_msg(k * DT_NS, x))])
            ans = answers.get(timeout_s=5.0)
            assert ans is not None, f"no answer for state {k}\n{procs.log(proc)}"
            if k == 0 and ans.hold:  # its solver is being made (a first compile): held, then
                ans = answers.get(timeout_s=300.0)  # answered again once it is ready
                assert ans is not None, f"no answer once the solver was made\n{procs.log(proc)}"
            assert ans.stamp_ns == k * DT_NS
            return ans

        sc = load_scenario("paper-c1")
        plant = Plant(sc, load_vessel(sc.vessel))
        for k in range(30):
            ans = period(k, plant.state.x)
            assert not ans.hold and ans.published[keys.THRUST.suffix] == [k * DT_NS]
            cmd = thrust.get(timeout_s=5.0)
            assert cmd is not None, f"no command for state {k}\n{procs.log(proc)}"
            assert cmd.stamp_ns == k * DT_NS and cmd.source == "cc-empc"
            plant.step((cmd.thrust_port_n, cmd.thrust_starboard_n), 0.1)
        # Records are published just after each command: collect all 30.
        records = [solve.get(timeout_s=5.0) for _ in range(30)]
        assert all(r is not None and r.success and r.fallback_level == 0 for r in records)
        assert [r.stamp_ns for r in records] == [k * DT_NS for k in range(30)]
        assert plant.state.x[0] > 0.02 and abs(plant.state.x[4]) < 0.05  # under way, on the leg
        assert wait_for(lambda: status.drain()[-1:], 5.0, what="mission status")[0].state == "active"

        bad = MissionRequest.make(stamp_ns=0, coa_radius_m=1.0, task_power_w=0.49,
                                  waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=0, y_m=0)])
        reply = bus.request(keys.MISSION_SET, bad, timeout_s=5.0)
        assert not reply.accepted and "zero length" in reply.reason
        reply = bus.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=0, command="pause"),
                            timeout_s=5.0)
        assert reply.accepted, reply.reason
        # Paused: nothing to fly, so the answer holds simulated time, and no command goes out.
        ans = period(30, plant.state.x)
        assert ans.hold and keys.THRUST.suffix not in ans.published
        assert thrust.drain() == []

    assert procs.stop(proc, signal.SIGTERM, timeout_s=10.0) < 10.0
    assert proc.returncode == 0, procs.log(proc)


def test_real_time_mode_commands_fresh_states_and_zeroes_stale_ones(zenoh_env, procs):
    proc = procs.start([str(BIN / "seaway-controller"), "--scenario", "paper-c1", "--vessel", VESSEL,
                        "--max-state-age-s", "0.3"], zenoh_env, name="controller-rt")
    with Bus.open(VESSEL) as bus:
        wait_for(lambda: "controller" in bus.alive_services(timeout_s=0.5) or proc.poll() is not None,
                 timeout_s=120, what="the controller's health token")
        assert proc.poll() is None, procs.log(proc)
        thrust = bus.subscribe(keys.THRUST, mode="fifo")
        nav = bus.publisher(keys.NAV_STATE)
        time.sleep(0.5)
        x = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        for _ in range(10):  # 1 s of fresh states at 10 Hz, stamped with the wall clock
            nav.put(state_msg(time.time_ns(), x))
            time.sleep(0.1)
        fresh = thrust.drain()
        assert len(fresh) >= 5 and all(c.source == "cc-empc" for c in fresh)
        assert all(c.thrust_port_n > 0 for c in fresh)
        # Then silence: the controller must zero the thrust instead of repeating old commands.
        stale = wait_for(lambda: [c for c in thrust.drain() if c.source == "stale-state"], 3.0,
                         what="a zero command for a stale state")
        assert (stale[0].thrust_port_n, stale[0].thrust_starboard_n) == (0.0, 0.0)
    assert procs.stop(proc, signal.SIGINT, timeout_s=10.0) < 10.0
    assert proc.returncode == 0, procs.log(proc)
