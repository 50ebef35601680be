"""A scenario whose disturbances of one kind add past what one may be, loaded over the bus by an
authorised sender (``sim/scenario``, action ``load``) into a real ``seaway-sim`` in real time with a
MAVLink peer: 200 currents of 5 m/s each were accepted, kept in the state file, and the sim died
10 ms later packing a GNSS speed of 1400 m/s into MAVLink (and at every restart after, from the
state file). Now the load is refused naming the field and the bound, the running world and the
state file untouched, and a state file kept with such a world stops the sim saying so (exit 2),
not a crash at its first step (``seaway.simkit.scenario.disturbance_sums``)."""

from __future__ import annotations

import subprocess

import pytest
from pymavlink.dialects.v20 import common as ml
from seaway.contract import keys
from seaway.contract.messages import ScenarioRequest
from seaway.runtime.bus import Bus
from seaway.simkit import scenario as sc
from seaway_sim import kept

from tests.conftest import BIN
from tests.system.sim.test_sim_realtime import MavClient, start_sim

pytestmark = pytest.mark.system

MANY_CURRENTS = [{"kind": "current", "north_mps": 5.0, "east_mps": 5.0}] * 60  # under the count


def many_currents() -> dict:
    doc = sc.load_scenario("lake").model_dump(mode="json")
    doc.update(name="many-currents", disturbances=MANY_CURRENTS)
    return doc


def heartbeat(mav: MavClient) -> None:
    mav.send(ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3))


def test_a_load_whose_disturbances_add_past_the_bound_is_refused_and_the_sim_flies_on(
        procs, zenoh_env, tmp_path) -> None:
    state = tmp_path / "sim-state.json"
    sim, port = start_sim(procs, zenoh_env, "--scenario", "lake", "--state-file", str(state))
    with Bus.open("vessel1") as bus:
        mav = MavClient(port)
        heartbeat(mav)
        assert mav.wait("GPS_RAW_INT", 10.0) is not None  # the sim sends its samples to this peer
        reply = bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="load",
                                                              scenario=many_currents()), 10.0)
        assert not reply.accepted
        assert "north_mps" in reply.reason and f"{sc.MAX_CURRENT_MPS:g}" in reply.reason, reply.reason
        assert not state.exists()  # nothing kept for a restart
        # The sim flies on in its scenario: samples keep coming, and it still serves requests.
        hb = ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3)
        for _ in range(3):  # 0.6 s of samples at least (5 Hz); it died within 10 ms before
            assert mav.wait("GPS_RAW_INT", 10.0, keep_streaming=hb) is not None
        assert sim.poll() is None, procs.log(sim)
        again = bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="restart"), 10.0)
        assert again.accepted and again.detail["name"] == "lake", again.reason


def test_a_state_file_keeping_such_a_world_stops_the_sim_saying_why(zenoh_env, tmp_path) -> None:
    """A world kept before this bound (by an older sim) is not flown into a crash at every restart:
    the sim stops at its start, naming the file and what is wrong."""
    state = tmp_path / "sim-state.json"
    kept.save(state, kept.KeptScenario(name="many-currents", document=many_currents(),
                                       saved_unix_ns=1))
    p = subprocess.run([str(BIN / "seaway-sim"), "--lockstep", "--scenario", "lake",
                        "--state-file", str(state)], env=zenoh_env, capture_output=True, text=True,
                       timeout=60)
    assert p.returncode == 2, p.stderr
    assert str(state) in p.stderr and "north_mps" in p.stderr and "Traceback" not in p.stderr
