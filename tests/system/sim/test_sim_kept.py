"""A sim killed after a scenario load comes back in the loaded scenario (``--state-file``,
``seaway_sim.kept``): a real ``seaway-sim`` in lockstep on a real Zenoh session, loaded over the
bus, SIGKILLed and started again with the same command line, as the launcher restarts it."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.config import read_document
from seaway.contract.messages import ScenarioRequest
from seaway.runtime.bus import Bus
from seaway.runtime.run import describe
from seaway.simkit.scenario import load_scenario
from seaway_sim import kept

from tests.conftest import BIN, REPO, wait_for

pytestmark = pytest.mark.system

VESSEL = "vessel1"


def start(procs, env, name: str, state: Path):
    p = procs.start([str(BIN / "seaway-sim"), "--lockstep", "--scenario", "paper-c1",
                     "--state-file", str(state)], env, name)
    wait_for(lambda: "lockstep: period" in procs.log(p), 30, what=f"{name} up")
    return p


def current_scenario(bus: Bus) -> str:
    """The sim's scenario, from the reply to restarting it (the reply names it)."""
    reply = bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="restart"), 10.0)
    assert reply.accepted, reply.reason
    return reply.detail["name"]


def test_a_killed_sim_comes_back_in_the_scenario_it_was_loaded_with(procs, zenoh_env,
                                                                    tmp_path: Path) -> None:
    state = tmp_path / "run" / "sim-state.json"
    with Bus.open(VESSEL) as bus:
        sim = start(procs, zenoh_env, "sim-1", state)
        assert current_scenario(bus) == "paper-c1" and not state.exists()
        doc = read_document(REPO / "deploy" / "scenarios" / "paper-c5.toml")
        reply = bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="load",
                                                              scenario=doc), 10.0)
        assert reply.accepted and reply.detail["name"] == "paper-c5", reply.reason
        assert state.exists()  # kept before the reply
        procs.stop(sim, signal.SIGKILL)
        again = start(procs, zenoh_env, "sim-2", state)  # the same command line
        assert "paper-c5, as loaded over the bus before this sim started" in procs.log(again)
        assert current_scenario(bus) == "paper-c5"


def test_a_state_file_that_cannot_be_used_stops_the_sim_saying_why(procs, zenoh_env,
                                                                   tmp_path: Path) -> None:
    state = tmp_path / "sim-state.json"
    state.write_text('{"name": "paper-c5", "document": {"name": "paper-c5"}, "saved_unix_ns": 1}')
    p = subprocess.run([str(BIN / "seaway-sim"), "--lockstep", "--scenario", "paper-c1",
                        "--state-file", str(state)], env=zenoh_env, capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"--state-file {state}" in p.stderr and "remove it to start with the run's" in p.stderr
    assert "paper-c1" in p.stderr  # the run's scenario, named


def test_a_scenario_kept_by_an_earlier_launch_into_the_same_folder_is_not_flown(procs, zenoh_env,
                                                                               tmp_path: Path
                                                                               ) -> None:
    """``seaway launch --run-dir`` may name a folder a launch used before, and the run id is the
    folder's name: a kept scenario saved before this run's description was written is that earlier
    launch's, and the run's own scenario flies (``seaway.runtime.run.from_earlier_launch``)."""
    state = tmp_path / "sim-state.json"
    doc = read_document(REPO / "deploy" / "scenarios" / "paper-c5.toml")
    kept.save(state, kept.KeptScenario(name="paper-c5", document=doc, saved_unix_ns=time.time_ns()))
    run_file = describe(vessel=VESSEL, run_id=tmp_path.name, clock="lockstep",
                        scenario=load_scenario("paper-c1"), scenario_ref="paper-c1"
                        ).write(tmp_path / "run.json")  # the next launch, after the file was kept
    with Bus.open(VESSEL) as bus:
        p = procs.start([str(BIN / "seaway-sim"), "--vessel", VESSEL, "--run", str(run_file),
                         "--state-file", str(state)], zenoh_env, "sim")
        wait_for(lambda: "lockstep: period" in procs.log(p), 30, what="sim up")
        assert "paper-c5 was kept before this run started" in procs.log(p)
        assert current_scenario(bus) == "paper-c1"
