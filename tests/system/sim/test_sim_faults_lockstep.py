"""A scenario's scheduled faults in a real lockstep run (sim, instant responder, recorder: real
processes, Zenoh, MCAP): a GNSS dropout removes the fixes of its window from the recording, a
thruster failure turns the vessel the other way, and two runs record the same states."""

from __future__ import annotations

import signal
import sys
import tomllib
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import GnssFix, SimTruth
from seaway.recording.reader import iter_messages
from seaway.runtime.bus import Bus

from tests.conftest import BIN, REPO, wait_for

pytestmark = pytest.mark.system

S = 1_000_000_000
DROPOUT_S = (1.0, 2.0)  # [start, end)
FAILURE_S = 3.0
RUN_S = 5.0
FAULTS = f"""
[[faults]]
kind = "gnss_dropout"
start_s = {DROPOUT_S[0]}
duration_s = {DROPOUT_S[1] - DROPOUT_S[0]}

[[faults]]
kind = "thruster"
time_s = {FAILURE_S}
thruster = "port"
factor = 0.0
"""


def faulty_lake(tmp: Path) -> Path:
    """The lake with the faults above (its mission is not flown: the responder sends 30 N / 20 N)."""
    text = (REPO / "deploy" / "scenarios" / "lake.toml").read_text()
    text = text.replace('name = "lake"', 'name = "lake-faulted"').replace("[mission]", FAULTS + "\n[mission]")
    assert len(tomllib.loads(text)["faults"]) == 2
    path = tmp / "lake-faulted.toml"
    path.write_text(text)
    return path


def run(procs, env, scenario: Path, out: Path, tag: str) -> tuple[list[GnssFix], dict[int, SimTruth]]:
    """Record ``RUN_S`` of sim time of ``scenario`` in lockstep; the recorded fixes and truths."""
    rec = procs.start(
        [str(BIN / "seaway"), "record", "--out", str(out), "--scenario", str(scenario)],
        env,
        f"recorder-{tag}",
    )
    wait_for(lambda: "READY" in procs.log(rec), 30, what="recorder ready")
    with Bus.open("vessel1") as bus:
        clock = bus.subscribe(keys.SIM_CLOCK, mode="latest")
        sim = procs.start(
            [str(BIN / "seaway-sim"), "--lockstep", "--scenario", str(scenario), "--stall-repeat-s", "0.3"],
            env,
            f"sim-{tag}",
        )
        resp = procs.start(
            [sys.executable, "-m", "seaway_lab.responder", "--port-n", "30", "--starboard-n", "20"],
            env,
            f"responder-{tag}",
        )

        def past_the_end() -> bool:
            tick = clock.get(0.2)
            return tick is not None and tick.stamp_ns > RUN_S * S

        wait_for(past_the_end, 90, what=f"{RUN_S} s of sim time")
        procs.stop(resp, signal.SIGTERM, timeout_s=15)
        procs.stop(sim, signal.SIGTERM, timeout_s=15)
    procs.stop(rec, signal.SIGTERM, timeout_s=30)
    files = sorted(out.glob("*.mcap"))
    fixes: list[GnssFix] = []
    truths: dict[int, SimTruth] = {}
    for m in iter_messages(files):
        if m.topic.endswith("/" + keys.GNSS.suffix):
            fixes.append(GnssFix.decode(m.data))
        elif m.topic.endswith("/" + keys.SIM_TRUTH.suffix):
            t = SimTruth.decode(m.data)
            truths[t.stamp_ns] = t
    return fixes, truths


@pytest.mark.skipif(not (BIN / "seaway-sim").exists(), reason="the sim is not installed")
def test_scheduled_faults_act_in_lockstep_and_the_run_stays_deterministic(procs, zenoh_env, tmp_path) -> None:
    scenario = faulty_lake(tmp_path)
    fixes_a, truths_a = run(procs, zenoh_env, scenario, tmp_path / "a", "a")
    fixes_b, truths_b = run(procs, zenoh_env, scenario, tmp_path / "b", "b")

    # The dropout: no fix in its window, every other 5 Hz fix of the run recorded.
    stamps = sorted({f.stamp_ns for f in fixes_a if f.stamp_ns <= RUN_S * S})
    window = range(round(DROPOUT_S[0] * S), round(DROPOUT_S[1] * S))
    assert not [t for t in stamps if t in window]
    assert stamps == [t for t in range(0, round(RUN_S * S) + 1, S // 5) if t not in window]

    # The failure: the port thruster produces nothing from then on, and the vessel, turning to
    # starboard on 30 N / 20 N, turns to port on the starboard thruster alone.
    before = [t for s, t in truths_a.items() if 0.5 * S <= s <= FAILURE_S * S]
    after = [t for s, t in truths_a.items() if s > FAILURE_S * S]
    assert before and all(t.thrust_port_n == 30.0 and t.r_radps > 0 for t in before)
    assert after and all(t.thrust_port_n == 0.0 and t.thrust_starboard_n == 20.0 for t in after)
    assert truths_a[max(truths_a)].r_radps < 0

    # Deterministic: both runs recorded the same states and fixes at every common stamp.
    common = sorted(set(truths_a) & set(truths_b))
    assert [s for s in common if s <= RUN_S * S] == [k * S // 10 for k in range(round(RUN_S * 10) + 1)]
    assert all(truths_a[s] == truths_b[s] for s in common)
    fixes_b_by_t = {f.stamp_ns: f for f in fixes_b}
    assert all(fixes_b_by_t[f.stamp_ns] == f for f in fixes_a if f.stamp_ns in fixes_b_by_t)
