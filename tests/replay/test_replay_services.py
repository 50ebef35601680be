"""Replay regression: each service's core, fed a recording's inputs in order, reproduces its outputs.

The goldens in ``data/`` are recordings of the real lockstep stack (``regen.py``; only ``--regen``
rewrites them). The order comes from the recording itself: the sim's lockstep answers
(``seaway.runtime.lockstep``) say, period by period, which samples and which command belong to it.
With that order:

* the estimator (its node ``EstimatorNode`` answering each period, and its core, on the
  in-memory bus) reproduces every recorded ``nav/state``, integers and flags exactly and every float
  to 1e-9 relative: another CPU's libm and BLAS differ in the last bit (4.4e-16 seen), while a real
  change does not hide under that (dropping one GNSS fix moves the estimate by orders of magnitude
  more: tested);
* the controller core (generated solver, its pinned options) reproduces every recorded ``ctrl/thrust``
  to 1e-6 N: the same compiled solver on the same inputs, so in practice exactly, with room for
  a different CPU's floating-point code paths.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import Attitude, GnssFix, PeriodDone, StateEstimate, ThrustCommand
from seaway.recording.reader import iter_messages
from seaway.runtime import run as runs
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryHub
from seaway.runtime.node import Period, PeriodAt
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_estimator.config import load_estimator_config
from seaway_estimator.core import EstimatorCore
from seaway_estimator.main import with_run
from seaway_estimator.node import EstimatorNode

from tests.replay.regen import GOLDENS

DATA = Path(__file__).with_name("data")
VESSEL = "vessel1"
THRUST_TOLERANCE_N = 1e-6
TYPES = {"sensors/gnss": GnssFix, "sensors/attitude": Attitude, "lockstep/sim": PeriodDone,
         "nav/state": StateEstimate, "ctrl/thrust": ThrustCommand}


def recorded(name: str) -> dict[str, list[tuple[bytes, object]]]:
    out: dict[str, list[tuple[bytes, object]]] = {k: [] for k in TYPES}
    for m in iter_messages([DATA / f"{name}.mcap"]):
        suffix = m.topic.split("/", 2)[2]
        if suffix in TYPES:
            out[suffix].append((m.data, TYPES[suffix].decode(m.data)))
    return out


STATE_RTOL, STATE_ATOL = 1e-9, 1e-12
KIND_OF = {keys.GNSS.suffix: "gnss", keys.ATTITUDE.suffix: "attitude", keys.THRUST.suffix: "thrust"}


def close(a: object, b: object) -> bool:
    """Equal, but floats (at any depth) only to STATE_RTOL / STATE_ATOL."""
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=STATE_RTOL, abs_tol=STATE_ATOL)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(close(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(close(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def replay_estimator(scenario: str, rec: dict, skip_gnss: int | None = None) -> dict[int, dict]:
    """Every state the estimator publishes when fed ``rec``'s inputs (without GNSS fix ``skip_gnss``).

    Period by period as the recorded sim answered them (a repeated answer once): the samples and
    the command it lists are queued, then the estimator's loop answers the period."""
    cfg = with_run(load_estimator_config(None),
                   runs.describe(scenario=load_scenario(scenario), scenario_ref=scenario, vessel=VESSEL,
                                 run_id="golden"))
    hub = MemoryHub()
    loop = EstimatorNode(EstimatorCore(cfg))
    member = Member(hub.bus(VESSEL), "estimator", watched=(), subscribe=False)
    states = []
    by_stamp = {(k, msg.stamp_ns): msg for k in KIND_OF for i, (_, msg) in enumerate(rec[k])
                if not (k == keys.GNSS.suffix and i == skip_gnss)}
    last: Period | None = None
    for _data, tick in rec[keys.LOCKSTEP_SIM.suffix]:
        period = Period.of(tick)
        if period == last:
            continue
        last = period
        for listing in (tick.published, tick.consumed):
            for suffix, stamps in listing.items():
                for stamp in stamps if suffix in KIND_OF else ():
                    msg = by_stamp.get((suffix, stamp))
                    if msg is not None:
                        loop.queue(KIND_OF[suffix], msg)
        answer = loop.answer(PeriodAt(period, tick.period_ns, {"sim": tick},
                                      lambda suffix, stamp, period=period, tick=tick: member.admit(
                                          suffix, stamp, period.stamp_ns, tick.period_ns)))
        states += [msg for spec, msg in answer.messages if spec == keys.NAV_STATE]
    return {s.stamp_ns: s.model_dump() for s in states}


def mismatched_states(rec: dict, replayed: dict[int, dict]) -> list[int]:
    """Stamps of recorded states the replay does not reproduce (a held tick may be recorded twice)."""
    recorded_states: dict[int, list[dict]] = {}
    for _data, msg in rec[keys.NAV_STATE.suffix]:
        recorded_states.setdefault(msg.stamp_ns, []).append(msg.model_dump())
    assert set(recorded_states) <= set(replayed), "a recorded state has no replayed counterpart"
    return [t for t, outs in recorded_states.items() if not any(close(replayed[t], o) for o in outs)]


@pytest.fixture(scope="module", params=sorted(GOLDENS))
def golden(request):
    name = request.param
    if not (DATA / f"{name}.mcap").exists():
        pytest.fail(f"missing golden {name}.mcap: run ./test tests/replay --regen")
    return name, GOLDENS[name][0], recorded(name)


def test_golden_is_small_and_complete(golden) -> None:
    name, _, rec = golden
    assert (DATA / f"{name}.mcap").stat().st_size < 1_000_000
    assert all(len(v) > 50 for v in rec.values()), {k: len(v) for k, v in rec.items()}


def test_estimator_reproduces_every_recorded_state(golden) -> None:
    _, scenario, rec = golden
    mismatched = mismatched_states(rec, replay_estimator(scenario, rec))
    assert not mismatched, (f"{len(mismatched)} of {len(rec[keys.NAV_STATE.suffix])} states differ, "
                            f"first at {min(mismatched)} ns")


def test_the_state_tolerance_still_catches_one_missing_gnss_fix(golden) -> None:
    _, scenario, rec = golden
    middle = len(rec[keys.GNSS.suffix]) // 2
    assert mismatched_states(rec, replay_estimator(scenario, rec, skip_gnss=middle))


def test_controller_reproduces_every_recorded_command(golden) -> None:
    _, scenario, rec = golden
    sc = load_scenario(scenario)
    # Pinned: the generated solver, and no wall-clock lateness (as the lockstep service runs).
    core = ControllerCore(load_vessel(sc.vessel), ControllerConfig(solver="generated", solve_budget_s=None))
    o = sc.origin
    core.set_origin(GeoOrigin.from_degrees(o.lat_deg, o.lon_deg, o.alt_m))
    assert core.handle_mission(0, sc.mission.to_request(0, mission_id=sc.name)).accepted
    commands = {}
    for _data, cmd in rec["ctrl/thrust"]:
        commands.setdefault(cmd.stamp_ns, cmd)
    worst, compared = 0.0, 0
    seen = set()
    for _data, state in rec["nav/state"]:
        if state.stamp_ns in seen:  # a held tick republished: the controller answered it once
            continue
        seen.add(state.stamp_ns)
        cmd, _record, _status = core.step(state.stamp_ns, state)
        want = commands.get(state.stamp_ns)
        if want is None:
            continue
        compared += 1
        worst = max(worst, abs(cmd.thrust_port_n - want.thrust_port_n),
                    abs(cmd.thrust_starboard_n - want.thrust_starboard_n))
        assert cmd.source == want.source, (state.stamp_ns, cmd.source, want.source)
    assert compared > 50
    assert worst <= THRUST_TOLERANCE_N, f"largest thrust difference {worst:.3g} N"
