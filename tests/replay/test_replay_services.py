"""Replay regression: each service's core, fed a recording's inputs in order, reproduces its outputs.

The goldens in ``data/`` are recordings of the real lockstep stack (``regen.py``; only ``--regen``
rewrites them). The inputs are ordered as the lockstep protocol defines them (services/sim/README.md):
for each tick t_k, the sensor samples stamped <= t_k, then the tick, then the command computed from
the state t_k. With that order:

* the estimator (its service glue ``EstimatorLoop`` and its core) reproduces every recorded
  ``nav/state`` byte for byte;
* the controller core (generated solver, its pinned options) reproduces every recorded ``ctrl/thrust``
  to 1e-6 N: the same compiled solver on the same inputs, so in practice exactly, with room for
  a different CPU's floating-point code paths.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from seaway.contract.messages import Attitude, ClockTick, GnssFix, StateEstimate, ThrustCommand
from seaway.runtime import run as runs
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel
from seaway_controller.core import ControllerConfig, ControllerCore
from seaway_estimator.config import load_estimator_config
from seaway_estimator.core import EstimatorCore
from seaway_estimator.service import EstimatorLoop, with_run
from seaway_recorder.recording import iter_messages

from tests.replay.regen import GOLDENS

DATA = Path(__file__).with_name("data")
THRUST_TOLERANCE_N = 1e-6
TYPES = {"sensors/gnss": GnssFix, "sensors/attitude": Attitude, "sim/clock": ClockTick,
         "nav/state": StateEstimate, "ctrl/thrust": ThrustCommand}
# Within one stamp: samples, then the tick, then the command answering the state of that tick.
RANK = {"sensors/gnss": 0, "sensors/attitude": 0, "sim/clock": 1, "ctrl/thrust": 2}


def recorded(name: str) -> dict[str, list[tuple[bytes, object]]]:
    out: dict[str, list[tuple[bytes, object]]] = {k: [] for k in TYPES}
    for m in iter_messages([DATA / f"{name}.mcap"]):
        suffix = m.topic.split("/", 2)[2]
        if suffix in TYPES:
            out[suffix].append((m.data, TYPES[suffix].decode(m.data)))
    return out


class Capture:
    """The estimator's publishers, keeping what it would have put on the bus."""

    def __init__(self) -> None:
        self.states: list[bytes] = []

    def publisher(self, spec):
        capture = self

        class _Pub:
            def put(self, msg) -> None:
                if isinstance(msg, StateEstimate):
                    capture.states.append(msg.encode())

        return _Pub()


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


def test_estimator_reproduces_every_recorded_state_exactly(golden) -> None:
    _, scenario, rec = golden
    inputs = [(msg.stamp_ns, RANK[k], i, k, msg) for k in RANK for i, (_, msg) in enumerate(rec[k])]
    cfg = with_run(load_estimator_config(None),
                   runs.describe(scenario=load_scenario(scenario), scenario_ref=scenario, vessel="vessel1",
                                 run_id="golden"))
    cap = Capture()
    loop = EstimatorLoop(EstimatorCore(cfg), cap)
    recorded_states = {}
    for data, msg in rec["nav/state"]:
        recorded_states.setdefault(msg.stamp_ns, set()).add(data)
    replayed: dict[int, bytes] = {}
    for _stamp, _rank, _i, kind, msg in sorted(inputs, key=lambda e: e[:3]):
        if kind == "sim/clock":
            n = len(cap.states)
            loop.on_tick(msg)
            for out in cap.states[n:]:
                replayed[StateEstimate.decode(out).stamp_ns] = out
        else:
            loop.queue({"sensors/gnss": "gnss", "sensors/attitude": "attitude",
                        "ctrl/thrust": "thrust"}[kind], msg)
    assert set(recorded_states) <= set(replayed), "a recorded state has no replayed counterpart"
    mismatched = [t for t, outs in recorded_states.items() if replayed[t] not in outs]
    assert not mismatched, (f"{len(mismatched)} of {len(recorded_states)} states differ, "
                            f"first at {min(mismatched)} ns")


def test_controller_reproduces_every_recorded_command(golden) -> None:
    _, scenario, rec = golden
    sc = load_scenario(scenario)
    # Pinned: the generated solver, and no wall-clock lateness (as the lockstep service runs).
    core = ControllerCore(load_vessel(sc.vessel), ControllerConfig(solver="generated", solve_budget_s=None))
    o = sc.origin
    core.set_origin(GeoOrigin(math.radians(o.lat_deg), math.radians(o.lon_deg), o.alt_m))
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
