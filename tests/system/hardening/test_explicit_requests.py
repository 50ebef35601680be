"""Issue 14, item 8, through real processes: ``{"stamp_ns": 1, "junk": 2}`` on ``sim/scenario``
restarted the scenario and on ``nav/reset`` reset the estimator. Now both are refused with the
reason, nothing happens, and the same services still do what an explicit request asks."""

from __future__ import annotations

import pytest
from seaway.contract import keys
from seaway.contract.messages import NavResetRequest, Reply, ScenarioRequest
from seaway.runtime.bus import Bus

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
JUNK = b'{"stamp_ns": 1, "junk": 2}'


def raw_request(bus: Bus, spec: keys.KeySpec, payload: bytes) -> Reply | None:
    for r in bus.query_raw(bus.key(spec), payload, 3.0):
        return Reply.decode(r.payload) if r.error is None else None
    return None


def test_junk_is_neither_a_scenario_restart_nor_an_estimator_reset(procs, zenoh_env) -> None:
    run = ["--scenario", "paper-c1", "--lockstep"]  # one run: the services check they agree
    sim = procs.start([str(BIN / "seaway-sim"), *run], zenoh_env, "sim")
    est = procs.start([str(BIN / "seaway-estimator"), *run], zenoh_env, "estimator")
    with Bus.open("vessel1") as bus:
        wait_for(lambda: {"sim", "estimator"} <= bus.alive_services(), 30, what="sim and estimator")
        for spec in (keys.SIM_SCENARIO, keys.NAV_RESET):
            reply = wait_for(lambda spec=spec: raw_request(bus, spec, JUNK), 20,
                             what=f"an answer on {spec.suffix}")
            assert not reply.accepted, reply
            assert "malformed request" in reply.reason and "junk: unknown field" in reply.reason
            assert "Field required" in reply.reason  # and it did not say what it asks for
        assert "restarted" not in procs.log(sim)
        assert "re-initialised" not in procs.log(est)
        # Saying what it asks for, the same request is served.
        reply = bus.request(keys.SIM_SCENARIO, ScenarioRequest.make(stamp_ns=1, action="restart"), 5.0)
        assert reply.accepted and "restarted" in reply.reason
        reply = bus.request(keys.NAV_RESET, NavResetRequest.make(stamp_ns=1, keep_origin=True,
                                                                  reason="test"), 5.0)
        assert reply.accepted
    wait_for(lambda: "re-initialised (request: test" in procs.log(est), 5, what="the reset logged")
