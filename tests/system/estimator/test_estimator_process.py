"""The estimator process on a real Zenoh session: fed sensors by this test, it publishes nav/state
and nav/origin, answers a reset request, and its recorded inputs replay to the bytes it published."""

from __future__ import annotations

import json
import math
import time

import pytest
from seaway.contract import keys
from seaway.contract.keys import NAV_RESET
from seaway.contract.messages import NavResetRequest, ThrustCommand
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import load_scenario
from seaway.simkit.sensors import SensorSuite, instants_in, origin_of
from seaway.vessel import model
from seaway_estimator.replay import read_trace, replay
from seaway_lab.closed_loop import REALISTIC_NOISE

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
TICK_NS = 100_000_000


def _ready(bus: Bus) -> bool:
    return bus.request(NAV_RESET, NavResetRequest(stamp_ns=0, keep_origin=True, reason="test: ready?"),
                       timeout_s=1.0).accepted


def _state_for(sub, t_ns: int, timeout_s: float = 5.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = sub.get(0.1)
        if msg is not None:
            assert msg.stamp_ns == t_ns, f"nav/state stamped {msg.stamp_ns}, tick was {t_ns}"
            return msg
    return None


def test_lockstep_process_publishes_state_and_origin_and_replays_exactly(procs, zenoh_env,
                                                                          tmp_path) -> None:
    """The test is the sim of the lockstep protocol (``seaway.runtime.lockstep``): it answers each
    period listing the samples it published and the command it applied; the estimator answers each
    period with the state it lists, never waiting on a timeout."""
    trace = tmp_path / "inputs.jsonl"
    est = procs.start([str(BIN / "seaway-estimator"), "--lockstep", "--record-inputs", str(trace)],
                      zenoh_env, "estimator")
    wait_for(lambda: "estimator lockstep" in procs.log(est), 20, what="estimator up")
    sc = load_scenario("paper-c4")
    plant = Plant(sc, model.load_vessel(sc.vessel))
    sensors = SensorSuite(REALISTIC_NOISE, sc.origin, sc.seed)
    truth_origin = origin_of(sc.origin)
    with Bus.open("vessel1") as bus:
        wait_for(lambda: _ready(bus), 20, what="the reset queryable (subscriptions declared)")
        states = bus.subscribe(keys.NAV_STATE, mode="fifo")
        origins = bus.subscribe(keys.NAV_ORIGIN, mode="fifo")
        answers = bus.subscribe(keys.LOCKSTEP_ESTIMATOR, mode="fifo")
        sim = Member(bus, "sim", watched=())
        ctl = Member(bus, "controller", watched=(), subscribe=False)  # its bundle: the command
        time.sleep(0.3)  # let our subscriptions reach the estimator's session
        received, first_fix = [], None
        applied: list[int] = []  # the stamp of the command applied over the last period

        def period(k: int, with_sensors: bool = True):
            """Sim period t_k, then the estimator's answer and the state it lists (or None)."""
            nonlocal first_fix
            t = k * TICK_NS
            if k > 0:
                plant.step((3.0, 2.5), TICK_NS / 1e9)
            x = plant.state.x
            after = t - TICK_NS if k > 0 else -1  # instants in (after, t]; t = 0 included
            out = []
            if with_sensors:
                out += [(keys.ATTITUDE, sensors.attitude(ts, x))
                        for ts in instants_in(sensors.attitude_period_ns, after, t)]
                for ts in instants_in(sensors.gnss_period_ns, after, t):
                    fix = sensors.gnss(ts, x, (0.0, 0.0))
                    first_fix = first_fix or fix
                    out.append((keys.GNSS, fix))
            sim.answer(Period(0, t), TICK_NS, out,
                       consumed={keys.THRUST.suffix: applied[-1:]} if applied else {})
            ans = None
            for _ in range(5):  # a repeat if our first samples were lost while Zenoh matched
                ans = answers.get(2.0)
                while ans is not None and ans.stamp_ns != t:
                    ans = answers.get(2.0)
                if ans is not None:
                    break
                sim.repeat()
            assert ans is not None, f"no answer from the estimator for t = {t}"
            if keys.NAV_STATE.suffix not in ans.published:
                return None
            assert ans.published[keys.NAV_STATE.suffix] == [t]
            return _state_for(states, t)

        def command(t: int) -> None:
            ctl.answer(Period(0, t), TICK_NS, [(keys.THRUST, ThrustCommand(
                stamp_ns=t, thrust_port_n=3.0, thrust_starboard_n=2.5, source="test"))])
            applied.append(t)

        first = period(0)
        assert first is not None, "no state at t = 0 (a GNSS fix and a heading are due then)"
        received.append(first)
        command(0)
        for k in range(1, 40):  # 4 s of lockstep, 10 Hz
            msg = period(k)
            assert msg is not None, f"no nav/state for tick {k}"
            received.append(msg)
            command(k * TICK_NS)
        # Stamped exactly with each tick, one per tick, finite, near the truth.
        assert [m.stamp_ns for m in received] == [k * TICK_NS for k in range(40)]
        last = received[-1]
        lat, lon, _ = truth_origin.to_ned(*origin_of_msg(origins, first_fix))
        assert math.hypot(last.x_m + lat - plant.state.x[3], last.y_m + lon - plant.state.x[4]) < 0.3
        assert not last.degraded and len(last.covariance) == 81

        # Re-initialise on request: the answers list no state until a position and a heading
        # arrive again (known at once from the answer, not by waiting).
        reply = bus.request(NAV_RESET, NavResetRequest(stamp_ns=1, keep_origin=True, reason="test"),
                            timeout_s=3)
        assert reply.accepted and reply.detail == {"keep_origin": True}
        assert period(40, with_sensors=False) is None
        command(40 * TICK_NS)
        assert period(41) is None  # a heading but the next GNSS fix is due at 4.2 s
        command(41 * TICK_NS)
        for k in range(42, 46):
            msg = period(k)
            assert msg is not None
            received.append(msg)
            command(k * TICK_NS)
    assert procs.stop(est) < 5.0
    log = procs.log(est)
    assert "re-initialised (request: test" in log and "Traceback" not in log
    # The recorded inputs replay to exactly the bytes the process published.
    outputs = [b for b in replay(read_trace(trace)) if b != b"null"]
    assert outputs == [m.encode() for m in received]


def origin_of_msg(sub, first_fix) -> tuple[float, float, float]:
    """The published origin (it must be the first fix's position) as (lat, lon, alt)."""
    o = sub.get(5.0)
    assert o is not None, "no nav/origin"
    assert (o.lat_rad, o.lon_rad) == (first_fix.lat_rad, first_fix.lon_rad)
    return o.lat_rad, o.lon_rad, o.alt_m


def test_realtime_process_publishes_at_the_configured_rate(procs, zenoh_env, tmp_path) -> None:
    cfg = tmp_path / "estimator.toml"
    cfg.write_text("publish_rate_hz = 10.0\n")
    # The origin is a run-wide fact (seaway.runtime.run): given to the run, not the estimator config.
    est = procs.start([str(BIN / "seaway-estimator"), "--config", str(cfg), "--origin", "47.0,8.0"],
                      zenoh_env, "est-rt")
    wait_for(lambda: "estimator realtime" in procs.log(est), 20, what="estimator up")
    sc = load_scenario("paper-c1")
    sensors = SensorSuite(REALISTIC_NOISE, sc.origin, sc.seed)
    with Bus.open("vessel1") as bus:
        wait_for(lambda: _ready(bus), 20, what="the reset queryable")
        states = bus.subscribe(keys.NAV_STATE, mode="fifo")
        origins = bus.subscribe(keys.NAV_ORIGIN, mode="fifo")
        g, a = bus.publisher(keys.GNSS), bus.publisher(keys.ATTITUDE)
        time.sleep(0.3)
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:  # a vessel at rest at the origin, sensors at 20 Hz
            now = time.time_ns()
            a.put(sensors.attitude(now, [0.0] * 6))
            g.put(sensors.gnss(now, [0.0] * 6, (0.0, 0.0)))
            time.sleep(0.05)
        got = states.drain()
        o = origins.get(2.0)
    assert procs.stop(est) < 5.0
    assert 12 <= len(got) <= 24, len(got)  # ~2 s at 10 Hz
    stamps = [m.stamp_ns for m in got]
    assert stamps == sorted(stamps)
    assert all(math.hypot(m.x_m, m.y_m) < 0.5 for m in got)
    # The configured origin, not the first fix.
    assert o is not None and o.lat_rad == pytest.approx(math.radians(47.0), abs=1e-12)
    assert json.loads(got[-1].encode())["degraded"] is False
