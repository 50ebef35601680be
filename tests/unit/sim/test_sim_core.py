"""The sim's core: actuators (saturation, dead zone, lag), determinism, sensor scheduling, reload."""

from __future__ import annotations

import math

import pytest
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore

PERIOD_NS = 100_000_000  # the paper's 0.1 s control period


def make(name: str, **updates) -> SimCore:
    sc = load_scenario(name)
    if updates:
        sc = sc.model_copy(update=updates)
    return SimCore(sc, load_vessel(sc.vessel))


def applied(core: SimCore, command: tuple[float, float]) -> tuple[float, float]:
    core.advance(command, PERIOD_NS)
    t = core.truth()
    return t.thrust_port_n, t.thrust_starboard_n


@pytest.mark.parametrize(("command", "expected"), [
    ((25.0, -25.0), (10.0, -10.0)),     # beyond +-10 N (paper-sim): clamped
    ((10.0, -10.0), (10.0, -10.0)),     # at the bound: unchanged
    ((3.5, -0.2), (3.5, -0.2)),         # inside: unchanged (no dead zone on paper-sim)
])
def test_saturation_at_thrust_max(command, expected) -> None:
    assert applied(make("paper-c1"), command) == expected


def test_saturation_uses_the_reverse_bound_when_it_differs() -> None:
    core = make("paper-c1")
    core.vessel = core.vessel.model_copy(update={"reverse_thrust_max_n": 4.0})
    core.load(core.scenario, core.vessel)
    assert applied(core, (-9.0, 9.0)) == (-4.0, 9.0)


@pytest.mark.parametrize(("command", "expected"), [
    ((9.9, -9.9), (0.0, 0.0)),          # inside the 10 N dead zone of paper-boat: nothing
    ((10.5, -12.0), (10.5, -12.0)),     # outside: passes
    ((200.0, 9.0), (75.0, 0.0)),        # saturation first (75 N), then the dead zone
])
def test_dead_zone_of_the_real_boat(command, expected) -> None:
    assert applied(make("lake"), command) == expected


def test_no_dead_zone_unless_the_scenario_asks() -> None:
    assert applied(make("lake", dead_zone=False), (9.9, -9.9)) == (9.9, -9.9)


def test_first_order_thruster_lag() -> None:
    sc = load_scenario("paper-c1").model_copy(update={"thruster_lag": True})
    vessel = load_vessel(sc.vessel).model_copy(update={"thruster_time_constant_s": 0.2})
    core = SimCore(sc, vessel)
    core.advance((8.0, -4.0), PERIOD_NS)
    # Exact first-order response after 0.1 s with tau = 0.2 s: T = T_cmd (1 - e^{-0.5}).
    k = 1.0 - math.exp(-0.5)
    t = core.truth()
    assert (t.thrust_port_n, t.thrust_starboard_n) == pytest.approx((8.0 * k, -4.0 * k), rel=1e-12)
    for _ in range(20):  # 2 s = 10 tau later it has settled
        core.advance((8.0, -4.0), PERIOD_NS)
    assert core.truth().thrust_port_n == pytest.approx(8.0, rel=1e-4)


def run(core: SimCore, periods: int) -> tuple[list, list, list, list]:
    """Truth, disturbance, GNSS and attitude outputs of a scripted run (commands vary)."""
    truth, dist, gnss, att = [], [], [], []
    for k in range(periods):
        core.advance((40.0 + 20.0 * math.sin(0.05 * k), 25.0), PERIOD_NS)
        s = core.take_samples()
        truth.append(core.truth().model_dump())
        dist.append(core.disturbance().model_dump())
        gnss += [None if f is None else f.model_dump() for f in s.gnss]
        att += [a.model_dump() for a in s.attitude]
    return truth, dist, gnss, att


def test_same_scenario_and_seed_give_identical_runs_bit_for_bit() -> None:
    # lake: wind gusts, a current, GNSS/heading/rate/SOG noise, dead zone: every random stream.
    a = run(make("lake"), 300)
    b = run(make("lake"), 300)
    assert a == b  # exact float equality, field by field
    assert len(a[2]) == 151 and len(a[3]) == 601  # t = 0, then 5 Hz GNSS, 20 Hz attitude, 30 s


def test_a_different_seed_gives_a_different_run() -> None:
    a = run(make("lake"), 100)
    b = run(make("lake", seed=8), 100)
    assert a[0][-1]["x_m"] != b[0][-1]["x_m"]  # the gusts differ, so the trajectory does
    assert a[2][10]["lat_rad"] != b[2][10]["lat_rad"]  # and the GNSS noise
    assert a[3][10]["yaw_rad"] != b[3][10]["yaw_rad"]  # and the heading noise


def test_reporting_the_disturbance_never_changes_the_trajectory() -> None:
    quiet, chatty = make("lake"), make("lake")
    for k in range(50):
        quiet.advance((30.0, 20.0), PERIOD_NS)
        chatty.advance((30.0, 20.0), PERIOD_NS)
        if k % 3 == 0:
            chatty.disturbance()
            chatty.disturbance()
    assert quiet.truth() == chatty.truth()


def test_sensor_samples_are_taken_at_their_own_instants() -> None:
    core = make("lake")
    first = core.take_samples()  # t = 0: one of each
    assert [f.stamp_ns for f in first.gnss] == [0]
    assert [a.stamp_ns for a in first.attitude] == [0]
    core.advance((30.0, 30.0), PERIOD_NS)
    core.advance((30.0, 30.0), PERIOD_NS)
    s = core.take_samples()
    assert [f.stamp_ns for f in s.gnss] == [200_000_000]
    assert [a.stamp_ns for a in s.attitude] == [50_000_000 * i for i in range(1, 5)]


def test_a_step_split_by_sensor_instants_is_the_same_motion() -> None:
    """Splitting at sample instants keeps the 10 ms grid: same state as one plant step."""
    no_sensors = make("paper-c1", sensors=load_scenario("paper-c1").sensors.model_copy(
        update={"gnss_rate_hz": 0.5, "attitude_rate_hz": 0.5}))
    many = make("paper-c1")
    for _ in range(10):
        no_sensors.advance((5.0, 3.0), PERIOD_NS)
        many.advance((5.0, 3.0), PERIOD_NS)
    assert many.truth().model_dump() == pytest.approx(no_sensors.truth().model_dump(), rel=1e-12)


def test_loading_restarts_the_vessel_but_not_the_clock() -> None:
    core = make("paper-c1")
    for _ in range(5):
        core.advance((10.0, 10.0), PERIOD_NS)
    assert core.truth().x_m > 0.05
    core.load(load_scenario("paper-c4"), core.vessel)
    t = core.truth()
    assert (t.x_m, t.u_mps, t.energy_j, t.stamp_ns) == (0.0, 0.0, 0.0, 5 * PERIOD_NS)
    assert core.disturbance().surge_n == pytest.approx(-0.0987)
