"""When the launcher ends a run (issue 56, item 18): a "complete" from the controller's identity
stamped an hour ahead, an hour behind or now, at the start of a mission, stopped the stack. Now a
status ends a mission only when its stamp is within bounds and the navigation state bears it out."""

from __future__ import annotations

from seaway.contract import bundle, keys
from seaway.contract.messages import (
    EnergyBudget,
    MissionAccepted,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    PeriodDone,
    StateEstimate,
    Waypoint,
    return_mission_id,
)
from seaway.runtime.memory_bus import MemoryBus
from seaway.tools.launch.mission_end import MissionEnd, MissionsTaken, VesselEnd

S = 1_000_000_000
NOW = 1_800_000_000 * S  # a wall clock [ns]
HOUR = 3600 * S
MISSION = MissionRequest(
    stamp_ns=NOW,
    mission_id="m1",
    coa_radius_m=2.0,
    task_power_w=250.0,
    waypoints=[Waypoint(x_m=0.0, y_m=0.0), Waypoint(x_m=300.0, y_m=0.0)],
)


def state(x_m: float, t_ns: int = NOW) -> StateEstimate:
    return StateEstimate(stamp_ns=t_ns, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=0.0, psi_rad=0.0)


def status(state_: str = "complete", t_ns: int = NOW, mission_id: str = "m1") -> MissionStatus:
    return MissionStatus(stamp_ns=t_ns, state=state_, mission_id=mission_id, active_leg=1, waypoint_count=2)


def test_a_complete_at_the_start_is_not_taken_whatever_its_stamp() -> None:
    end = VesselEnd("v1", MISSION)
    end.on_state(state(0.5), NOW)  # the vessel at the start, 300 m from the last waypoint
    for stamp in (NOW + HOUR, NOW - HOUR, NOW):
        assert not end.over(status(t_ns=stamp), None, NOW)
    assert end.gate.dropped == {("mission/status", "ahead"): 1, ("mission/status", "behind"): 1}
    assert end.refused == {"stamp": 2, "position": 1}


def test_a_complete_after_the_vessel_arrived_is_taken_also_once_it_coasted_on() -> None:
    end = VesselEnd("v1", MISSION)
    end.on_state(state(150.0), NOW)
    assert not end.over(status(), None, NOW)
    end.on_state(state(299.0), NOW)  # within the circle
    end.on_state(state(310.0), NOW)  # then coasted on: the arrival was seen
    assert end.over(status(), None, NOW)
    assert not end.over(status(t_ns=NOW + HOUR), None, NOW)  # still bounded


def test_a_state_stamped_out_of_bounds_is_no_evidence() -> None:
    end = VesselEnd("v1", MISSION)
    end.on_state(state(300.0, NOW + HOUR), NOW)
    end.on_state(state(300.0, NOW - HOUR), NOW)
    assert not end.over(status(), None, NOW)


def test_the_return_home_is_complete_only_with_the_vessel_seen_back_at_home() -> None:
    end = VesselEnd("v1", MISSION)
    home = status(mission_id=return_mission_id("m1"))
    end.on_state(state(80.0), NOW)  # out on the first leg: a return "complete" there is refused
    assert not end.over(home, None, NOW)
    end.on_state(state(1.0), NOW)
    assert end.over(home, None, NOW)
    end.on_state(state(6.0), NOW)  # coasted on past the circle: the arrival was seen
    assert end.over(home, None, NOW)
    assert end.refused == {"position": 1}


def test_a_return_home_decided_before_the_vessel_left_is_complete_where_it_stands() -> None:
    end = VesselEnd("v1", MISSION)
    home = status(mission_id=return_mission_id("m1"))
    end.on_state(state(0.0), NOW)  # the budget decided the return at the start, at home
    end.on_state(state(1.5), NOW)  # it never left the circle
    assert end.over(home, None, NOW)
    assert not end.over(status(), None, NOW)  # the mission's own "complete" there is no arrival
    assert end.refused == {"position": 1}


def test_a_return_home_once_at_home_is_not_complete_once_the_vessel_went_out() -> None:
    end = VesselEnd("v1", MISSION)
    home = status(mission_id=return_mission_id("m1"))
    end.on_state(state(0.0), NOW)  # at home at the start ...
    end.on_state(state(40.0), NOW)  # ... then out on the leg: a forged return "complete" now
    assert not end.over(home, None, NOW)


def test_a_loop_mission_ends_only_after_the_vessel_went_round() -> None:
    loop = MISSION.model_copy(
        update={
            "waypoints": [Waypoint(x_m=0.0, y_m=0.0), Waypoint(x_m=50.0, y_m=0.0), Waypoint(x_m=0.0, y_m=1.0)]
        }
    )
    end = VesselEnd("v1", loop)
    end.on_state(state(0.0), NOW)
    assert not end.over(status(), None, NOW)
    end.on_state(state(40.0), NOW)
    end.on_state(state(0.5), NOW)
    assert end.over(status(), None, NOW)


def test_waypoints_in_degrees_are_judged_through_the_origin() -> None:
    origin = NavOrigin(stamp_ns=NOW, lat_rad=0.82, lon_rad=0.14, alt_m=0.0)
    mission = MISSION.model_copy(
        update={
            "waypoints": [Waypoint(lat_deg=46.983, lon_deg=8.021), Waypoint(lat_deg=46.985, lon_deg=8.021)]
        }
    )
    end = VesselEnd("v1", mission)
    end.on_state(state(0.0), NOW)
    assert not end.over(status(), None, NOW)
    assert end.refused == {"origin": 1}
    end.on_origin(origin)
    far, there = end.targets()
    assert far is not None and there is not None
    end.on_state(state(far[0]).model_copy(update={"y_m": far[1]}), NOW)
    assert end.over(status(), None, NOW)


def test_a_hold_needs_a_current_budget() -> None:
    end = VesselEnd("v1", MISSION)
    held = status("paused")
    budget = EnergyBudget(
        stamp_ns=NOW - HOUR,
        mission_id="m1",
        energy_used_j=1.0,
        decision="hold",
        home_x_m=0.0,
        home_y_m=0.0,
        policy="hold",
    )
    assert not end.over(held, budget, NOW)
    assert end.over(held, budget.model_copy(update={"stamp_ns": NOW}), NOW)


def test_lockstep_judges_stamps_against_the_newest_state() -> None:
    end = VesselEnd("v1", MISSION, period_ns=S // 10)
    t = 120 * S
    end.on_state(state(300.0, t), end.reference_ns(NOW, state(300.0, t)))
    assert end.reference_ns(NOW, None) is None
    assert end.over(status(t_ns=t), None, t)
    assert not end.over(status(t_ns=t + HOUR), None, t)
    assert not end.over(status(t_ns=t - 10 * S), None, t)


def test_on_a_bus_every_vessel_must_be_over() -> None:
    from seaway.contract import keys

    bus = MemoryBus("v1")
    ending = MissionEnd(["v1", "v2"], MISSION)
    ending.watch(bus)
    for v in ("v1", "v2"):
        bus.publisher(keys.NAV_STATE, vessel=v).put(state(299.0))
    bus.publisher(keys.MISSION_STATUS, vessel="v1").put(status())
    assert not ending.over(NOW)  # v2 has no status
    bus.publisher(keys.MISSION_STATUS, vessel="v2").put(status())
    assert ending.over(NOW)


def test_mission_time_is_the_wall_clock_in_real_time_and_the_states_in_lockstep() -> None:
    """``--max-mission-s`` (seaway.tools.launch.stack) reads ``MissionEnd.timed_out``."""
    bus = MemoryBus("v1")
    live = MissionEnd(["v1"], MISSION)
    live.watch(bus)
    assert live.timed_out(60.0) is None  # no look yet
    live.over(NOW)
    live.over(NOW + 59 * S)  # no state at all: the wall clock still runs
    assert live.timed_out(60.0) is None
    live.over(NOW + 90 * S)
    assert live.timed_out(60.0) == 90.0
    # Lockstep: the states' simulated time since t_0, where the clock held until the mission was
    # there, and the limit reached at the last period the sim's clock flies to (t = 20.0 s for
    # 20.05 s: the clock holds there).
    batch = MissionEnd(["v1", "v2"], MISSION, period_ns=S // 10)
    batch.watch(bus)
    states = {v: bus.publisher(keys.NAV_STATE, vessel=v) for v in ("v1", "v2")}
    batch.over(NOW)
    assert batch.timed_out(20.05) is None  # no state: no simulated time yet
    states["v1"].put(state(10.0, 20 * S))
    states["v2"].put(state(5.0, 19_900_000_000))
    batch.over(NOW + HOUR)  # the wall clock does not count in lockstep
    assert batch.timed_out(20.05) is None  # v2 is one period short
    states["v2"].put(state(5.0, 20 * S))
    batch.over(NOW)
    assert batch.timed_out(20.05) == 20.0
    assert batch.timed_out(20.1) is None  # a limit of 20.1 s flies to t = 20.1 s


def test_a_mission_that_ended_is_not_held_to_its_time() -> None:
    """A profile that runs on after the mission (``sim``, ``--stay``): the limit no longer ends it."""
    bus = MemoryBus("v1")
    live = MissionEnd(["v1"], MISSION)
    live.watch(bus)
    bus.publisher(keys.NAV_STATE, vessel="v1").put(state(150.0))
    live.over(NOW)
    bus.publisher(keys.NAV_STATE, vessel="v1").put(state(299.0, NOW + 30 * S))
    bus.publisher(keys.MISSION_STATUS, vessel="v1").put(status(t_ns=NOW + 30 * S))
    assert live.over(NOW + 30 * S)
    assert not live.over(NOW + 90 * S)  # the status is a minute old by now: not "over" again
    assert live.timed_out(60.0) is None  # but the mission did end


class HandOffCountingBus(MemoryBus):
    """An in-memory bus that notes each subscription whose samples would go to a callback on a
    Python thread of the transport's (``inline=False``), one hand-off per sample."""

    def __init__(self, vessel: str) -> None:
        super().__init__(vessel)
        self.handed_off: list[str] = []

    def subscribe_raw(self, keyexpr, callback, *, inline=False, history_s=0.0):
        if not inline:
            self.handed_off.append(keyexpr)
        return super().subscribe_raw(keyexpr, callback, inline=inline, history_s=history_s)


def accepted(stamp_ns: int) -> MissionAccepted:
    return MissionAccepted.make(
        stamp_ns=stamp_ns,
        accepted_ns=stamp_ns,
        mission_id="m1",
        waypoints=MISSION.waypoints,
        coa_radius_m=2.0,
        task_power_w=1.0,
        controller="cc-empc",
        predict_disturbance=False,
    )


def test_missions_taken_are_read_when_looked_at_with_no_callback_per_sample() -> None:
    """The launcher heard ``mission/accepted`` through a callback, which in lockstep handed every
    controller bundle (hundreds a second) to a Python thread to find the key in it. Now it is read
    when the launcher looks; alone (real time) or in a controller's bundle (lockstep)."""
    bus = HandOffCountingBus("v1")
    taken = MissionsTaken(["v1", "v2", "v3"])
    taken.watch(bus)
    assert bus.handed_off == []  # nothing per sample to a Python thread
    assert taken.look() == set()
    bus.publisher(keys.MISSION_ACCEPTED, vessel="v1").put(accepted(NOW))
    assert taken.look() == {"v1"}
    done = PeriodDone(
        stamp_ns=S,
        service="controller",
        episode=0,
        seq=1,
        period_ns=S // 10,
        published={keys.MISSION_ACCEPTED.suffix: [S]},
    )
    payload = bundle.encode(done.encode(), [(keys.MISSION_ACCEPTED.suffix, accepted(S).encode())])
    bus.raw_publisher(keys.LOCKSTEP_CONTROLLER.key("v2"), bundle.ENCODING).put(payload)
    assert taken.look() == {"v1", "v2"}
    assert taken.look() == {"v1", "v2"}  # once taken, taken for the run
